"""Eval runs grouped for a report: a row per set of run.json conditions, a column per pattern.

Runs are pooled only when every run.json field but the seed and the pattern as given is
the same, and their patterns have the same content (pattern_sha256); nothing is grouped by
a name or a path string. Rows that share a method label get the fields that tell them apart
added to it, and patterns that share a title get their hash.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any, TypeVar

from pydantic import TypeAdapter, ValidationError

from actionreasoning.agents.verification import Verification
from actionreasoning.errors import ConfigError
from actionreasoning.recording.mp4 import Unfinished, check_mp4
from actionreasoning.report.runs import Run, read_runs
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.markdown import plural
from actionreasoning.runs.run_dir import AnyManifest, RecordedManifest, RunManifest
from actionreasoning.runs.summary import RunSummary, summarize
from actionreasoning.trial.provenance import Provenance
from actionreasoning.trial.results import TrialResult
from actionreasoning.trial.rules import Method
from actionreasoning.world.physics import PhysicsProfile
from actionreasoning.world.success import SuccessRule

PATTERN_HASH = "pattern_sha256"
#: The rung of verification each method runs at unless told otherwise, left out of labels.
DEFAULT_VERIFY: dict[str, str] = {
    Method.AGENTS: Verification.FULL,
    Method.SINGLE_AGENT: Verification.NONE,
}
T = TypeVar("T")


@dataclass(frozen=True)
class Group:
    """Every trial of one row's conditions on one pattern, from one or more directories."""

    label: str  # the row: method, backend, conditions
    pattern: str  # the column: the pattern's title
    conditions: dict[str, Any]  # run.json, flattened (see Run.conditions)
    results: tuple[TrialResult, ...]  # ordered by seed and trial
    sources: dict[tuple[int, int], tuple[Path, ...]]  # (seed, trial) -> directories holding it
    summary: RunSummary  # bricks before the first failure and cycle time: where known
    rule: SuccessRule | None  # None where run.json gave it in words (an earlier version)
    repeated: int = 0  # lines identical to a trial already read from another directory

    def snapshot_dir(self, result: TrialResult) -> Path | None:
        """Where the pictures of ``result`` are, if its run kept them."""
        for directory in self.sources[(result.seed, result.trial)]:
            path = RunDir(directory).snapshots(result.trial)
            if path.is_dir():
                return path
        return None

    def video(self, result: TrialResult) -> Path | None:
        """The video of ``result``, if its run filmed it (eval --video) and it is whole: only
        the final name is looked for (never a ``.partial`` one), and a file cut short there
        (left by an earlier version on a full disk) is left out."""
        for directory in self.sources[(result.seed, result.trial)]:
            path = RunDir(directory).video(result)
            if path.is_file() and _whole(path):
                return path
        return None


def _whole(video: Path) -> bool:
    try:
        check_mp4(str(video))
    except (OSError, Unfinished):
        return False
    return True


def pattern_title(pattern: str) -> str:
    """A pattern as given, as a title: a built-in name, or a pattern file's stem."""
    return PurePath(pattern).stem if pattern.endswith((".json", ".yaml", ".yml")) else pattern


def method_label(manifest: AnyManifest, verify: str | None = None) -> str:
    """How a row names a method: with its reasoning backend and tier where it has one, what
    its agents observed where not the state, and its rung of verification (``verify``, of
    its results lines) where not the method's default; its physics profile and, where there
    are any, its noise level and answer error rate (with its persistence)."""
    rung = "" if verify in (None, DEFAULT_VERIFY.get(manifest.method)) else f", verify {verify}"
    seen = "" if manifest.observation == "state" else f", observe {manifest.observation}"
    name = (
        manifest.method
        if manifest.llm == "none"
        else f"{manifest.method} ({manifest.llm}, tools {manifest.tier}{seen}{rung})"
    )
    noise = "" if manifest.noise_name == "none" else f", noise {manifest.noise_name}"
    rate, persistence = manifest.answer_errors.rate, manifest.answer_errors.persistence
    errors = f", answer errors {rate:g}" if rate else ""
    errors += f" (persistence {persistence:g})" if rate and persistence else ""
    return f"{name}, {manifest.physics_name}{noise}{errors}"


