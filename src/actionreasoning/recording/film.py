"""The film process: renders a trial's frames and encodes them as an MP4, beside the trial.

``python -m actionreasoning.recording.film MP4`` reads pickles from its standard input, written
by its parent (``recording/video.py``): a :class:`Reel` (what the scene looks like, from where),
then one :class:`Frame` per frame, then ``None``; if the input ends before ``None``, the
parent is gone (killed, say) and the film process ends, leaving no file. A video that could
not be finished (a full disk: the encoder gives up, or writes a file cut short, without a
word) is checked for, deleted, and the reason printed as the last line of the standard
output, exit status 2. It poses a look-alike
of the scene (:class:`Replica`) for each frame, renders it with TinyRenderer over a ground
rendered once, captions it and writes it to the MP4. It is a process of its own, not a
``multiprocessing`` child, so that filming works from any script, with or without an
``if __name__ == "__main__"`` guard.
"""

from __future__ import annotations

import pickle
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import imageio.v2 as imageio
import numpy as np
from PIL import Image, ImageDraw

from actionreasoning.recording.mp4 import Unfinished, check_mp4
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
    """Render and encode the reel read from ``source`` into the MP4 at ``path``; EOFError
    if ``source`` ends before the reel does."""
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
    try:
        while (frame := pickle.load(source)) is not None:
            replica.show(frame.pose)
            writer.append_data(captioned(camera.render(replica.client), frame.caption))
    finally:
        try:
            writer.close()
        finally:
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
    path = sys.argv[1]
    try:
        film(sys.stdin.buffer, path)
        check_mp4(path)
    except EOFError:  # the trial's process is gone: nobody will read the video
        Path(path).unlink(missing_ok=True)
        sys.exit(1)
    except (OSError, Unfinished) as error:  # the encoder's, or its file's, failure
        Path(path).unlink(missing_ok=True)
        reason = error.strerror if isinstance(error, OSError) and error.strerror else error
        lines = str(reason).strip().splitlines() or [type(error).__name__]
        print(f"\n{' '.join(lines[0].split())}", flush=True)
        sys.exit(2)


if __name__ == "__main__":
    main()
