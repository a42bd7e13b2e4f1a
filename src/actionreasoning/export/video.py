"""The dataset's MP4: every episode's frames in turn, decoded from the run's videos and
encoded again as one H.264 stream (LeRobot v3 keeps many episodes in a file, each found by
its start and end time in it).

Frame k of the file plays at k / fps seconds, so an episode starting at frame s runs from
s / fps. A keyframe every other frame (LeRobot's ``g=2``) keeps seeking to any frame cheap.
"""

from __future__ import annotations

import errno
from pathlib import Path

import imageio.v2 as imageio
import imageio.v3 as iio
import numpy as np

from actionreasoning.errors import ConfigError
from actionreasoning.export.lerobot_format import PIXEL_FORMAT
from actionreasoning.export.stats import ImageStats, Stats, sampled_frames
from actionreasoning.recording.mp4 import Unfinished, check_mp4

#: libx264's constant rate factor imageio gives quality 6 (the run's videos' quality).
QUALITY = 6
KEYFRAME_EVERY = 2


class EpisodeVideo:
    """The MP4 at ``path`` being written, ``fps`` frames a second; ``close()`` ends it."""

    def __init__(self, path: Path, fps: int) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.frames = 0
        self.shape: tuple[int, ...] | None = None
        self._writer = imageio.get_writer(
            str(path),
            format="FFMPEG",
            fps=fps,
            codec="libx264",
            quality=QUALITY,
            pixelformat=PIXEL_FORMAT,
            macro_block_size=16,
            output_params=["-g", str(KEYFRAME_EVERY), "-movflags", "+faststart"],
        )

    def append(self, source: Path, length: int) -> Stats:
        """Append the frames of the MP4 ``source``, which must be ``length`` frames of this
        file's size; the image statistics of the frames sampled of them."""
        _check_whole(source)
        sampled, stats = set(sampled_frames(length)), ImageStats()
        count = 0
        for count, frame in enumerate(iio.imiter(source, plugin="FFMPEG"), start=1):
            self._check_shape(source, frame)
            self._writer.append_data(frame)
            if count - 1 in sampled:
                stats.add(frame)
        if count != length:
            raise ConfigError(
                f"{source} has {count} frames but its frame record {length}: they are not of "
                "one trial; run eval with --video into a new --out"
            )
        self.frames += count
        return stats.stats()

    def _check_shape(self, source: Path, frame: np.ndarray) -> None:
        if self.shape is None:
            self.shape = frame.shape
        elif frame.shape != self.shape:
            raise ConfigError(
                f"{source} has frames of {frame.shape[1]}x{frame.shape[0]} px, the videos "
                f"before it {self.shape[1]}x{self.shape[0]}: one dataset needs one size"
            )

    def close(self) -> None:
        """Finish the file and check it is whole (a full disk cuts it short silently)."""
        self._writer.close()
        try:
            check_mp4(str(self.path))
        except Unfinished as error:
            raise OSError(errno.EIO, f"the video was {error}", str(self.path)) from error


def _check_whole(source: Path) -> None:
    try:
        check_mp4(str(source))
    except Unfinished as error:
        raise ConfigError(
            f"{source} is not whole ({error}): run eval with --video into a new --out"
        ) from error
