"""Per-stage pictures of a trial, kept in memory as PNG files until the run writes them.

For every stage of every brick: a close-up (pick stages at the brick's starting spot,
placing stages at the build area) and an overview frame of the whole workspace, the frames
of the trial's animation. At the end: two final views and a sheet with stages left to right
and bricks top to bottom, like the paper's Figures 3 and 4. Rendering only reads the
simulator, so a trial with snapshots gives the same results as one without.
"""

from __future__ import annotations

from io import BytesIO

import imageio.v3 as iio
import numpy as np
from matplotlib.figure import Figure

from actionreasoning.control.classical import StageEvent
from actionreasoning.eval.layout import RunDir
from actionreasoning.sim.camera import build_closeup, closeup, overview, render
from actionreasoning.sim.scene import Scene
from actionreasoning.world.geometry import Vec3

WIDTH, HEIGHT = 320, 240
PICK_STAGES = frozenset({"pre_grasp", "descent", "grasp", "lift"})
FRAMES_DIR = "frames"


def png(image: np.ndarray) -> bytes:
    """An RGB image encoded as PNG."""
    return iio.imwrite("<bytes>", image, extension=".png")


class SnapshotRecorder:
    """A stage hook collecting ``files``: relative path -> PNG bytes.

    ``b<brick>_<n>_<stage>.png`` are the close-ups, ``frames/<k>_b<brick>_<stage>.png`` the
    overview frames in trial order, then ``final_overview.png``, ``final_build.png`` and
    the sheet ``stages.png``.
    """

    def __init__(self) -> None:
        self.files: dict[str, bytes] = {}
        self._rows: dict[int, list[tuple[str, np.ndarray]]] = {}
        self._pick_spot: dict[int, Vec3] = {}
        self._frames = 0

    def __call__(self, scene: Scene, event: StageEvent) -> None:
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
        self.files[RunDir.FINAL_BUILD] = png(render(scene, build_closeup(scene)))
        if self._rows:
            self.files[RunDir.STAGE_SHEET] = sheet_png(self._rows)


def sheet_png(rows: dict[int, list[tuple[str, np.ndarray]]]) -> bytes:
    """A grid of stage images as PNG: one row per brick, stage names as column titles.

    A picture whose stage differs from the first row's in its column (a re-grasp, an extra
    waypoint) gets its own title.
    """
    return image_grid(
        [(f"brick {brick}", row) for brick, row in sorted(rows.items())], titles_on_first_row=True
    )


def image_grid(
    rows: list[tuple[str, list[tuple[str, np.ndarray | None]]]], titles_on_first_row: bool
) -> bytes:
    """Labelled rows of titled pictures as one PNG; a ``None`` picture leaves its cell blank.

    With ``titles_on_first_row`` a column's title is printed once, and again only where a
    row's stage differs from the first row's; otherwise every cell has its title.
    """
    n_rows, n_cols = len(rows), max(len(cells) for _, cells in rows)
    figure = Figure(figsize=(1.9 * n_cols, 1.5 * n_rows), dpi=100)
    axes = figure.subplots(n_rows, n_cols, squeeze=False)
    first = rows[0][1]
    for r, (label, cells) in enumerate(rows):
        for c, axis in enumerate(axes[r]):
            axis.set_xticks([])
            axis.set_yticks([])
            if c >= len(cells) or cells[c][1] is None:
                axis.set_axis_off()
                continue
            stage, image = cells[c]
            axis.imshow(image)
            shown_above = c < len(first) and first[c][1] is not None and first[c][0] == stage
            repeated = r > 0 and shown_above
            if not (titles_on_first_row and repeated):
                axis.set_title(stage.replace("_", " "), fontsize=9)
        axes[r][0].set_axis_on()
        axes[r][0].set_ylabel(label, fontsize=9)
    figure.tight_layout(pad=0.3)
    buffer = BytesIO()
    figure.savefig(buffer, format="png")
    return buffer.getvalue()
