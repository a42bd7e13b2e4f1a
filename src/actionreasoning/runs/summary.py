"""Aggregate a run's trials into summary.json and a Table-I style summary.md."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, NonNegativeFloat, NonNegativeInt, PositiveInt

from actionreasoning.agents.answer_errors import AnswerErrors, Caught, CorruptionKind
from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.records import FailureClass, FailureCode
from actionreasoning.runs.courses import (
    CourseMetrics,
    CycleTime,
    bricks_set_down,
    cycle_time,
    per_course,
    placed_before_first_failure,
)
from actionreasoning.runs.leaderboard import (
    LEADERBOARD_COLUMNS,
    Leaderboard,
    first_attempts_text,
    leaderboard,
    leaderboard_cells,
)
from actionreasoning.runs.markdown import plural, table_lines
from actionreasoning.runs.statistics import (
    BOOTSTRAP_RESAMPLES,
    BOOTSTRAP_SEED,
    RateInterval,
    bootstrap_mean,
    wilson,
)
from actionreasoning.trial.provenance import Provenance
from actionreasoning.trial.results import (
    AnswerErrorCounts,
    LLMUsage,
    PerceptionErrors,
    Refusals,
    TrialResult,
    sum_refusals,
)
from actionreasoning.world.noise import NoiseLevel
from actionreasoning.world.physics import PhysicsProfile
from actionreasoning.world.success import SuccessRule

K = TypeVar("K", bound=str)

METRICS = ("rotation_error_deg", "center_offset_cm", "iou", "symmetric_rotation_error_deg")


class MetricStats(BaseModel):
    """Mean and (population) standard deviation of a per-trial metric, and the bootstrap
    95 % interval of the mean (runs/statistics.py); None without data, and the interval
    absent in summaries written before it was computed."""

    model_config = ConfigDict(frozen=True)

    #: The metrics (METRICS) are all offsets, angles or overlaps: none is negative.
    mean: NonNegativeFloat | None
    std: NonNegativeFloat | None
    ci_low: NonNegativeFloat | None = Field(None, exclude_if=lambda value: value is None)
    ci_high: NonNegativeFloat | None = Field(None, exclude_if=lambda value: value is None)


class AnswerErrorTotals(AnswerErrorCounts):
    """A run's answer errors: the rate, kinds and persistence it ran with (persistence absent
    at 0), its trials' counts summed."""

    rate: float = Field(ge=0.0, le=1.0)
    kinds: tuple[CorruptionKind, ...]
    persistence: float = Field(0.0, ge=0.0, le=1.0, exclude_if=lambda value: value == 0.0)


