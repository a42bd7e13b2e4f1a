"""The frame record of a filmed trial (``frames/trial_NNN.npz``): per video frame, what the
arm measured and what it was commanded.

The video recorder samples it at each frame it films (``recording/video.py``), from the
same reading of the scene, so row k belongs to frame k of the trial's MP4. An NPZ of five
arrays, n rows each: ``time_s`` (simulated time), ``joints_rad`` (n, 7: the arm's measured
joint angles), ``gripper_m`` (the measured opening between the finger pads),
``joint_targets_rad`` (n, 7: the joint position targets the controller commands) and
``gripper_target_m`` (the opening it commands). Free of the simulator, so the export reads
it without one.
"""

from __future__ import annotations

import io
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from actionreasoning.errors import ConfigError

ARM_DOF = 7


@dataclass(frozen=True)
class FrameSample:
    """One frame's row: measured joints and gripper opening, and their commanded targets."""

    time_s: float
    joints_rad: np.ndarray
    gripper_m: float
    joint_targets_rad: np.ndarray
    gripper_target_m: float


@dataclass(frozen=True)
class FrameRecord:
    """A trial's frame samples as arrays, one row per video frame."""

    time_s: np.ndarray
    joints_rad: np.ndarray
    gripper_m: np.ndarray
    joint_targets_rad: np.ndarray
    gripper_target_m: np.ndarray

    @classmethod
    def of(cls, samples: Sequence[FrameSample]) -> FrameRecord:
        """The record of ``samples``, in order."""
        return cls(
            **{
                f.name: np.array([getattr(s, f.name) for s in samples], dtype=np.float64)
                for f in fields(FrameSample)
            }
        )

    def __len__(self) -> int:
        return len(self.time_s)

    def npz(self) -> bytes:
        """The record as an NPZ file's bytes."""
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **{f.name: getattr(self, f.name) for f in fields(self)})
        return buffer.getvalue()

    @classmethod
    def read(cls, path: Path) -> FrameRecord:
        """The record at ``path``; one that is damaged or not a frame record is refused in
        one line."""
        try:
            with np.load(path, allow_pickle=False) as npz:
                arrays = {f.name: np.asarray(npz[f.name], dtype=np.float64) for f in fields(cls)}
        except (OSError, KeyError, ValueError, zipfile.BadZipFile) as error:
            reason = getattr(error, "strerror", None) or str(error).splitlines()[0]
            raise ConfigError(f"{path}: not a frame record ({reason})") from error
        record = cls(**arrays)
        record._check(path)
        return record

    def _check(self, path: Path) -> None:
        n = len(self)
        shapes = {
            "time_s": (n,),
            "joints_rad": (n, ARM_DOF),
            "gripper_m": (n,),
            "joint_targets_rad": (n, ARM_DOF),
            "gripper_target_m": (n,),
        }
        for name, shape in shapes.items():
            found = getattr(self, name).shape
            if found != shape:
                raise ConfigError(f"{path}: not a frame record ({name} has shape {found})")
