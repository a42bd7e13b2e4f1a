"""Bricks set down and bricks within the success rule are named apart, and the cycle time is
given per brick set down: the classical script that sets its six bricks in 66 s, two of
them within the rule, builds at 11 s a brick, not 33 s."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_courses import brick
from test_report import table_after
from test_run_dir import result
from test_summary_statistics import classical, write_run

from actionreasoning.records import Failure, FailureCode
from actionreasoning.report.build import build_report
from actionreasoning.runs.courses import bricks_set_down, cycle_time
from actionreasoning.runs.summary import summarize, summary_markdown
from actionreasoning.trial.results import TrialResult
from actionreasoning.world.physics import PRECISE

STEPS = round(66 / PRECISE.time_step_s)  # 66 simulated s
SIX = tuple(brick(0.03, 0.5 if k < 2 else 3.0) for k in range(6))  # two within 2 cm


def script(trial: int, reason: FailureCode | None) -> TrialResult:
    """A classical line of six bricks, two of them within the rule."""
    failure = None if reason is None else Failure(reason=reason, detail="")
    return result(trial, success=reason is None).model_copy(
        update={
            "method": "classical",
            "llm": "none",
            "bricks": SIX,
            "bricks_placed": 2,
            "sim_steps": STEPS,
            "failure": failure,
        }
    )


def test_a_finished_build_set_down_every_brick() -> None:
    """A build judged at its end (misplaced, not at rest, or a success) set every brick
    down; a line of one stopped on the way does not tell how many."""
    assert bricks_set_down(script(0, FailureCode.MISPLACED)) == 6
    assert bricks_set_down(script(0, FailureCode.NOT_AT_REST)) == 6
    assert bricks_set_down(script(0, None)) == 6
    assert bricks_set_down(script(0, FailureCode.STEP_BUDGET)) is None


def test_the_cycle_time_is_given_per_brick_set_down_and_per_brick_within_the_rule() -> None:
    lines = [script(0, FailureCode.MISPLACED), script(1, FailureCode.MISPLACED)]
    time = cycle_time(lines, PRECISE.time_step_s)
    assert time.seconds_per_brick_set_down == pytest.approx(11.0)  # 132 s over 12 bricks
    assert time.bricks_set_down_per_hour == pytest.approx(3600 / 11)
    assert time.seconds_per_brick == pytest.approx(33.0)  # over 4 bricks within the rule
    unknown = cycle_time([*lines, script(2, FailureCode.STEP_BUDGET)], PRECISE.time_step_s)
    assert unknown.seconds_per_brick_set_down is None and unknown.seconds_per_brick is not None
    summary = summarize(lines, wall_time_s=1.0, physics=PRECISE)
    assert summary.bricks_set_down_mean == 6 and summary.bricks_placed_mean == 2
    text = summary_markdown(summary)
    assert (
        "Bricks per trial: set down 6.00 of 6 (whatever their errors), within the success "
        "rule 2.00 of 6."
    ) in text
    assert (
        "Cycle time: 11.0 simulated s per brick set down (327 an hour); 33.0 simulated s per "
        "brick within the success rule (109 an hour)."
    ) in text
    assert "placed" not in text.split("Success rule")[0].split("Means ±")[1]


def test_the_report_names_bricks_set_down_and_within_the_rule_apart(tmp_path: Path) -> None:
    lines = [script(0, FailureCode.MISPLACED), script(1, FailureCode.STEP_BUDGET)]
    report = build_report([write_run(tmp_path / "c", classical(), lines)], tmp_path / "report")
    markdown = (report.directory / "table.md").read_text()
    assert table_after(markdown, "Bricks a trial set down") == [
        "| classical, precise | pyramid | – | 2.00 of 6 | 2.00 of 6 | – | – | 33.0 |"
    ]  # trial 1 stopped on the way: how many it set down is unknown
    lines = [script(0, FailureCode.MISPLACED), script(1, FailureCode.MISPLACED)]
    report = build_report([write_run(tmp_path / "f", classical(), lines)], tmp_path / "finished")
    markdown = (report.directory / "table.md").read_text()
    assert table_after(markdown, "Bricks a trial set down") == [
        "| classical, precise | pyramid | 6.00 of 6 | 2.00 of 6 | 2.00 of 6 | 11.0 | 327 | 33.0 |"
    ]  # 132 s over 12 bricks set down, 4 within the rule
    html = (report.directory / "report.html").read_text()
    assert "<td>6.00 of 6</td><td>2.00 of 6</td><td>2.00 of 6</td><td>11.0</td>" in html