class RunSummary(Provenance):
    """The figures of one eval run (one method, one pattern), and which code made them."""

    model_config = ConfigDict(frozen=True, extra="ignore")

    method: str
    pattern: str
    llm: str
    physics: PhysicsProfile | None = None
    noise: NoiseLevel | None = None
    #: The reasoning tier; None in summaries written before tiers existed (solve).
    tools: str | None = None
    #: What the agents observed (agents/observation.py); absent when the state, as in
    #: summaries written before pictures existed.
    observe: str = Field("state", exclude_if=lambda shown: shown == "state")
    #: The rung of verification (agents/verification.py); None for the classical script and
    #: in summaries written before rungs existed.
    verify: str | None = None
    seed: NonNegativeInt
    trials: PositiveInt
    successes: NonNegativeInt
    success_rate: float = Field(ge=0.0, le=1.0)
    #: The Wilson 95 % interval of the success rate; None in summaries written before it.
    success_interval: RateInterval | None = None
    #: Bricks within the success rule's limits of their targets, a mean per trial.
    bricks_placed_mean: NonNegativeFloat
    #: Bricks set down on their targets whatever their errors, a mean per trial; None where
    #: a line does not tell (courses.bricks_set_down) and in summaries written before it.
    bricks_set_down_mean: NonNegativeFloat | None = None
    bricks_per_trial: NonNegativeInt = 0
    success_rule: str
    successful: dict[str, MetricStats]
    all_trials: dict[str, MetricStats]
    failures: dict[FailureCode, NonNegativeInt]
    failure_examples: dict[FailureCode, NonNegativeInt]
    #: The failures by what ended them (every class, zeros included); empty in summaries
    #: written before classes were counted.
    failure_classes: dict[FailureClass, NonNegativeInt] = Field(default_factory=dict)
    llm_usage: LLMUsage
    llm_usage_by_agent: dict[str, LLMUsage] = Field(default_factory=dict)
    llm_mode: str | None = None
    decisions: NonNegativeInt = 0
    fallback_decisions: NonNegativeInt = 0
    #: The wall time of this session's trials (``trials - resumed_trials`` of them): an
    #: earlier session's, whose trials were resumed, is not recorded (results.jsonl holds
    #: no wall time, so that a seed gives the same lines).
    wall_time_s: NonNegativeFloat
    resumed_trials: NonNegativeInt = 0
    answer_errors: AnswerErrorTotals | None = Field(None, exclude_if=lambda totals: totals is None)
    #: Refused and failed answers by agent and category, summed over the trials (absent
    #: when there were none).
    refusals: Refusals = Field(default_factory=dict, exclude_if=lambda counts: not counts)
    #: Answers nobody corrupted that a pre-move check, sigma_1 or sigma_6 refused, by
    #: ``gate:check``, summed over the trials (absent when there were none).
    premove_refusals: dict[str, NonNegativeInt] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )
    #: Per course, over all trials; absent in summaries written before courses were measured.
    courses: list[CourseMetrics] = Field(default_factory=list)
    placed_before_first_failure_mean: NonNegativeFloat | None = None
    #: Needs the run's physics (its time step).
    cycle_time: CycleTime | None = None
    #: None in summaries written before it was computed.
    leaderboard: Leaderboard | None = None
    #: With pictures: per agent, how far its answers' poses of bricks were from them, over
    #: every trial; absent without pictures.
    perception: dict[str, PerceptionErrors] = Field(
        default_factory=dict, exclude_if=lambda errors: not errors
    )


def failure_classes(failures: Mapping[FailureCode, int]) -> dict[FailureClass, int]:
    """The failures counted by class, every class present (a class none fell in: 0)."""
    counts = dict.fromkeys(FailureClass, 0)
    for reason, count in failures.items():
        counts[reason.failure_class] += count
    return counts


def classes_text(counts: Mapping[FailureClass, int]) -> str:
    """``reasoning 1, physics 2``: the counts of :func:`failure_classes` in words."""
    return ", ".join(f"{kind} {count}" for kind, count in counts.items())


def describe_rule(rule: SuccessRule) -> str:
    """The success rule in words, as printed in every summary."""
    return (
        f"every brick within {rule.max_center_offset_cm:g} cm and "
        f"{rule.max_rotation_error_deg:g} deg (plain geodesic) of its target, and every brick "
        f"at rest (< {rule.max_speed_mps * 100:g} cm/s, < {rule.max_angular_speed_radps:g} rad/s) "
        "after the final settle"
    )


def _stats(results: Sequence[TrialResult], metric: str) -> MetricStats:
    values = [getattr(r.metrics, metric) for r in results]
    interval = bootstrap_mean(values)
    if interval is None:
        return MetricStats(mean=None, std=None)
    return MetricStats(
        mean=float(np.mean(values)),
        std=float(np.std(values)),
        ci_low=interval.low,
        ci_high=interval.high,
    )


