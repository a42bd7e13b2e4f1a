"""How error grows with height, and how fast a method builds: per-course placement
metrics, bricks within the success rule before the first failure, the bricks set down, and
the robot's cycle time.

A brick's course is the rank of its target's bottom height among the pattern's: bricks
whose bottoms lie within COURSE_TOL_M of each other share a course (a course's bottoms
differ by seating only; two courses by a brick's height, at least 3 cm).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, NonNegativeFloat, NonNegativeInt

from actionreasoning.records import FailureCode
from actionreasoning.trial.results import BrickResult, IoU, OffsetCm, RotationDeg, TrialResult
from actionreasoning.world.success import SuccessRule

#: Bottom heights closer than this are one course (m).
COURSE_TOL_M = 0.01
SECONDS_PER_HOUR = 3600.0
#: Failures found on the finished build, every target's brick set down.
FINISHED_BUILD = (FailureCode.MISPLACED, FailureCode.NOT_AT_REST)


class CourseMetrics(BaseModel):
    """The placement metrics of one course's bricks over a run's trials: means and
    (population) standard deviations."""

    model_config = ConfigDict(frozen=True)

    course: NonNegativeInt
    bricks: NonNegativeInt
    center_offset_cm: tuple[OffsetCm, NonNegativeFloat]
    rotation_error_deg: tuple[RotationDeg, NonNegativeFloat]
    iou: tuple[IoU, NonNegativeFloat]


class CycleTime(BaseModel):
    """Simulated seconds per brick and the bricks an hour that makes: per brick within the
    success rule (``seconds_per_brick``, ``bricks_per_hour``) and per brick set down,
    whatever its errors (the robot's own pace). None without such a brick, and per brick set
    down also where a line does not tell (see :func:`bricks_set_down`) or in summaries
    written before it was computed."""

    model_config = ConfigDict(frozen=True)

    seconds_per_brick: NonNegativeFloat | None
    bricks_per_hour: NonNegativeFloat | None
    seconds_per_brick_set_down: NonNegativeFloat | None = None
    bricks_set_down_per_hour: NonNegativeFloat | None = None


def _bottom_m(brick: BrickResult) -> float:
    return brick.target_position[2] - brick.size[2] / 2.0


def courses(bricks: Sequence[BrickResult]) -> list[int]:
    """Each brick's course, 0 at the ground, in the order given."""
    levels: list[float] = []
    for bottom in sorted(_bottom_m(b) for b in bricks):
        if not levels or bottom - levels[-1] > COURSE_TOL_M:
            levels.append(bottom)
    return [
        next(k for k, level in enumerate(levels) if abs(_bottom_m(b) - level) <= COURSE_TOL_M)
        for b in bricks
    ]


def per_course(results: Sequence[TrialResult]) -> list[CourseMetrics]:
    """Centre offset, rotation error and IoU per course, pooled over the trials' bricks."""
    pooled: dict[int, list[BrickResult]] = {}
    for result in results:
        for brick, course in zip(result.bricks, courses(result.bricks), strict=True):
            pooled.setdefault(course, []).append(brick)
    return [
        CourseMetrics(
            course=course,
            bricks=len(bricks),
            center_offset_cm=_mean_std([b.center_offset_cm for b in bricks]),
            rotation_error_deg=_mean_std([b.rotation_error_deg for b in bricks]),
            iou=_mean_std([b.iou for b in bricks]),
        )
        for course, bricks in sorted(pooled.items())
    ]


def placed_before_first_failure(result: TrialResult, rule: SuccessRule) -> int:
    """The bricks within ``rule`` of their targets, in build order, before the first that
    is not."""
    count = 0
    for brick in result.bricks:
        if not rule.is_placed(brick):
            break
        count += 1
    return count


def bricks_set_down(result: TrialResult) -> int | None:
    """The bricks a trial set down on their targets, whatever their errors: all of them if
    the build finished (the trial succeeded, or failed as FINISHED_BUILD), else None. A
    results line does not say how many bricks a build cut short had set down (recording it
    would change the lines of valid runs)."""
    if result.failure is None or result.failure.reason in FINISHED_BUILD:
        return len(result.bricks)
    return None


def cycle_time(results: Sequence[TrialResult], time_step_s: float) -> CycleTime:
    """The run's simulated time over the bricks it placed within the success rule, and over
    those it set down (None if any trial's are unknown)."""
    seconds = sum(r.sim_steps for r in results) * time_step_s
    counts = [bricks_set_down(r) for r in results]
    within = _pace(seconds, sum(r.bricks_placed for r in results))
    set_down = _pace(seconds, None if None in counts else sum(n or 0 for n in counts))
    return CycleTime(
        seconds_per_brick=within[0],
        bricks_per_hour=within[1],
        seconds_per_brick_set_down=set_down[0],
        bricks_set_down_per_hour=set_down[1],
    )


def _pace(seconds: float, bricks: int | None) -> tuple[float | None, float | None]:
    """Seconds per brick and bricks an hour; None without a brick or time."""
    if not bricks or not seconds:
        return None, None
    return seconds / bricks, SECONDS_PER_HOUR * bricks / seconds


def _mean_std(values: list[float]) -> tuple[float, float]:
    return float(np.mean(values)), float(np.std(values))
