"""What a run's text says: a failed trial's progress line names the brick that broke the
success rule, counts take the number of their noun, and the
wall time of a resumed run says whose it is."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest
from conftest import SMALL_PATTERN, cli
from rich.console import Console
from test_courses import brick
from test_run_dir import result

from actionreasoning.records import LLMUsage
from actionreasoning.runs.markdown import plural
from actionreasoning.runs.progress import ConsoleProgress, trial_line
from actionreasoning.runs.summary import summarize, summary_markdown, wall_time_text
from actionreasoning.trial.results import BrickResult
from actionreasoning.trial.runner import misplaced
from actionreasoning.world.success import SuccessRule


def turned(id_: int, offset_cm: float, rotation_deg: float) -> BrickResult:
    return brick(0.03, offset_cm).model_copy(update={"id": id_, "rotation_error_deg": rotation_deg})


def test_the_progress_line_of_a_misplaced_build_names_the_brick_outside_the_rule() -> None:
    """As seen on a wall of 13 bricks: brick 0 was the furthest off (0.81 cm, 1.43 deg,
    inside the rule), brick 4 turned 5.28 deg: the line names brick 4 and its figures, then
    the trial's means, called means."""
    wall = [turned(k, 0.2, 0.5) for k in range(13)]
    wall[0], wall[4] = turned(0, 0.81, 1.43), turned(4, 0.31, 5.28)
    failure = misplaced(wall, SuccessRule())
    line = result(3, success=False).model_copy(update={"failure": failure})
    assert trial_line(line) == (
        "trial 3: FAILED (misplaced: 1 of 13 bricks outside 2.0 cm / 5.0 deg; worst brick 4: "
        "0.31 cm, 5.28 deg); mean 0.010 cm, 0.020 deg, IoU 0.990"
    )


def test_counts_take_the_number_of_their_noun() -> None:
    assert [plural(n, "trial") for n in (0, 1, 2)] == ["0 trials", "1 trial", "2 trials"]
    usage = LLMUsage(calls=1, prompt_tokens=1, completion_tokens=2, latency_s=0.5)
    one = summarize([result(0).model_copy(update={"llm_usage": usage})], wall_time_s=2.0)
    text = summary_markdown(one.model_copy(update={"llm": "openai:m"}))
    assert "· seed 0 · 1 trial · wall time 2.0 s" in text
    assert "1 call, 1 prompt token and 2 completion tokens, 0.5 s." in text
    assert "· 2 trials ·" in summary_markdown(summarize([result(0), result(1)], wall_time_s=2.0))


@pytest.mark.parametrize(
    ("trials", "resumed", "said"),
    [
        (3, 0, "wall time 2.0 s"),
        (3, 1, "wall time 2.0 s for the 2 trials run in this session (1 trial finished by an "
         "earlier session, not timed here)"),
        (3, 3, "no trial run in this session (3 trials finished by an earlier session, not "
         "timed here)"),
    ],
)  # fmt: skip
def test_the_wall_time_of_a_resumed_run_is_this_sessions_and_says_so(
    trials: int, resumed: int, said: str
) -> None:
    summary = summarize([result(k) for k in range(trials)], wall_time_s=2.0, resumed_trials=resumed)
    assert wall_time_text(summary) == said
    assert f"· 3 trials · {said}\n" in summary_markdown(summary)


@pytest.mark.slow
def test_a_resume_that_runs_nothing_new_says_so(tmp_path: Path) -> None:
    """The same command again: the trial is in results.jsonl, this session runs none."""
    pattern = tmp_path / "small.json"
    pattern.write_text(json.dumps(SMALL_PATTERN))
    command = (
        "eval", "--method", "classical", "--pattern", str(pattern), "--trials", "1",
        "--physics", "precise", "--out", str(tmp_path / "run"),
    )  # fmt: skip
    for _ in range(2):
        outcome = cli(*command)
        assert outcome.returncode == 0, outcome.stderr
    text = (tmp_path / "run" / "summary.md").read_text()
    assert (
        "· 1 trial · no trial run in this session (1 trial finished by an earlier session, "
        "not timed here)"
    ) in text
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert (summary["trials"], summary["resumed_trials"]) == (1, 1)


def test_a_resume_of_a_one_trial_run_says_trial(capsys: pytest.CaptureFixture[str]) -> None:
    with ConsoleProgress(Console(file=io.StringIO()), "a run") as progress:
        progress.started(1, [result(0, success=True)])
    assert capsys.readouterr().out == "resuming: 1 of 1 trial already in results.jsonl (1 ok)\n"