def summarize(
    results: Sequence[TrialResult],
    wall_time_s: float,
    rule: SuccessRule = SuccessRule(),
    llm_mode: str | None = None,
    resumed_trials: int = 0,
    physics: PhysicsProfile | None = None,
    noise: NoiseLevel | None = None,
    answer_errors: AnswerErrors | None = None,
    tools: str | None = None,
) -> RunSummary:
    """Means and standard deviations over successful trials (the paper's protocol) and all;
    with ``answer_errors`` at a rate above 0, what they corrupted and what caught it."""
    if not results:
        raise ValueError("no trial results to summarize")
    first = results[0]
    ok = [r for r in results if r.success]
    failures = Counter(r.failure.reason for r in results if r.failure is not None)
    examples: dict[FailureCode, int] = {}
    for r in results:
        if r.failure is not None:
            examples.setdefault(r.failure.reason, r.trial)
    return RunSummary(
        method=first.method,
        pattern=first.pattern,
        llm=first.llm,
        physics=physics,
        noise=noise,
        tools=tools,
        observe=first.observe,
        verify=first.verify,
        seed=first.seed,
        trials=len(results),
        successes=len(ok),
        success_rate=len(ok) / len(results),
        success_interval=wilson(len(ok), len(results)),
        bricks_placed_mean=float(np.mean([r.bricks_placed for r in results])),
        bricks_set_down_mean=_mean_known([bricks_set_down(r) for r in results]),
        bricks_per_trial=len(first.bricks),
        success_rule=describe_rule(rule),
        successful={m: _stats(ok, m) for m in METRICS},
        all_trials={m: _stats(results, m) for m in METRICS},
        failures=dict(sorted(failures.items())),
        failure_examples=examples,
        failure_classes=failure_classes(failures),
        llm_usage=sum((r.llm_usage for r in results), LLMUsage()),
        llm_usage_by_agent={
            agent: sum((r.llm_usage_by_agent.get(agent, LLMUsage()) for r in results), LLMUsage())
            for agent in dict.fromkeys(a for r in results for a in r.llm_usage_by_agent)
        },
        llm_mode=llm_mode,
        decisions=sum(r.decisions for r in results),
        fallback_decisions=sum(r.fallback_decisions for r in results),
        wall_time_s=wall_time_s,
        resumed_trials=resumed_trials,
        answer_errors=_answer_error_totals(results, answer_errors),
        refusals=sum_refusals(r.refusals for r in results),
        premove_refusals=dict(
            sorted(sum((Counter(r.premove_refusals) for r in results), Counter[str]()).items())
        ),
        courses=per_course(results),
        placed_before_first_failure_mean=float(
            np.mean([placed_before_first_failure(r, rule) for r in results])
        ),
        cycle_time=None if physics is None else cycle_time(results, physics.time_step_s),
        leaderboard=leaderboard(results),
        perception=_perception(results),
    )


def _mean_known(values: Sequence[int | None]) -> float | None:
    """The mean of ``values``; None if any is unknown."""
    known = [v for v in values if v is not None]
    return float(np.mean(known)) if len(known) == len(values) else None


def _answer_error_totals(
    results: Sequence[TrialResult], errors: AnswerErrors | None
) -> AnswerErrorTotals | None:
    if errors is None or not errors.rate:
        return None
    counts = sum((r.answer_errors or AnswerErrorCounts() for r in results), AnswerErrorCounts())
    return AnswerErrorTotals(
        rate=errors.rate, kinds=errors.kinds, persistence=errors.persistence, **dict(counts)
    )


def stats_text(stats: MetricStats, scale: float = 1.0, digits: int = 3) -> str:
    """``0.530 ± 0.153 [0.441, 0.618]``: mean ± standard deviation [bootstrap interval, where
    known], scaled; n/a without data."""
    if stats.mean is None or stats.std is None:
        return "n/a"
    text = f"{stats.mean * scale:.{digits}f} ± {stats.std * scale:.{digits}f}"
    if stats.ci_low is None or stats.ci_high is None:
        return text
    return f"{text} [{stats.ci_low * scale:.{digits}f}, {stats.ci_high * scale:.{digits}f}]"


def success_text(successes: int, trials: int) -> str:
    """``17/20 (85 %, 95 % CI 64–95 %)``: the Wilson interval of the success rate."""
    interval = wilson(successes, trials)
    if interval is None:
        return f"{successes}/{trials}"
    return (
        f"{successes}/{trials} ({100 * successes / trials:.0f} %, 95 % CI "
        f"{100 * interval.low:.0f}–{100 * interval.high:.0f} %)"
    )


