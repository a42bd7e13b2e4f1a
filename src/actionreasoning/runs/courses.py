"""How error grows with height, and how fast a method builds: per-course placement
metrics, bricks placed before the first failure, and the robot's cycle time.

A brick's course is the rank of its target's bottom height among the pattern's: bricks
whose bottoms lie within COURSE_TOL_M of each other share a course (a course's bottoms
differ by seating only; two courses by a brick's height, at least 3 cm).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict

from actionreasoning.trial.results import BrickResult, TrialResult
from actionreasoning.world.success import SuccessRule

#: Bottom heights closer than this are one course (m).
COURSE_TOL_M = 0.01
SECONDS_PER_HOUR = 3600.0


class CourseMetrics(BaseModel):
    """The placement metrics of one course's bricks over a run's trials: means and
    (population) standard deviations."""

    model_config = ConfigDict(frozen=True)

    course: int
    bricks: int
    center_offset_cm: tuple[float, float]
    rotation_error_deg: tuple[float, float]
    iou: tuple[float, float]


class CycleTime(BaseModel):
    """Simulated seconds per placed brick, and the bricks an hour that makes."""

    model_config = ConfigDict(frozen=True)

    seconds_per_brick: float | None
    bricks_per_hour: float | None


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


def cycle_time(results: Sequence[TrialResult], time_step_s: float) -> CycleTime:
    """The run's simulated time over the bricks it placed; None if it placed none."""
    placed = sum(r.bricks_placed for r in results)
    if placed == 0:
        return CycleTime(seconds_per_brick=None, bricks_per_hour=None)
    seconds = sum(r.sim_steps for r in results) * time_step_s / placed
    return CycleTime(seconds_per_brick=seconds, bricks_per_hour=SECONDS_PER_HOUR / seconds)


def _mean_std(values: list[float]) -> tuple[float, float]:
    return float(np.mean(values)), float(np.std(values))
