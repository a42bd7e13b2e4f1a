"""Per-stage pictures of a trial, kept in memory as PNG files until the run writes them.

For every stage of every brick: a close-up (pick stages at the brick's starting spot,
placing stages at the build area) and an overview frame of the whole workspace, the frames
of the trial's animation. At the end: two final views and a sheet with stages left to right
and bricks top to bottom, like the paper's Figures 3 and 4. Rendering only reads the
simulator, so a trial with snapshots gives the same results as one without.
"""

from __future__ import annotations

import numpy as np

from actionreasoning.recording.images import image_grid, png
from actionreasoning.recording.names import FINAL_BUILD, FRAMES_DIR, STAGE_SHEET
from actionreasoning.sim.camera import build_closeup, closeup, overview, render
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.runner import TrialObserver
from actionreasoning.world.geometry import Vec3
from actionreasoning.world.stages import Stage, StageEvent

WIDTH, HEIGHT = 320, 240
PICK_STAGES = frozenset({Stage.PRE_GRASP, Stage.DESCENT, Stage.GRASP, Stage.LIFT})


class SnapshotRecorder(TrialObserver):
    """A trial observer collecting ``files``: relative path -> PNG bytes.

    ``b<brick>_<n>_<stage>.png`` are the close-ups, ``frames/<k>_b<brick>_<stage>.png`` the
    overview frames in trial order, then ``final_overview.png``, ``final_build.png`` and
    the sheet ``stages.png``.
    """

    def __init__(self) -> None:
        self.files: dict[str, bytes] = {}
        self._rows: dict[int, list[tuple[str, np.ndarray]]] = {}
        self._pick_spot: dict[int, Vec3] = {}
        self._frames = 0

    def stage(self, scene: Scene, event: StageEvent) -> None:
        if event.brick < 0:
            self._frame(scene, "final")
            self._finish(scene)
            return
        spot = self._pick_spot.setdefault(event.brick, scene.brick_pose(event.brick)[0])
        view = closeup(spot) if event.stage in PICK_STAGES else build_closeup(scene)
        image = render(scene, view, WIDTH, HEIGHT)
        row = self._rows.setdefault(event.brick, [])
        self.files[f"b{event.brick}_{len(row)}_{event.stage}.png"] = png(image)
        row.append((event.stage, image))
        self._frame(scene, f"b{event.brick}_{event.stage}")

    def _frame(self, scene: Scene, label: str) -> None:
        image = render(scene, overview(scene), WIDTH, HEIGHT)
        self.files[f"{FRAMES_DIR}/{self._frames:03d}_{label}.png"] = png(image)
        self._frames += 1

    def _finish(self, scene: Scene) -> None:
        self.files["final_overview.png"] = png(render(scene, overview(scene)))
        self.files[FINAL_BUILD] = png(render(scene, build_closeup(scene)))
        if self._rows:
            self.files[STAGE_SHEET] = sheet_png(self._rows)


def sheet_png(rows: dict[int, list[tuple[str, np.ndarray]]]) -> bytes:
    """A grid of stage images as PNG: one row per brick, stage names as column titles.

    A picture whose stage differs from the first row's in its column (a re-grasp, an extra
    waypoint) gets its own title.
    """
    return image_grid(
        [(f"brick {brick}", row) for brick, row in sorted(rows.items())], titles_on_first_row=True
    )