def summary_markdown(summary: RunSummary) -> str:
    """A Table-I style markdown report of one run."""
    lines = [
        f"# {summary.method} on {summary.pattern}"
        + (f" under {summary.physics.name} physics" if summary.physics else "")
        + (f", noise {summary.noise.name}" if summary.noise else "")
        + (f", tools {summary.tools}" if summary.tools and summary.llm != "none" else "")
        + (f", observe {summary.observe}" if summary.observe != "state" else "")
        + (f", verify {summary.verify}" if summary.verify else "")
        + (f", answer errors {summary.answer_errors.rate:g}" if summary.answer_errors else "")
        + (
            f" (persistence {summary.answer_errors.persistence:g})"
            if summary.answer_errors and summary.answer_errors.persistence
            else ""
        ),
        "",
        f"Reasoning backend: `{summary.llm}` · seed {summary.seed} · "
        f"{plural(summary.trials, 'trial')} · {wall_time_text(summary)}",
        "",
        *_condition_lines(summary),
        "Means ± standard deviations over successful trials (per-brick values averaged per "
        f"trial), a bootstrap 95 % interval of the mean in brackets ({BOOTSTRAP_RESAMPLES} "
        f"resamples, seed {BOOTSTRAP_SEED}); success with its Wilson 95 % interval."
        + ("" if summary.successes else " No trial succeeded: the second row is over all trials."),
        "",
        "| Method | Rot. Err (°) ↓ | Ctr. Off. (cm) ↓ | IoU (%) ↑ | Sym. Rot. Err (°) ↓ "
        "| Success |",
        "|---|---|---|---|---|---|",
        _table_row(summary.method, summary.successful, summary),
        *(
            []
            if summary.successes
            else [_table_row(f"{summary.method}, all trials", summary.all_trials, summary)]
        ),
        "",
        *_leaderboard_lines(summary),
        *_perception_lines(summary),
        _bricks_line(summary),
        f"Success rule: {summary.success_rule}.",
        "",
        *_course_lines(summary),
    ]
    if summary.failures:
        lines += [
            f"Failures by class: {classes_text(summary.failure_classes)}.",
            "",
            "| Failure reason | Class | Meaning | Trials | Example trial |",
            "|---|---|---|---|---|",
        ]
        lines += [
            f"| `{reason}` | {reason.failure_class} | {reason.meaning} | {count} | "
            f"{summary.failure_examples[reason]} |"
            for reason, count in summary.failures.items()
        ]
    else:
        lines.append("No failures.")
    if summary.refusals:
        lines += [
            "",
            "Refused and failed answers (repairs included) by agent and error category:",
            "",
            *category_table("Agent", summary.refusals),
        ]
    if summary.premove_refusals:
        lines += ["", *premove_refusal_lines(summary.premove_refusals)]
    if summary.answer_errors is not None:
        lines += ["", *_answer_error_lines(summary.answer_errors)]
    if summary.llm_usage.calls:
        lines += ["", *_llm_lines(summary)]
    return "\n".join(lines) + "\n"


def wall_time_text(summary: RunSummary) -> str:
    """The run's wall time in words: this session's, and how many trials it ran where an
    earlier session (whose time is not recorded) finished the others."""
    resumed, seconds = summary.resumed_trials, summary.wall_time_s
    if not resumed:
        return f"wall time {seconds:.1f} s"
    earlier = f"{plural(resumed, 'trial')} finished by an earlier session, not timed here"
    if resumed >= summary.trials:
        return f"no trial run in this session ({earlier})"
    ran = plural(summary.trials - resumed, "trial")
    return f"wall time {seconds:.1f} s for the {ran} run in this session ({earlier})"


def _bricks_line(summary: RunSummary) -> str:
    """The bricks set down per trial, whatever their errors, and those within the rule."""
    of = f" of {summary.bricks_per_trial}" if summary.bricks_per_trial else ""
    set_down = summary.bricks_set_down_mean
    return (
        "Bricks per trial: "
        + ("" if set_down is None else f"set down {set_down:.2f}{of} (whatever their errors), ")
        + f"within the success rule {summary.bricks_placed_mean:.2f}{of}."
    )


