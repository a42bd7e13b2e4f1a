"""The film process: renders a trial's frames and encodes them as an MP4, beside the trial.

``python -m actionreasoning.eval.film MP4 PARENT_PID`` reads pickles from its standard
input, written by its parent (``eval/video.py``): a :class:`Reel` (what the scene looks
like, from where), then one :class:`Frame` per frame, then ``None``. It poses a look-alike
of the scene (:class:`Replica`) for each frame, renders it with TinyRenderer over a ground
rendered once, captions it and writes it to the MP4; a frame where nothing moved is not
rendered again. A process of its own, not a ``multiprocessing`` child, so that filming
works from any script, guarded by ``if __name__ == "__main__"`` or not.
"""

from __future__ import annotations

import pickle
import sys
from dataclasses import dataclass
from typing import BinaryIO

import imageio.v2 as imageio
import numpy as np
from PIL import Image, ImageDraw

from actionreasoning.eval.lifeline import exit_with_parent
from actionreasoning.sim.camera import CameraView, FixedCamera
from actionreasoning.sim.replica import Replica, SceneLooks, ScenePose

CAPTION_LINE_PX = 12


@dataclass(frozen=True)
class Reel:
    """What every frame shares: the scene's looks, the camera's view, size and rate."""

    looks: SceneLooks
    view: CameraView
    width: int
    height: int
    fps: int


@dataclass(frozen=True)
class Frame:
    """One frame to film: the scene's pose and the caption's lines."""

    pose: ScenePose
    caption: tuple[str, ...]


def film(source: BinaryIO, path: str) -> None:
    """Render and encode the reel read from ``source`` into the MP4 at ``path``."""
    reel: Reel = pickle.load(source)
    camera = FixedCamera(reel.view, reel.width, reel.height)
    replica = Replica(reel.looks)
    writer = imageio.get_writer(
        path,
        format="FFMPEG",
        fps=reel.fps,
        codec="libx264",
        quality=6,
        macro_block_size=16,
        output_params=["-movflags", "+faststart", "-preset", "veryfast"],
    )
    shown: ScenePose | None = None
    picture = np.zeros((reel.height, reel.width, 3), dtype=np.uint8)  # the first frame's
    try:
        while (frame := pickle.load(source)) is not None:
            if shown is None or not frame.pose.same_as(shown):
                replica.show(frame.pose)
                picture, shown = camera.render(replica.client), frame.pose
            writer.append_data(captioned(picture, frame.caption))
    finally:
        writer.close()
        replica.close()


def captioned(image: np.ndarray, lines: tuple[str, ...]) -> np.ndarray:
    """``image`` with its non-empty ``lines`` in white on a dark band along its top."""
    shown = [line for line in lines if line]
    picture = Image.fromarray(image)
    draw = ImageDraw.Draw(picture)
    draw.rectangle((0, 0, picture.width, 2 + CAPTION_LINE_PX * len(shown)), fill=(0, 0, 0))
    for row, line in enumerate(shown):
        draw.text((4, 2 + CAPTION_LINE_PX * row), line, fill=(255, 255, 255))
    return np.asarray(picture)


def main() -> None:
    path, parent = sys.argv[1], int(sys.argv[2])
    exit_with_parent(parent)
    film(sys.stdin.buffer, path)


if __name__ == "__main__":
    main()