def show(value: Any) -> str:
    """A run.json value, short: floats as %g where that loses nothing, the rest as JSON."""
    if isinstance(value, float) and float(f"{value:g}") == value:
        return f"{value:g}"
    return value if isinstance(value, str) else json.dumps(value)


def differing(conditions: Sequence[dict[str, Any]]) -> list[str]:
    """The fields whose values are not the same in all ``conditions`` (a missing one counts)."""
    names = dict.fromkeys(name for c in conditions for name in c)
    return [
        name
        for name in names
        if len({json.dumps(c[name]) if name in c else None for c in conditions}) > 1
    ]


def load_groups(directories: Sequence[Path]) -> list[Group]:
    """The trials of every directory, grouped by conditions, the rung of verification of
    their lines, and pattern content."""
    runs = read_runs(directories)
    found: dict[tuple[str, str], list[Run]] = {}
    for run in runs:
        conditions = run.conditions()
        pattern = conditions.pop(PATTERN_HASH)
        row = json.dumps([conditions, run.results[0].verify], sort_keys=True)
        found.setdefault((row, pattern), []).append(run)
    rows = _row_labels({row: members[0] for (row, _), members in found.items()})
    columns = _pattern_titles({p: members[0] for (_, p), members in found.items()})
    return [_pool(rows[row], columns[p], members) for (row, p), members in found.items()]


def _row_labels(rows: dict[str, Run]) -> dict[str, str]:
    """A unique label per row: the method label, with the fields that tell apart rows that
    share it (``classical, precise [budget.max_steps=2000]``)."""
    by_label: dict[str, list[str]] = {}
    for row, run in rows.items():
        by_label.setdefault(method_label(run.manifest, run.results[0].verify), []).append(row)
    labels = {}
    for label, same in by_label.items():
        conditions = {row: rows[row].conditions() for row in same}
        names = [n for n in differing(list(conditions.values())) if n != PATTERN_HASH]
        for row in same:
            shown = ", ".join(f"{n}={show(conditions[row].get(n, '–'))}" for n in names)
            labels[row] = f"{label} [{shown}]" if shown else label
    return labels


def _pattern_titles(patterns: dict[str, Run]) -> dict[str, str]:
    """A unique title per pattern content: the title, with the hash where two share it."""
    titles = {p: pattern_title(run.manifest.pattern) for p, run in patterns.items()}
    shared = {t for t in titles.values() if list(titles.values()).count(t) > 1}
    return {p: f"{t} ({p[:8]})" if t in shared else t for p, t in titles.items()}


def _pool(label: str, pattern: str, runs: Sequence[Run]) -> Group:
    """One group from the runs of one row and pattern; the same trial in two directories
    is counted once if its lines agree, and refused if they do not."""
    kept: dict[tuple[int, int], TrialResult] = {}
    sources: dict[tuple[int, int], tuple[Path, ...]] = {}
    repeated = 0
    for run in runs:
        for result in run.results:
            key = (result.seed, result.trial)
            if key in kept:
                if _same(kept[key], result):
                    sources[key] += (run.directory,)
                    repeated += 1
                    continue
                raise ConfigError(
                    f"trial {result.trial} of seed {result.seed} is in "
                    f"{RunDir(sources[key][0]).results} and {RunDir(run.directory).results} under "
                    "the same run.json conditions, with different results: report one of them"
                )
            kept[key], sources[key] = result, (run.directory,)
    results = tuple(kept[key] for key in sorted(kept))
    manifest = runs[0].manifest
    rule, physics = _rule_and_physics(manifest)
    summary = summarize(
        results,
        wall_time_s=0.0,
        rule=rule or SuccessRule(),
        physics=physics,
        answer_errors=manifest.answer_errors,
    )
    if rule is None:
        summary = summary.model_copy(update={"placed_before_first_failure_mean": None})
    return Group(
        label=label,
        pattern=pattern,
        conditions=runs[0].conditions(),
        results=results,
        sources=sources,
        summary=summary,
        rule=rule,
        repeated=repeated,
    )


