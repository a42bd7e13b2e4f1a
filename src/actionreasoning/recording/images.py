"""Pictures as PNG files: one image, or labelled rows of titled images in one grid.

Used by the snapshots of a trial (its stage sheet) and by the report (stage grids), which
reads snapshots without the simulator.
"""

from __future__ import annotations

from collections.abc import Sequence
from io import BytesIO

import imageio.v3 as iio
import numpy as np
from matplotlib.figure import Figure


def png(image: np.ndarray) -> bytes:
    """An RGB image encoded as PNG."""
    return iio.imwrite("<bytes>", image, extension=".png")


def image_grid(
    rows: Sequence[tuple[str, Sequence[tuple[str, np.ndarray | None]]]], titles_on_first_row: bool
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