def _table_row(label: str, stats: Mapping[str, MetricStats], summary: RunSummary) -> str:
    """A row of summary.md's Table I: the means of ``stats``, the run's success."""
    cells = [
        stats_text(stats["rotation_error_deg"]),
        stats_text(stats["center_offset_cm"]),
        stats_text(stats["iou"], 100.0, 2),
        stats_text(stats["symmetric_rotation_error_deg"]),
        success_text(summary.successes, summary.trials),
    ]
    return f"| {label} | " + " | ".join(cells) + " |"


def _leaderboard_lines(summary: RunSummary) -> list[str]:
    """The leaderboard figures, and each agent's first answers where there are several;
    nothing for the classical script, which has none."""
    board = summary.leaderboard
    if board is None or summary.llm == "none":
        return []
    lines = [
        "First answers accepted: of the answers at attempt 1 of each request to an agent (once "
        "a brick; the placement agent twice, and again after a raise), those accepted as they "
        "came; refused and failed answers (repairs included) and prompt tokens per brick of "
        "the pattern, and tokens per brick placed within the success rule:",
        "",
        *table_lines(LEADERBOARD_COLUMNS, [leaderboard_cells(board)]),
        "",
    ]
    if len(board.first_attempts_by_agent) > 1:
        lines += [
            "First answers (attempt 1) of each agent, and how many were accepted as they came:",
            "",
            "| Agent | First answers | Accepted |",
            "|---|---|---|",
            *(
                f"| `{agent}` | {n.asked} | {first_attempts_text(n)} |"
                for agent, n in board.first_attempts_by_agent.items()
            ),
            "",
        ]
    return lines


def _perception(results: Sequence[TrialResult]) -> dict[str, PerceptionErrors]:
    """Each agent's perception errors over every trial."""
    errors: dict[str, PerceptionErrors] = {}
    for result in results:
        for agent, seen in result.perception.items():
            errors[agent] = errors.get(agent, PerceptionErrors()) + seen
    return errors


def _perception_lines(summary: RunSummary) -> list[str]:
    """With pictures: how far each agent's answers' poses of bricks were from them."""
    if not summary.perception:
        return []
    return [
        "Perception: how far the answers that named a brick's pose (an approach over it, a "
        "grasp pose on it) were from the brick as measured, in the plane and in yaw:",
        "",
        "| Agent | Answers | Centre offset (cm) mean | max | Yaw error (°) mean | max |",
        "|---|---|---|---|---|---|",
        *(
            f"| `{agent}` | {e.answers} | {e.centre_offset_cm_mean:.3f} | "
            f"{e.centre_offset_cm_max:.3f} | {e.yaw_error_deg_mean:.3f} | "
            f"{e.yaw_error_deg_max:.3f} |"
            for agent, e in summary.perception.items()
        ),
        "",
    ]


def _course_lines(summary: RunSummary) -> list[str]:
    """Per-course metrics, bricks before the first failure and cycle time, where measured."""
    lines = []
    if summary.courses:
        lines += [
            "Per course, over all trials' bricks (means ± standard deviations):",
            "",
            *course_table(summary.courses),
            "",
        ]
    if summary.placed_before_first_failure_mean is not None:
        lines.append(
            "Bricks within the success rule before the first brick out of it, per trial: "
            f"{summary.placed_before_first_failure_mean:.2f}."
        )
    if summary.cycle_time is not None and (pace := cycle_text(summary.cycle_time)):
        lines.append(f"Cycle time: {pace}.")
    return [*lines, ""] if lines else []


def cycle_text(time: CycleTime) -> str:
    """``11.0 simulated s per brick set down (327 an hour); 33.0 s per brick within the
    success rule (109 an hour)``: the figures known; empty without any."""
    parts = []
    if time.seconds_per_brick_set_down is not None and time.bricks_set_down_per_hour:
        parts.append(
            f"{time.seconds_per_brick_set_down:.1f} simulated s per brick set down "
            f"({time.bricks_set_down_per_hour:.0f} an hour)"
        )
    if time.seconds_per_brick is not None and time.bricks_per_hour:
        parts.append(
            f"{time.seconds_per_brick:.1f} simulated s per brick within the success rule "
            f"({time.bricks_per_hour:.0f} an hour)"
        )
    return "; ".join(parts)


