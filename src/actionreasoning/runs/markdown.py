"""Markdown tables of text cells, as summaries and reports write them."""

from __future__ import annotations

from collections.abc import Sequence


def table_lines(columns: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """A markdown table: the header, its rule, a line per row."""
    return [
        "| " + " | ".join(columns) + " |",
        "|---" * len(columns) + "|",
        *("| " + " | ".join(row) + " |" for row in rows),
    ]


def captioned_table(
    caption: str, columns: Sequence[str], rows: Sequence[Sequence[str]]
) -> list[str]:
    """A markdown table under a caption; nothing without rows."""
    return [caption, "", *table_lines(columns, rows)] if rows else []
