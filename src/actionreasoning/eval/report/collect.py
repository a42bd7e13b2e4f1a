"""Eval output directories read back, grouped by method (with backend) and pattern."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import get_args

from actionreasoning.agents.outputs import SingleAgentStep
from actionreasoning.errors import ConfigError
from actionreasoning.eval.results import TrialResult
from actionreasoning.eval.run_dir import RESULTS_FILE, read_results
from actionreasoning.eval.summary import RunSummary, summarize

#: Stages in the order a brick goes through them: the single agent's cycle, whose names
#: the six agents and the classical script share.
STAGE_ORDER = tuple(step for step in get_args(SingleAgentStep) if step != "done")


@dataclass(frozen=True)
class Group:
    """Every trial of one method and backend on one pattern, from one or more directories."""

    label: str
    pattern: str
    directories: tuple[Path, ...]
    results: tuple[TrialResult, ...]
    summary: RunSummary
    repeated: int = 0  # trials found in two directories (same seed and index), counted once

    def snapshot_dir(self, trial: int) -> Path | None:
        """Where the pictures of ``trial`` are, if its run kept them."""
        for directory in self.directories:
            path = directory / "snapshots" / f"trial_{trial:03d}"
            if path.is_dir():
                return path
        return None


def method_label(result: TrialResult) -> str:
    """How a table row names a method: with its reasoning backend where it has one, its
    physics profile and, where there is any, its noise level. Runs whose labels differ are
    never pooled."""
    name = result.method if result.llm == "none" else f"{result.method} ({result.llm})"
    noise = "" if result.noise == "none" else f", noise {result.noise}"
    return f"{name}, {result.physics}{noise}"


def load_groups(directories: Sequence[Path]) -> list[Group]:
    """The trials of every directory, grouped; a directory without results is an error."""
    found: dict[tuple[str, str], list[tuple[Path, TrialResult]]] = {}
    for directory in directories:
        path = directory / RESULTS_FILE
        if not path.is_file():
            raise ConfigError(f"{directory} holds no {RESULTS_FILE}: not an eval --out directory")
        results = read_results(path)
        if not results:
            raise ConfigError(f"{path} is empty: no trial has finished there yet")
        for result in results:
            found.setdefault((method_label(result), result.pattern), []).append((directory, result))
    groups = []
    for (label, pattern), members in found.items():
        unique = {(r.seed, r.trial): r for _, r in reversed(members)}  # the first one kept
        results = tuple(unique[key] for key in sorted(unique))
        groups.append(
            Group(
                label=label,
                pattern=pattern,
                directories=tuple(dict.fromkeys(d for d, _ in members)),
                results=results,
                summary=summarize(results, wall_time_s=0.0),
                repeated=len(members) - len(results),
            )
        )
    return groups


def labels(groups: Sequence[Group]) -> list[str]:
    """Method labels in first-seen order."""
    return list(dict.fromkeys(g.label for g in groups))


def patterns(groups: Sequence[Group]) -> list[str]:
    """Patterns in first-seen order."""
    return list(dict.fromkeys(g.pattern for g in groups))