COURSE_COLUMNS = ("Course", "Bricks", "Ctr. Off. (cm)", "Rot. Err (°)", "IoU (%)")


def course_cells(course: CourseMetrics) -> list[str]:
    """One course's row: its number, bricks, and each metric's mean ± standard deviation."""
    offset, rotation, iou = course.center_offset_cm, course.rotation_error_deg, course.iou
    return [
        str(course.course),
        str(course.bricks),
        f"{offset[0]:.3f} ± {offset[1]:.3f}",
        f"{rotation[0]:.3f} ± {rotation[1]:.3f}",
        f"{100 * iou[0]:.2f} ± {100 * iou[1]:.2f}",
    ]


def course_table(courses: Sequence[CourseMetrics]) -> list[str]:
    """A markdown table of per-course metrics, a row per course (COURSE_COLUMNS)."""
    return [
        "| " + " | ".join(COURSE_COLUMNS) + " |",
        "|---" * len(COURSE_COLUMNS) + "|",
        *("| " + " | ".join(course_cells(c)) + " |" for c in courses),
    ]


def premove_refusal_lines(counts: Mapping[str, int]) -> list[str]:
    """The answers nobody corrupted that a pre-move check, sigma_1 or sigma_6 refused."""
    return [
        "Answers nobody corrupted, refused before the move by a pre-move check, σ1 or σ6 "
        "(each a check refusing an answer its reasoner believed right):",
        "",
        "| Check | Answers |",
        "|---|---|",
        *(f"| `{check}` | {n} |" for check, n in counts.items()),
    ]


#: Where a corrupted answer was caught, as summary.md and the report title it.
CAUGHT_TITLES = {
    Caught.BEFORE: "Before the move",
    Caught.AFTER: "After the move",
    Caught.MISSED: "Missed",
    Caught.TRIAL_STOPPED: "Trial stopped",
}


def _answer_error_lines(totals: AnswerErrorTotals) -> list[str]:
    """The answers eval --answer-errors corrupted, by kind, and what caught them."""
    kinds = "all kinds" if set(totals.kinds) == set(CorruptionKind) else ", ".join(totals.kinds)
    persistence = f", persistence {totals.persistence:g}" if totals.persistence else ""
    repeats = sum(totals.repeated.values())
    lines = [
        f"Answer errors: each answer corrupted with probability {totals.rate:g} "
        f"({kinds}{persistence}); {plural(totals.corrupted, 'answer')} corrupted"
        + (f", {repeats} of them repeating a refused mistake." if repeats else "."),
    ]
    if not totals.corrupted:
        return lines
    if totals.caught:
        lines += ["", *_caught_table(totals), "", *_check_table(totals)]
        lines += _consequence_lines(totals)
    else:  # lines written before `caught`: what stopped each answer, flat
        lines += ["", "| Kind | Meaning | Answers |", "|---|---|---|"]
        lines += [f"| `{k}` | {k.meaning} | {n} |" for k, n in totals.by_kind.items()]
        lines += ["", "| Caught by | Answers |", "|---|---|"]
        lines += [f"| `{check}` | {n} |" for check, n in totals.caught_by.items()]
    if totals.refused_as:
        expected = {kind: f"`{kind.expected}`" for kind in totals.refused_as}
        lines += [
            "",
            "Corrupted answers refused or failed, by kind and the category they got:",
            "",
            *category_table("Kind", totals.refused_as, {"Expected": expected}),
        ]
    return lines


