"""Pictures from the runs' snapshots: stage grids comparing methods (the paper's Figures 3
and 4: stages left to right, methods top to bottom) and an animated GIF per trial.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import imageio.v3 as iio
import numpy as np

from actionreasoning.recording.images import image_grid
from actionreasoning.recording.names import FRAMES_DIR
from actionreasoning.report.collect import Group
from actionreasoning.trial.results import TrialResult
from actionreasoning.world.stages import Stage

CLOSEUP = re.compile(r"b(?P<brick>\d+)_(?P<n>\d+)_(?P<stage>\w+)\.png")
FRAME_S = 0.35
LAST_FRAME_S = 2.0


def stage_pictures(directory: Path, brick: int) -> dict[str, Path]:
    """The close-up of each stage of ``brick`` (the last one where a stage was repeated)."""
    found: list[tuple[int, str, Path]] = []
    for path in directory.glob(f"b{brick}_*.png"):
        match = CLOSEUP.fullmatch(path.name)
        if match is not None:
            found.append((int(match["n"]), match["stage"], path))
    return {stage: path for _, stage, path in sorted(found)}


def shown_trial(group: Group) -> tuple[TrialResult, Path] | None:
    """The trial a grid shows for a group: its first trial with snapshots, successful first."""
    ordered = sorted(group.results, key=lambda r: (not r.success, r.trial))
    for result in ordered:
        directory = group.snapshot_dir(result)
        if directory is not None:
            return result, directory
    return None


def stage_grid(groups: Sequence[Group], path: Path) -> Path | None:
    """One row per method: the stages of the pattern's last brick in its shown trial."""
    rows: list[tuple[str, list[tuple[str, np.ndarray | None]]]] = []
    for group in groups:
        shown = shown_trial(group)
        if shown is None:
            continue
        result, directory = shown
        pictures = stage_pictures(directory, result.bricks[-1].id)
        if not pictures:
            continue
        cells: list[tuple[str, np.ndarray | None]] = [
            (stage, iio.imread(pictures[stage]) if stage in pictures else None) for stage in Stage
        ]
        while cells and cells[-1][1] is None:
            cells.pop()
        rows.append((f"{group.label}\ntrial {result.trial}", cells))
    if not rows:
        return None
    path.write_bytes(image_grid(rows, titles_on_first_row=True))
    return path


def trial_gif(snapshots: Path, path: Path) -> Path | None:
    """The trial's overview frames as a looping GIF, the final frame held longest."""
    frames = sorted((snapshots / FRAMES_DIR).glob("*.png"))
    if not frames:
        return None
    images = [iio.imread(frame) for frame in frames]
    durations = [FRAME_S * 1000] * (len(images) - 1) + [LAST_FRAME_S * 1000]
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, images, extension=".gif", duration=durations, loop=0)
    return path
