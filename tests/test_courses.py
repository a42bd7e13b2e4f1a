"""Per-course metrics, bricks before the first failure and cycle time, against hand
computations."""

from __future__ import annotations

import pytest
from test_run_dir import result

from actionreasoning.runs.courses import (
    courses,
    cycle_time,
    per_course,
    placed_before_first_failure,
)
from actionreasoning.runs.summary import RunSummary, summarize, summary_markdown
from actionreasoning.trial.results import BrickResult, TrialResult
from actionreasoning.world.physics import PAPER
from actionreasoning.world.success import SuccessRule

FULL = (0.2, 0.095, 0.06)
HALF = (0.095, 0.095, 0.06)


def brick(z: float, offset_cm: float, size: tuple[float, float, float] = FULL) -> BrickResult:
    return BrickResult(
        id=0, size=size, target_position=(0.5, 0.0, z), target_orientation=(0, 0, 0, 1),
        final_position=(0.5, 0.0, z), final_orientation=(0, 0, 0, 1),
        center_offset_cm=offset_cm, rotation_error_deg=offset_cm / 2,
        symmetric_rotation_error_deg=offset_cm / 2, iou=1.0 - offset_cm / 10,
    )  # fmt: skip


def trial(*bricks: BrickResult, steps: int = 100, placed: int | None = None) -> TrialResult:
    placed = len(bricks) if placed is None else placed
    return result(0).model_copy(
        update={"bricks": bricks, "bricks_placed": placed, "sim_steps": steps}
    )


def test_bricks_are_grouped_in_courses_by_their_bottoms_whatever_their_size() -> None:
    wall = [brick(0.03, 0), brick(0.09, 0, HALF), brick(0.0305, 0), brick(0.15, 0), brick(0.09, 0)]
    assert courses(wall) == [0, 1, 0, 2, 1]


def test_per_course_metrics_are_the_pooled_means_and_deviations() -> None:
    first = trial(brick(0.03, 0.2), brick(0.03, 0.4), brick(0.09, 1.0))
    second = trial(brick(0.03, 0.6), brick(0.09, 3.0))
    ground, top = per_course([first, second])
    assert (ground.course, ground.bricks, top.course, top.bricks) == (0, 3, 1, 2)
    # course 0: offsets 0.2, 0.4, 0.6 -> mean 0.4, population std sqrt(0.08 / 3)
    assert ground.center_offset_cm == pytest.approx((0.4, (0.08 / 3) ** 0.5))
    assert ground.rotation_error_deg == pytest.approx((0.2, (0.02 / 3) ** 0.5))
    # course 1: offsets 1.0, 3.0 -> mean 2.0, std 1.0; IoU 0.9 and 0.7
    assert top.center_offset_cm == pytest.approx((2.0, 1.0))
    assert top.iou == pytest.approx((0.8, 0.1))


def test_bricks_before_the_first_failure_stop_at_the_first_brick_out_of_the_rule() -> None:
    rule = SuccessRule()  # 2 cm, 5 deg
    built = trial(brick(0.03, 0.5), brick(0.03, 1.0), brick(0.09, 2.5), brick(0.09, 0.1))
    assert placed_before_first_failure(built, rule) == 2
    assert placed_before_first_failure(trial(brick(0.03, 3.0)), rule) == 0


def test_cycle_time_is_simulated_time_over_placed_bricks() -> None:
    runs = [trial(brick(0.03, 0), steps=2400, placed=2), trial(steps=600, placed=0)]
    time = cycle_time(runs, time_step_s=1 / 240)
    assert time.seconds_per_brick == pytest.approx((3000 / 240) / 2)  # 6.25 s
    assert time.bricks_per_hour == pytest.approx(3600 / 6.25)
    assert cycle_time([trial(placed=0)], 1 / 240).seconds_per_brick is None


def test_the_summary_gives_courses_bricks_before_the_first_failure_and_cycle_time() -> None:
    first = trial(brick(0.03, 0.2), brick(0.09, 3.0), steps=2400, placed=1)
    second = trial(brick(0.03, 0.6), brick(0.09, 1.0), steps=2400, placed=2)
    summary = summarize([first, second], wall_time_s=1.0, physics=PAPER)
    assert [(c.course, c.bricks) for c in summary.courses] == [(0, 2), (1, 2)]
    assert summary.courses[1].center_offset_cm == pytest.approx((2.0, 1.0))
    assert summary.placed_before_first_failure_mean == pytest.approx(1.5)  # 1 and 2
    seconds = 4800 * PAPER.time_step_s / 3
    assert summary.cycle_time is not None
    assert summary.cycle_time.seconds_per_brick == pytest.approx(seconds)
    text = summary_markdown(summary)
    assert "| 1 | 2 | 2.000 ± 1.000 | 1.000 ± 0.500 | 80.00 ± 10.00 |" in text
    assert f"{seconds:.1f} simulated s per brick within the success rule" in text
    assert RunSummary.model_validate_json(summary.model_dump_json()) == summary
