"""The paper's protocol (Table I) as one command: which runs, and where they go.

Table I compares the classical controller with the agents on two patterns, pyramid and
grid, each over seeded trials of 6 bricks under the paper's physics; we run the single
agent too (the ablation without the pipeline). ``actionreasoning paper --out DIR`` runs
each (method, pattern) into ``DIR/runs/METHOD-PATTERN``, as ``eval`` would (so a second
call resumes them), then ``report`` into ``DIR/report``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from actionreasoning.trial.rules import Method

#: The methods of our Table I, in its row order, and the paper's two patterns.
METHODS: tuple[Method, ...] = (Method.AGENTS, Method.SINGLE_AGENT, Method.CLASSICAL)
PATTERNS: tuple[str, ...] = ("pyramid", "grid")
#: The paper's trials per pattern ("10 trials per pattern under randomized initial poses").
TRIALS = 10


@dataclass(frozen=True)
class PaperRun:
    """One (method, pattern) cell of the protocol and the directory of its run."""

    method: Method
    pattern: str
    out: Path


def paper_runs(out: Path) -> list[PaperRun]:
    """The protocol's runs under ``out``, in Table I's order."""
    return [
        PaperRun(method, pattern, out / "runs" / f"{method}-{pattern}")
        for method in METHODS
        for pattern in PATTERNS
    ]