def _caught_table(totals: AnswerErrorTotals) -> list[str]:
    """Kind by where it was caught: before the move, after it, missed, trial stopped."""
    header = ["Kind", "Meaning", "Answers", "Repeats", *CAUGHT_TITLES.values()]
    lines = ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
    for kind, n in totals.by_kind.items():
        where = totals.caught.get(kind, {})
        cells = [f"`{kind}`", kind.meaning, str(n), str(totals.repeated.get(kind, 0))]
        cells += [str(where.get(caught, 0)) for caught in Caught]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _check_table(totals: AnswerErrorTotals) -> list[str]:
    """The checks that caught corrupted answers (before or after the move), by kind."""
    kinds = [k for k in CorruptionKind if any(k in row for row in totals.checks.values())]
    if not kinds:
        return ["No check caught a corrupted answer."]
    header = ["Caught by", *(f"`{k}`" for k in kinds), "Total"]
    lines = ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
    for check, row in totals.checks.items():
        cells = [f"`{check}`", *(str(row.get(k, 0)) for k in kinds), str(sum(row.values()))]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _consequence_lines(totals: AnswerErrorTotals) -> list[str]:
    """What the missed answers led to, and what would have caught them on another rung."""
    if not totals.led_to:
        return []
    lines = [
        "",
        "What the missed answers led to (the first check to refuse anything later in the "
        "brick's cycle, else the trial's failure if the brick was never placed, `misplaced` if "
        "it ended outside the success rule, else `harmless`), and the check they failed that "
        "this run did not enforce:",
        "",
        "| Kind | Led to | Would be caught by |",
        "|---|---|---|",
    ]
    for kind, led in totals.led_to.items():
        would = totals.would_catch.get(kind, {})
        cells = [
            f"`{kind}`",
            ", ".join(f"`{what}` {n}" for what, n in led.items()),
            ", ".join(f"`{check}` {n}" for check, n in would.items()) or "–",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def category_table(
    first: str,
    counts: Mapping[K, Mapping[ErrorCategory, int]],
    extra: Mapping[str, Mapping[K, str]] | None = None,
) -> list[str]:
    """A markdown table of ``counts``: a row per key (titled ``first``), a column per
    category that occurs and the total; ``extra`` columns (title -> key -> cell) after the
    first."""
    extra = extra or {}
    shown = categories_in(counts)
    header = [first, *extra, *(f"`{c}`" for c in shown), "Total"]
    lines = ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
    for key, row in counts.items():
        cells = [f"`{key}`", *(column[key] for column in extra.values())]
        cells += [str(row.get(c, 0)) for c in shown] + [str(sum(row.values()))]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _condition_lines(summary: RunSummary) -> list[str]:
    """The physics profile and noise level the run ran under, one line each."""
    lines = []
    if summary.physics is not None:
        lines.append(f"Physics `{summary.physics.describe()}`.")
    if summary.noise is not None:
        lines.append(f"Noise `{summary.noise.describe()}`.")
    return [" ".join(lines), ""] if lines else []


def _llm_lines(summary: RunSummary) -> list[str]:
    """LLM cost per agent, per brick of the pattern, and the model's share of decisions."""
    u, bricks = summary.llm_usage, summary.trials * summary.bricks_per_trial
    own = summary.decisions - summary.fallback_decisions
    lines = [
        f"LLM (`{summary.llm}`, structured output `{summary.llm_mode}`): "
        f"{plural(u.calls, 'call')}, {plural(u.prompt_tokens, 'prompt token')} and "
        f"{plural(u.completion_tokens, 'completion token')}, "
        f"{u.latency_s:.1f} s. Decisions: {summary.decisions}, "
        f"{summary.fallback_decisions} of them by the built-in fallback "
        f"({own / max(summary.decisions, 1):.0%} the model's own).",
        "",
        "| Agent | Calls | Prompt tokens / brick | Completion tokens / brick "
        "| Latency / call (s) |" + (" Image bytes / brick |" if u.image_bytes else ""),
        "|---|---|---|---|---|" + ("---|" if u.image_bytes else ""),
    ]
    for agent, a in summary.llm_usage_by_agent.items():
        lines.append(
            f"| {agent} | {a.calls} | {a.prompt_tokens / bricks:.0f} | "
            f"{a.completion_tokens / bricks:.0f} | {a.latency_s / max(a.calls, 1):.2f} |"
            + (f" {a.image_bytes / bricks:,.0f} |" if u.image_bytes else "")
        )
    return lines


def categories_in(*counts: Mapping[Any, Mapping[ErrorCategory, int]]) -> list[ErrorCategory]:
    """The categories that occur in any row of ``counts``, in their order."""
    return [c for c in ErrorCategory if any(c in row for table in counts for row in table.values())]
