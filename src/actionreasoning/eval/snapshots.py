"""Per-stage pictures of a trial: one PNG per stage and brick, and a labelled sheet.

Pick stages are seen close up at the brick's starting spot, placing stages at the build
area. The sheet has stages left to right and bricks top to bottom, like the paper's
Figures 3 and 4. Rendering only reads the simulator, so a trial with snapshots gives the
same results as one without.
"""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np
from matplotlib.figure import Figure

from actionreasoning.control.classical import StageEvent
from actionreasoning.sim.camera import build_closeup, closeup, overview, render
from actionreasoning.sim.scene import Scene
from actionreasoning.world.geometry import Vec3

WIDTH, HEIGHT = 320, 240
PICK_STAGES = frozenset({"pre_grasp", "descent", "grasp", "lift"})


class SnapshotRecorder:
    """A stage hook writing ``<dir>/b<brick>_<n>_<stage>.png`` and, at the end, the sheet."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self.directory.mkdir(parents=True, exist_ok=True)
        self._rows: dict[int, list[tuple[str, np.ndarray]]] = {}
        self._pick_spot: dict[int, Vec3] = {}

    def __call__(self, scene: Scene, event: StageEvent) -> None:
        if event.brick < 0:
            self._finish(scene)
            return
        spot = self._pick_spot.setdefault(event.brick, scene.brick_pose(event.brick)[0])
        view = closeup(spot) if event.stage in PICK_STAGES else build_closeup(scene)
        image = render(scene, view, WIDTH, HEIGHT)
        row = self._rows.setdefault(event.brick, [])
        iio.imwrite(self.directory / f"b{event.brick}_{len(row)}_{event.stage}.png", image)
        row.append((event.stage, image))

    def _finish(self, scene: Scene) -> None:
        iio.imwrite(self.directory / "final_overview.png", render(scene, overview(scene)))
        iio.imwrite(self.directory / "final_build.png", render(scene, build_closeup(scene)))
        if self._rows:
            save_sheet(self._rows, self.directory / "stages.png")


def save_sheet(rows: dict[int, list[tuple[str, np.ndarray]]], path: Path) -> None:
    """A grid of stage images: one row per brick, stage names as column titles.

    A picture whose stage differs from the first row's in its column (a re-grasp, an extra
    waypoint) gets its own title.
    """
    n_rows, n_cols = len(rows), max(len(r) for r in rows.values())
    figure = Figure(figsize=(1.9 * n_cols, 1.5 * n_rows), dpi=100)
    axes = figure.subplots(n_rows, n_cols, squeeze=False)
    ordered = [row for _, row in sorted(rows.items())]
    for r, (brick, row) in enumerate(sorted(rows.items())):
        for c, axis in enumerate(axes[r]):
            axis.set_xticks([])
            axis.set_yticks([])
            if c < len(row):
                stage, image = row[c]
                axis.imshow(image)
                if r == 0 or c >= len(ordered[0]) or ordered[0][c][0] != stage:
                    axis.set_title(stage.replace("_", " "), fontsize=9)
            else:
                axis.set_axis_off()
        axes[r][0].set_ylabel(f"brick {brick}", fontsize=9)
    figure.tight_layout(pad=0.3)
    figure.savefig(path)
