"""Markdown tables of text cells, and counted nouns, as summaries and reports write them."""

from __future__ import annotations

from collections.abc import Sequence


def plural(count: int, noun: str, nouns: str | None = None) -> str:
    """``1 trial``, ``2 trials``: ``count`` with ``noun`` in the number it takes (``nouns``
    where the plural is not ``noun`` + s)."""
    return f"{count} {noun if count == 1 else nouns or noun + 's'}"


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