def _rule_and_physics(manifest: AnyManifest) -> tuple[SuccessRule | None, PhysicsProfile | None]:
    """The success rule and physics profile of a run, None where its run.json records one
    otherwise than this version reads it (an earlier version gave the rule in words)."""
    if isinstance(manifest, RunManifest):
        return manifest.config.success_rule, manifest.config.physics
    if isinstance(manifest, RecordedManifest):
        rule, physics = manifest.config.get("success_rule"), manifest.config.get("physics")
    else:
        rule, physics = manifest.success_rule, manifest.physics
    return _read(SuccessRule, rule), _read(PhysicsProfile, physics)


def _read(kind: type[T], data: Any) -> T | None:
    try:
        return TypeAdapter(kind).validate_python(data)
    except ValidationError:
        return None


def _same(first: TrialResult, second: TrialResult) -> bool:
    """Whether two lines record the same outcome (the pattern as given aside: runs.py has
    checked that both patterns have the same content; and which code wrote them)."""
    aside = {"pattern", *Provenance.model_fields}
    return first.model_dump(exclude=aside) == second.model_dump(exclude=aside)


def labels(groups: Sequence[Group]) -> list[str]:
    """Row labels in first-seen order."""
    return list(dict.fromkeys(g.label for g in groups))


def patterns(groups: Sequence[Group]) -> list[str]:
    """Pattern titles in first-seen order."""
    return list(dict.fromkeys(g.pattern for g in groups))


def condition_notes(groups: Sequence[Group]) -> list[str]:
    """What a reader must know about how runs were grouped: the run.json fields that differ
    between rows, patterns that share a title, trials found in two directories."""
    notes = []
    rows = {g.label: g.conditions for g in groups}
    names = [n for n in differing(list(rows.values())) if n != PATTERN_HASH]
    if names:
        notes.append(
            f"Rows differ in run.json: {_compact(names)}. All its other fields are the same "
            "in every row (seeds may differ)."
        )
    shared: dict[str, list[str]] = {}  # a title two pattern contents share -> their hashes
    for group in groups:
        digest = group.conditions[PATTERN_HASH]
        title = group.pattern.removesuffix(f" ({digest[:8]})")
        if title != group.pattern and digest not in shared.setdefault(title, []):
            shared[title].append(digest)
    for title, hashes in shared.items():
        notes.append(
            f"{title}: {len(hashes)} different pattern files (pattern_sha256 "
            f"{', '.join(h[:8] for h in hashes)}), shown apart: the file was edited "
            "between runs, or two files share the name."
        )
    for group in groups:
        if group.repeated:
            notes.append(
                f"{group.label} on {group.pattern}: {plural(group.repeated, 'trial line')} "
                f"{'is' if group.repeated == 1 else 'are'} also in another directory, identical: "
                f"{'it is' if group.repeated == 1 else 'each'} counted once."
            )
    return notes


def _compact(names: Sequence[str]) -> str:
    """Dotted names, those under one field together: ``physics.{name, solver_iterations}``;
    a field that is a value in one run and has fields in another is named both ways
    (``llm, llm.{spec, fallback}``: none for the classical script, a backend for agents)."""
    by_top: dict[str, list[str]] = {}
    for name in names:
        top, _, rest = name.partition(".")
        by_top.setdefault(top, []).append(rest)
    parts = []
    for top, rests in by_top.items():
        if "" in rests:
            parts.append(top)
        nested = [r for r in rests if r]
        if len(nested) == 1:
            parts.append(f"{top}.{nested[0]}")
        elif nested:
            parts.append(f"{top}.{{{', '.join(nested)}}}")
    return ", ".join(parts)
