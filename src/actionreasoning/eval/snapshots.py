"""Per-stage pictures of a trial: one PNG per stage and brick, and a contact sheet.

The sheet has stages left to right and bricks top to bottom, like the paper's Figures 3
and 4. Rendering only reads the simulator, so a trial with snapshots gives the same
results as one without.
"""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np

from actionreasoning.control.classical import StageEvent
from actionreasoning.sim.camera import build_closeup, overview, render
from actionreasoning.sim.scene import Scene

WIDTH, HEIGHT = 320, 240


class SnapshotRecorder:
    """A stage hook that writes ``<dir>/b<brick>_<n>_<stage>.png`` and, at the end, sheets."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self.directory.mkdir(parents=True, exist_ok=True)
        self._rows: dict[int, list[np.ndarray]] = {}
        self._stages: list[str] = []

    def __call__(self, scene: Scene, event: StageEvent) -> None:
        if event.brick < 0:
            self._finish(scene)
            return
        image = render(scene, overview(scene), WIDTH, HEIGHT)
        row = self._rows.setdefault(event.brick, [])
        if event.brick == min(self._rows):
            self._stages.append(event.stage)
        iio.imwrite(self.directory / f"b{event.brick}_{len(row)}_{event.stage}.png", image)
        row.append(image)

    def _finish(self, scene: Scene) -> None:
        iio.imwrite(self.directory / "final_overview.png", render(scene, overview(scene)))
        iio.imwrite(self.directory / "final_build.png", render(scene, build_closeup(scene)))
        if self._rows:
            iio.imwrite(self.directory / "stages.png", contact_sheet(list(self._rows.values())))


def contact_sheet(rows: list[list[np.ndarray]], scale: int = 2) -> np.ndarray:
    """Tile images (rows of equal-size RGB arrays) into one, downsampled by ``scale``."""
    width = max(len(r) for r in rows)
    blank = np.full_like(rows[0][0], 255)
    tiled = [np.concatenate(r + [blank] * (width - len(r)), axis=1) for r in rows]
    return np.concatenate(tiled, axis=0)[::scale, ::scale]
