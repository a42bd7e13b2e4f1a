"""Our Table I beside the paper's: its two rows as printed, and one markdown table that sets
our methods' means over successful trials (as ``table.md`` gives them) above them.

The paper's figures come from its own simulator and its own language model: they are set
beside ours for scale, not pooled with them (and its Average column is printed as it is,
although it is not quite the mean of its two patterns: 1.004 against (1.103 + 0.939) / 2).
"""

from __future__ import annotations

from actionreasoning.report.tables import AVERAGE, COLUMNS, Table
from actionreasoning.runs.markdown import table_lines

#: The paper's Table I: per pattern and on average, rotation error (deg), centre offset
#: (cm) and IoU (%), as printed.
PAPER_TABLE_I: dict[str, dict[str, tuple[float, float, float]]] = {
    "paper: classical controller": {
        "pyramid": (1.103, 4.318, 38.51),
        "grid": (0.939, 4.379, 37.72),
        AVERAGE: (1.004, 4.314, 38.38),
    },
    "paper: ActionReasoning (its agents)": {
        "pyramid": (0.583, 0.561, 89.03),
        "grid": (0.822, 0.712, 87.02),
        AVERAGE: (0.703, 0.637, 88.03),
    },
}
PAPER_PATTERNS = ("pyramid", "grid", AVERAGE)
CAPTION = (
    "Beside the paper's Table I: our means over successful trials (a dash: no successful "
    "trial, or for Average not every pattern run) above the paper's figures, which come from "
    "its own simulator and language model, for scale."
)


def paper_rows(table: Table) -> tuple[list[str], list[list[str]]]:
    """The columns and rows of the comparison: our rows of Table I, then the paper's, over
    pyramid, grid and Average."""
    columns = ["Method"] + [f"{p}: {header}" for p in PAPER_PATTERNS for _, header, *_ in COLUMNS]
    ours = [
        [row] + [_ours(table, row, p, metric) for p in PAPER_PATTERNS for metric, *_ in COLUMNS]
        for row in table.rows
    ]
    paper = [
        [label] + [f"{value:g}" for p in PAPER_PATTERNS for value in figures[p]]
        for label, figures in PAPER_TABLE_I.items()
    ]
    return columns, ours + paper


def beside_the_paper(table: Table) -> str:
    """The comparison as markdown, under its caption."""
    return "\n".join([CAPTION, "", *table_lines(*paper_rows(table)), ""])


def _ours(table: Table, row: str, pattern: str, metric: str) -> str:
    """A cell of ours: the mean over successful trials, a dash where the table has none
    (the pattern not run, or no success)."""
    if pattern != AVERAGE and pattern not in table.patterns:
        return "–"
    return table.cell(row, pattern, metric)[0]
