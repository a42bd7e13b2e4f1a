"""A video of a trial: overview frames on a fixed simulated-time cadence, as an MP4.

The scene calls the recorder every ``FRAME_S`` (``1 / FPS``) simulated seconds
(``Scene.watch``) and it renders a frame, so the video plays in real time. Each frame carries a
caption: simulated time, the brick in hand and the current stage or agent step (from the
trial's stage hook). Rendering only reads the simulator, so a filmed trial gives the same
results as one without (tests check this).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
from PIL import Image, ImageDraw

from actionreasoning.control.classical import StageEvent
from actionreasoning.sim.camera import FixedCamera, overview
from actionreasoning.sim.scene import Scene

#: Frames per simulated second; also the playback rate, so videos play in real time.
FPS = 8
#: Simulated time between two frames.
FRAME_S = 1.0 / FPS
WIDTH, HEIGHT = 320, 240


class VideoRecorder:
    """A tick observer and a stage hook that film a trial; ``close()`` gives the MP4."""

    def __init__(self) -> None:
        handle, name = tempfile.mkstemp(suffix=".mp4")
        os.close(handle)
        self._path = Path(name)
        self._writer = imageio.get_writer(
            self._path,
            format="FFMPEG",
            fps=FPS,
            codec="libx264",
            quality=6,
            macro_block_size=16,
            output_params=["-movflags", "+faststart", "-preset", "veryfast"],
        )
        self._caption = "settling"
        self._camera: FixedCamera | None = None
        self.frames = 0

    def on_tick(self, scene: Scene) -> None:
        """Film a frame (called every ``FRAME_S`` of simulated time)."""
        if self._camera is None:
            self._camera = FixedCamera(overview(scene), WIDTH, HEIGHT)
        image = self._camera.render(scene)
        self._writer.append_data(captioned(image, f"{scene.time_s:5.1f} s  {self._caption}"))
        self.frames += 1

    def on_stage(self, scene: Scene, event: StageEvent) -> None:
        """Caption the following frames with the stage just reached."""
        self._caption = "final settle" if event.brick < 0 else f"brick {event.brick}: {event.stage}"

    def close(self) -> bytes:
        """The MP4 (empty if no frame was filmed); the recorder is done."""
        try:
            self._writer.close()
            return self._path.read_bytes() if self.frames else b""
        finally:
            self._path.unlink(missing_ok=True)


def captioned(image: np.ndarray, text: str) -> np.ndarray:
    """``image`` with ``text`` in white on a dark band along its top."""
    picture = Image.fromarray(image)
    draw = ImageDraw.Draw(picture)
    draw.rectangle((0, 0, picture.width, 14), fill=(0, 0, 0))
    draw.text((4, 2), text, fill=(255, 255, 255))
    return np.asarray(picture)
