"""The ablation ladder: the rungs of verification side by side, under each condition.

Rows of a report that differ only in method and rung of verification (the single agent;
the six agents with sigma_1..sigma_6 only, with the pre-move checks only, with both) form a
ladder under one condition: the same reasoner and tier, physics, noise and answer errors.
Each rung's trials are pooled over the patterns every rung of the ladder ran, and the rung
gives its success with its Wilson interval, McNemar's exact test against the single agent
on the trials both ran (paired by trial seed), and what became of the corrupted answers:
caught before the move, caught by a gate after it, missed (and of those, the ones that did
harm), with the checks that caught them.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

from actionreasoning.agents.answer_errors import Caught, CorruptionKind
from actionreasoning.agents.verification import Verification
from actionreasoning.report.collect import Group
from actionreasoning.runs.markdown import captioned_table
from actionreasoning.runs.statistics import McNemar, mcnemar_exact, wilson
from actionreasoning.trial.results import AnswerErrorCounts, TrialResult
from actionreasoning.trial.rules import Method, rung_of

#: The rungs in the order of the ladder, with their names.
RUNGS: tuple[tuple[str, Verification, str], ...] = (
    (Method.SINGLE_AGENT, Verification.NONE, "single agent"),
    (Method.AGENTS, Verification.NONE, "six agents, validation only"),
    (Method.AGENTS, Verification.GATES, "σ1–σ6 only"),
    (Method.AGENTS, Verification.CHECKS, "pre-move checks only"),
    (Method.AGENTS, Verification.FULL, "both (the method)"),
)
#: How many of the checks that caught the most a rung names.
TOP_CHECKS = 4

LADDER_COLUMNS = (
    "Condition",
    "Rung",
    "Success (95 % CI)",
    "p vs single agent",
    "Corrupted",
    "Caught before the move",
    "Caught after it",
    "Missed (did harm)",
    "Caught by",
)
LADDER_CAPTION = (
    "Rows that differ only in their rung of verification, under one condition, pooled over "
    "the patterns every rung ran. p: McNemar's exact test against the single agent on the "
    "trials both ran (paired by trial seed). Corrupted answers (eval --answer-errors): caught "
    "before the move (validation, a pre-move check, σ1 or σ6), by a gate after it (σ2–σ5), "
    "or missed: they ran; those that did harm led to a later refusal, a failure or a brick "
    "outside the success rule. Caught by: the checks that caught the most."
)


@dataclass(frozen=True)
class Rung:
    """One rung of a ladder: its trials, pooled over the ladder's patterns."""

    condition: str
    name: str
    results: tuple[TrialResult, ...]
    errors: AnswerErrorCounts


@dataclass(frozen=True)
class LadderRow:
    """A rung as the ladder table shows it."""

    rung: Rung
    versus_single: McNemar | None

    @property
    def cells(self) -> list[str]:
        results, errors = self.rung.results, self.rung.errors
        k, n = sum(r.success for r in results), len(results)
        interval = wilson(k, n)
        success = f"{k}/{n}" + (
            "" if interval is None else f" ({100 * interval.low:.0f}–{100 * interval.high:.0f} %)"
        )
        where = Counter[Caught]()
        for counts in errors.caught.values():
            where.update(counts)
        harmful = sum(
            n for led in errors.led_to.values() for what, n in led.items() if what != "harmless"
        )
        checks = Counter({check: sum(kinds.values()) for check, kinds in errors.checks.items()})
        test = self.versus_single
        return [
            self.rung.condition,
            self.rung.name,
            success,
            "–" if test is None else f"{test.p:.3g} (b {test.b}, c {test.c})",
            str(errors.corrupted),
            str(where[Caught.BEFORE]),
            str(where[Caught.AFTER]),
            f"{where[Caught.MISSED]} ({harmful})",
            ", ".join(f"{c} {n}" for c, n in checks.most_common(TOP_CHECKS)) or "–",
        ]


def ladder_lines(rows: Sequence[LadderRow]) -> list[str]:
    """The ladder as markdown: what it is, then a table (LADDER_COLUMNS)."""
    cells = [row.cells for row in rows]
    return captioned_table(f"The ablation ladder. {LADDER_CAPTION}", LADDER_COLUMNS, cells)


def ladders(groups: Sequence[Group]) -> list[LadderRow]:
    """Every ladder of two or more rungs among ``groups``, rung by rung."""
    found: dict[str, dict[str, list[Group]]] = {}
    for group in groups:
        name = _rung_name(group.results[0])
        if name is not None:
            found.setdefault(_condition(group), {}).setdefault(name, []).append(group)
    rows = []
    for condition, rungs in found.items():
        if len(rungs) < 2:
            continue
        shared = set.intersection(*({g.pattern for g in groups} for groups in rungs.values()))
        pooled = {
            name: Rung(condition, name, *_pool([g for g in rungs[name] if g.pattern in shared]))
            for _, _, name in RUNGS
            if name in rungs
        }
        single = pooled.get(RUNGS[0][2])
        for rung in pooled.values():
            versus = None if single is None or rung is single else _paired(single, rung)
            rows.append(LadderRow(rung, versus))
    return rows


def _rung_name(result: TrialResult) -> str | None:
    """The ladder's name of the rung a results line ran at (None: the classical script)."""
    method = Method(result.method)
    verify = Verification(result.verify) if result.verify else None
    rung = rung_of(method, verify)
    return next((name for m, v, name in RUNGS if m == method and v == rung), None)


def _condition(group: Group) -> str:
    """What a ladder holds fixed, in words: the reasoner and tier, physics, noise and answer
    errors (its rate, persistence and kinds)."""
    first = group.results[0]
    text = f"{first.llm}, tools {first.tools}, {first.physics}, noise {first.noise}"
    errors = group.summary.answer_errors
    if errors is None or not errors.rate:
        return text + ", no answer errors"
    text += f", answer errors {errors.rate:g}"
    if errors.persistence:
        text += f" (persistence {errors.persistence:g})"
    if set(errors.kinds) != set(CorruptionKind):
        text += ", kinds " + ", ".join(errors.kinds)
    return text


def _pool(groups: Sequence[Group]) -> tuple[tuple[TrialResult, ...], AnswerErrorCounts]:
    results = tuple(r for g in groups for r in g.results)
    errors = sum(
        (r.answer_errors for r in results if r.answer_errors is not None), AnswerErrorCounts()
    )
    return results, errors


def _paired(first: Rung, second: Rung) -> McNemar:
    """McNemar's exact test on the trials both rungs ran (paired by trial seed)."""
    one = {(r.pattern, r.trial_seed): r.success for r in first.results}
    two = {(r.pattern, r.trial_seed): r.success for r in second.results}
    common = one.keys() & two.keys()
    b = sum(one[key] and not two[key] for key in common)
    c = sum(two[key] and not one[key] for key in common)
    return mcnemar_exact(b, c)
