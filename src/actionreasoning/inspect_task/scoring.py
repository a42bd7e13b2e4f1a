"""The scorer and its metrics: a trial's outcome and Table I's placement metrics, from its
results line.

A sample's score is a dict: ``success`` (1 or 0), ``bricks_placed`` and the placement
metrics of the line (means over its bricks); its answer is ``success`` or the failure
code, its explanation the failure's detail. The metrics treat each scored epoch as one
trial: the success rate with its Wilson 95 % interval, the placement metrics' means over
the successful trials as Table I gives them (none without a success), bricks placed, a
mean over all trials, and the trials by failure code.
"""

from __future__ import annotations

from collections import Counter
from statistics import fmean
from typing import Any

from inspect_ai.scorer import (
    Metric,
    SampleScore,
    Score,
    Scorer,
    Target,
    Value,
    metric,
    scorer,
)
from inspect_ai.solver import TaskState

from actionreasoning.inspect_task.solver import RESULT
from actionreasoning.runs.statistics import wilson
from actionreasoning.trial.results import PlacementMetrics, TrialResult

#: A successful trial's answer; a failed one's is its failure code.
SUCCESS = "success"
PLACEMENT = tuple(PlacementMetrics.model_fields)


@metric(scores="unreduced")
def success_rate() -> Metric:
    """Successful trials over trials, with the Wilson 95 % interval."""

    def compute(scores: list[SampleScore]) -> Value:
        successes = sum(1 for value in _values(scores) if value["success"] == 1)
        interval = wilson(successes, len(scores))
        if interval is None:  # no trial scored yet
            return {}
        rate = successes / len(scores)
        return {"success_rate": rate, "ci_low": interval.low, "ci_high": interval.high}

    return compute


@metric(scores="unreduced")
def table_i() -> Metric:
    """Table I: the placement metrics' means over the successful trials, and bricks placed,
    a mean over all trials (nothing without a trial)."""

    def compute(scores: list[SampleScore]) -> Value:
        values = _values(scores)
        ok = [value for value in values if value["success"] == 1]
        means = {key: fmean(value[key] for value in ok) for key in PLACEMENT} if ok else {}
        if values:
            means["bricks_placed"] = fmean(value["bricks_placed"] for value in values)
        return means

    return compute


@metric(scores="unreduced")
def failures() -> Metric:
    """The failed trials by failure code."""

    def compute(scores: list[SampleScore]) -> Value:
        codes = Counter(s.score.answer for s in scores if s.score.answer != SUCCESS)
        return {str(code): count for code, count in sorted(codes.items(), key=str)}

    return compute


@scorer(metrics=[success_rate(), table_i(), failures()])
def trial_outcome() -> Scorer:
    """The trial's outcome and metrics from its results line in the sample's store."""

    async def score(state: TaskState, target: Target) -> Score:
        line = state.store.get(RESULT)
        if line is None:
            return Score.unscored(explanation="the trial did not finish (a limit ended it)")
        result = TrialResult.model_validate(line)
        failure = result.failure
        placed = f"{result.bricks_placed} of {len(result.bricks)} bricks placed"
        return Score(
            value={
                "success": int(result.success),
                "bricks_placed": result.bricks_placed,
                **result.metrics.model_dump(),
            },
            answer=SUCCESS if failure is None else str(failure.reason),
            explanation=placed if failure is None else f"{placed}; {failure.detail}",
        )

    return score


def _values(scores: list[SampleScore]) -> list[dict[str, Any]]:
    values = [s.score.value for s in scores]
    assert all(isinstance(value, dict) for value in values)  # trial_outcome's
    return [dict(value) for value in values if isinstance(value, dict)]
