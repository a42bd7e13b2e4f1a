"""A leaderboard row per method and pattern: success with its Wilson interval, answers
accepted at the first attempt (each agent's too), refusals and prompt tokens per brick
(runs/leaderboard.py computes them)."""

from __future__ import annotations

from collections.abc import Sequence

from actionreasoning.report.collect import Group
from actionreasoning.runs.leaderboard import LEADERBOARD_COLUMNS, by_agent_text, leaderboard_cells
from actionreasoning.runs.markdown import table_lines
from actionreasoning.runs.summary import success_text

BOARD_COLUMNS = ("Method", "Pattern", "Success", *LEADERBOARD_COLUMNS, "First answers by agent")
BOARD_CAPTION = (
    "Success with its Wilson 95 % interval; first answers accepted: of the answers at "
    "attempt 1 of each request to an agent (once a brick; the placement agent twice, and "
    "again after a raise), those accepted as they came; refused and failed answers (repairs "
    "included) and prompt tokens per brick of the pattern, and per brick placed within the "
    "success rule. A dash: no reasoner, no token counted, no brick within the rule, or lines "
    "written before it was counted."
)


def board_rows(groups: Sequence[Group]) -> list[list[str]]:
    """A row per group, as BOARD_COLUMNS shows it."""
    return [
        [
            group.label,
            group.pattern,
            success_text(group.summary.successes, group.summary.trials),
            *leaderboard_cells(group.summary.leaderboard),
            by_agent_text(group.summary.leaderboard),
        ]
        for group in groups
    ]


def board_lines(rows: Sequence[Sequence[str]]) -> list[str]:
    """The leaderboard as markdown: what it counts, then a table (BOARD_COLUMNS)."""
    return [f"Leaderboard. {BOARD_CAPTION}", "", *table_lines(BOARD_COLUMNS, rows)]
