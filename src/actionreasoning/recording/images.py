"""Pictures as PNG files: one image, or labelled rows of titled images in one grid.

Used by the snapshots of a trial (its stage sheet) and by the report (stage grids), which
reads snapshots without the simulator.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from io import BytesIO

import imageio.v3 as iio
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

#: A grid's picture width (in), the room above it for its title (in), and the characters a
#: line of a row's label holds (the label stands left of its row, wrapped).
CELL_IN = 1.9
TITLE_IN = 0.3
LABEL_CHARS = 24
GRID_DPI = 100
#: The picture's height over its width where a grid has no picture.
DEFAULT_ASPECT = 0.75

Rows = Sequence[tuple[str, Sequence[tuple[str, np.ndarray | None]]]]


def png(image: np.ndarray) -> bytes:
    """An RGB image encoded as PNG."""
    return iio.imwrite("<bytes>", image, extension=".png")


def image_grid(rows: Rows, titles_on_first_row: bool) -> bytes:
    """Labelled rows of titled pictures as one PNG (see :func:`grid_figure`)."""
    buffer = BytesIO()
    grid_figure(rows, titles_on_first_row).savefig(buffer, format="png")
    return buffer.getvalue()


def grid_figure(rows: Rows, titles_on_first_row: bool) -> Figure:
    """Labelled rows of titled pictures; a ``None`` picture leaves its cell blank.

    With ``titles_on_first_row`` a column's title is printed once, and again only where a
    row's stage differs from the first row's; otherwise every cell has its title. Each
    row's label stands left of it, wrapped; the figure is as wide as the pictures and the
    widest label, and as tall as the pictures and their titles, so that nothing is cut.
    """
    n_rows, n_cols = len(rows), max(len(cells) for _, cells in rows)
    shapes = [image.shape for _, cells in rows for _, image in cells if image is not None]
    aspect = shapes[0][0] / shapes[0][1] if shapes else DEFAULT_ASPECT
    figure = Figure(dpi=GRID_DPI, layout="constrained")
    canvas = FigureCanvasAgg(figure)
    axes = figure.subplots(n_rows, n_cols, squeeze=False)
    first = rows[0][1]
    titled = set()  # the rows with a title above a picture
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
                titled.add(r)
        axes[r][0].set_axis_on()
        axes[r][0].set_ylabel(
            _wrapped(label), fontsize=9, rotation=0, ha="right", va="center", labelpad=6
        )
    renderer = canvas.get_renderer()
    label_in = max(a.yaxis.label.get_window_extent(renderer).width for a in axes[:, 0]) / GRID_DPI
    figure.set_size_inches(
        CELL_IN * n_cols + label_in + 0.3, CELL_IN * aspect * n_rows + TITLE_IN * len(titled) + 0.2
    )
    return figure


def _wrapped(label: str) -> str:
    """A row's label in lines of at most LABEL_CHARS characters (its own breaks kept)."""
    return "\n".join(
        "\n".join(textwrap.wrap(line, LABEL_CHARS, break_on_hyphens=False)) or line
        for line in label.splitlines()
    )
