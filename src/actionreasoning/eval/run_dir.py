"""An eval output directory: what run it holds (run.json) and its finished trials.

results.jsonl only ever grows by whole lines, each written with one call, flushed and
synced as its trial finishes. A run killed at any moment leaves at most a partial last
line, which resuming cuts off; a trial is never written twice. run.json records what makes
trials comparable, so a different configuration cannot be mixed into the same directory.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import IO, Any

from pydantic import BaseModel, ConfigDict, ValidationError

from actionreasoning.errors import ConfigError
from actionreasoning.eval.results import TrialResult
from actionreasoning.world.config_files import read_user_file
from actionreasoning.world.noise import NoiseLevel
from actionreasoning.world.physics import PhysicsProfile

RESULTS_FILE = "results.jsonl"
MANIFEST_FILE = "run.json"


class RunManifest(BaseModel):
    """What every trial of a run shares. Trial count, workers and outputs may differ."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: str
    pattern: str
    pattern_sha256: str
    seed: int
    llm: str
    llm_limits: dict[str, int | bool]
    success_rule: str
    budget: dict[str, float]
    physics: PhysicsProfile
    noise: NoiseLevel


def digest(text: str) -> str:
    """SHA-256 of a text, hex."""
    return hashlib.sha256(text.encode()).hexdigest()


def open_run(out: Path, manifest: RunManifest) -> list[TrialResult]:
    """Create ``out`` for this run, or check it holds the same run; its finished trials."""
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a directory")
    results, stored = out / RESULTS_FILE, out / MANIFEST_FILE
    if not results.exists() or results.stat().st_size == 0:
        out.mkdir(parents=True, exist_ok=True)
        temporary = stored.with_suffix(".tmp")
        temporary.write_text(manifest.model_dump_json(indent=2) + "\n")
        os.replace(temporary, stored)
        return []
    if not stored.exists():
        raise ConfigError(
            f"{results} exists but {stored} does not: not a run this version can resume; "
            "choose another --out"
        )
    try:
        previous = RunManifest.model_validate_json(read_user_file(stored, "run file"))
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        raise ConfigError(
            f"{stored} is damaged or from an earlier version ({where}: {first['msg']}): "
            "choose another --out"
        ) from error
    if previous != manifest:
        differences = ", ".join(_differences(previous.model_dump(), manifest.model_dump()))
        raise ConfigError(
            f"--out {out} holds a different run ({differences}): choose another --out, "
            "or repeat that run's options to resume it"
        )
    return read_results(results, repair=True)


def _differences(there: dict[str, Any], now: dict[str, Any], prefix: str = "") -> list[str]:
    """Every field (nested ones dotted: ``physics.time_step_s``) that differs, with both values."""
    found = []
    for name in dict.fromkeys([*there, *now]):
        old, new = there.get(name), now.get(name)
        if isinstance(old, dict) and isinstance(new, dict):
            found += _differences(old, new, f"{prefix}{name}.")
        elif old != new:
            found.append(f"{prefix}{name} {old!r} there, {new!r} now")
    return found


def read_results(path: Path, repair: bool = False) -> list[TrialResult]:
    """The trials in a results.jsonl; a partial last line is ignored (cut off if ``repair``)."""
    data = read_user_file(path, "results file", limit=None)
    whole = data.rfind(b"\n") + 1
    if repair and whole < len(data):
        with path.open("r+b") as handle:
            handle.truncate(whole)
    results: list[TrialResult] = []
    seen: set[int] = set()
    for number, line in enumerate(data[:whole].splitlines(), start=1):
        try:
            result = TrialResult.model_validate_json(line)
        except ValidationError as error:
            raise ConfigError(
                f"{path} line {number} is not a trial result ({error.errors()[0]['msg']})"
            ) from error
        if result.trial in seen:
            raise ConfigError(f"{path} line {number} repeats trial {result.trial}")
        seen.add(result.trial)
        results.append(result)
    return results


def append_result(sink: IO[bytes], result: TrialResult) -> None:
    """Write one result line with a single system call and push it to the disk.

    ``sink`` is the results file opened unbuffered for appending (``open(path, "ab", 0)``).
    """
    sink.write((result.model_dump_json() + "\n").encode())
    os.fsync(sink.fileno())
