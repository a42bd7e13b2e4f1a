"""Eval directories read back for a report: each one's run.json and the trials under it.

A directory is named by its resolved path, so one given two ways (``r``, ``./r/``, a link
to it) is read once. Every line must be a trial of the run its run.json describes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from actionreasoning.errors import ConfigError
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.run_dir import (
    AnyManifest,
    check_lines,
    read_any_manifest,
    read_results,
)
from actionreasoning.trial.results import TrialResult

#: run.json fields that do not make trials incomparable: the seed (runs of other seeds are
#: pooled) and the pattern as it was given (its content is compared, by pattern_sha256).
NOT_CONDITIONS = ("seed", "pattern")


@dataclass(frozen=True)
class Run:
    """One eval directory: the run it holds and its finished trials."""

    directory: Path
    manifest: AnyManifest
    results: tuple[TrialResult, ...]

    def conditions(self) -> dict[str, Any]:
        """Every run.json value that trials must share to be pooled, nested ones dotted and
        those of the trial configuration by their path in it (``budget.max_steps``)."""
        fields = self.manifest.fields()
        return {name: value for name, value in fields.items() if name not in NOT_CONDITIONS}


def unique(directories: Sequence[Path]) -> list[Path]:
    """The directories resolved, each once, in the order first given."""
    return list(dict.fromkeys(directory.resolve() for directory in directories))


def read_runs(directories: Sequence[Path]) -> list[Run]:
    """The run of every directory, each read once."""
    return [read_run(directory) for directory in unique(directories)]


def read_run(directory: Path) -> Run:
    """A directory's run; one without results, without run.json, or whose lines belong to
    another run is an error. A run of an earlier version is read as far as it recorded."""
    run = RunDir(directory)
    path, stored = run.results, run.manifest
    for name, there in ((run.RESULTS, path), (run.MANIFEST, stored)):
        if there.exists() and not there.is_file():
            raise ConfigError(f"{there} is not a regular file: not a {name} eval writes")
    if not path.is_file():
        raise ConfigError(f"{directory} holds no {run.RESULTS}: not an eval --out directory")
    if not stored.is_file():
        raise ConfigError(
            f"{directory} holds {run.RESULTS} but no {run.MANIFEST}: the conditions of its "
            "trials are unknown, so they cannot be compared"
        )
    manifest = read_any_manifest(stored)
    results = read_results(path)
    if not results:
        raise ConfigError(f"{path} is empty: no trial has finished there yet")
    check_lines(results, manifest, path, stored)
    return Run(directory=directory, manifest=manifest, results=tuple(results))
