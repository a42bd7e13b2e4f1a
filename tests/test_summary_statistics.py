"""Statistics on every compared number, from hand-written results lines (no simulation):
Wilson intervals on success rates and bootstrap intervals on Table I means in summaries and
reports, the leaderboard figures, the means over all trials of a method with no success,
and the paired comparison of two rows run on the same trial seeds."""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from test_courses import brick
from test_report import table_after
from test_run_dir import manifest, result

from actionreasoning.agents.answer_errors import Caught
from actionreasoning.agents.answer_errors import CorruptionKind as K
from actionreasoning.agents.error_kinds import ErrorCategory as C
from actionreasoning.agents.transcript import AgentCall, Outcome
from actionreasoning.agents.verification import Verification
from actionreasoning.records import LLMUsage
from actionreasoning.report.build import build_report
from actionreasoning.runs.run_dir import RunManifest
from actionreasoning.runs.statistics import bootstrap_mean, mcnemar_exact, wilson
from actionreasoning.runs.summary import MetricStats, RunSummary, summarize, summary_markdown
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.results import AnswerErrorCounts, FirstAttempts, TrialResult
from actionreasoning.trial.runner import first_attempts_of
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scenarios import NOISE

AGENTS = "agents (builtin, tools check), precise"
CLASSICAL = "classical, precise"


def lines(successes: Sequence[bool], **update: object) -> list[TrialResult]:
    """Trials 0, 1, ... of seed 0 of the agents on the pyramid; trial k's centre offset is
    k / 10 cm."""
    return [
        result(k, success=ok).model_copy(
            update={"metrics": result(k).metrics.model_copy(update={"center_offset_cm": k / 10})}
            | update
        )
        for k, ok in enumerate(successes)
    ]


# --- summaries --------------------------------------------------------------------------


def test_a_summary_gives_the_wilson_interval_and_each_means_bootstrap_interval() -> None:
    trials = lines([True, True, False, True, True])
    summary = summarize(trials, wall_time_s=1.0)
    assert summary.success_interval == wilson(4, 5)
    offsets = summary.successful["center_offset_cm"]
    interval = bootstrap_mean([0.0, 0.1, 0.3, 0.4])  # the successful trials' offsets
    assert interval is not None and (offsets.ci_low, offsets.ci_high) == (
        interval.low,
        interval.high,
    )
    assert offsets.mean == pytest.approx(0.2) and offsets.ci_low < 0.2 < offsets.ci_high
    everything = summary.all_trials["center_offset_cm"]
    assert everything.mean == pytest.approx(0.2) and everything.ci_low is not None
    markdown = summary_markdown(summary)
    assert "| 4/5 (80 %, 95 % CI 38–96 %) |" in markdown  # Wilson 0.376 to 0.964
    assert f"| 0.200 ± 0.158 [{offsets.ci_low:.3f}, {offsets.ci_high:.3f}] |" in markdown
    assert "10000 resamples, seed 0" in markdown
    assert "all trials" not in markdown  # a row over all trials only without a success


def test_a_run_without_success_gets_a_row_over_all_trials() -> None:
    markdown = summary_markdown(summarize(lines([False] * 3), wall_time_s=1.0))
    table = table_after(markdown, "No trial succeeded")
    assert table[0].startswith("| agents | n/a | n/a | n/a | n/a | 0/3 (0 %, 95 % CI 0–56 %) |")
    assert table[1].startswith("| agents, all trials | 0.020 ± 0.000 [0.020, 0.020] | 0.100 ± ")


def test_a_summary_written_before_intervals_and_the_leaderboard_still_loads() -> None:
    summary = summarize(lines([True, False]), wall_time_s=1.0)
    older = json.loads(summary.model_dump_json())
    del older["success_interval"], older["leaderboard"]
    for stats in (*older["successful"].values(), *older["all_trials"].values()):
        del stats["ci_low"], stats["ci_high"]
    loaded = RunSummary.model_validate(older)
    assert loaded.success_interval is None and loaded.leaderboard is None
    assert "| 1/2 (50 %, 95 % CI 9–91 %) |" in summary_markdown(loaded)
    assert json.loads(MetricStats(mean=None, std=None).model_dump_json()) == {
        "mean": None,
        "std": None,
    }


# --- the leaderboard --------------------------------------------------------------------


def test_leaderboard_figures_are_sums_over_bricks_and_placed_bricks() -> None:
    """Two trials of 3 bricks (6 bricks), 3 placed in all; 4 refusals; 9000 prompt tokens."""
    bricks = (brick(0.03, 0.1), brick(0.03, 0.2), brick(0.09, 0.3))
    first = {"pre_grasp": FirstAttempts(asked=3, accepted=2)}
    trials = [
        lines([True])[0].model_copy(
            update={
                "bricks": bricks,
                "bricks_placed": 3,
                "llm": "openai:m",
                "llm_usage": LLMUsage(calls=9, prompt_tokens=6000),
                "refusals": {"pre_grasp": {C.WRONG_CHOICE: 1}},
                "first_attempts": first | {"grasp": FirstAttempts(asked=3, accepted=3)},
            }
        ),
        lines([False])[0].model_copy(
            update={
                "bricks": bricks,
                "bricks_placed": 0,
                "llm": "openai:m",
                "llm_usage": LLMUsage(calls=5, prompt_tokens=3000),
                "refusals": {"pre_grasp": {C.WRONG_CHOICE: 2}, "lift": {C.DYNAMICS: 1}},
                "first_attempts": first,
            }
        ),
    ]
    board = summarize(trials, wall_time_s=1.0).leaderboard
    assert board is not None
    assert board.first_attempts == FirstAttempts(asked=9, accepted=7)
    assert board.first_attempts_by_agent == {
        "pre_grasp": FirstAttempts(asked=6, accepted=4),
        "grasp": FirstAttempts(asked=3, accepted=3),
    }
    assert board.refusals_per_brick == pytest.approx(4 / 6)
    assert board.prompt_tokens_per_brick == pytest.approx(9000 / 6)
    assert board.prompt_tokens_per_placed_brick == pytest.approx(9000 / 3)
    markdown = summary_markdown(summarize(trials, wall_time_s=1.0))
    assert "| 7/9 (78 %) | 0.67 | 1500 | 3000 |" in markdown
    assert "| `pre_grasp` | 6 | 4/6 (67 %) |" in markdown


def test_no_tokens_no_reasoner_or_no_placed_brick_give_no_figure() -> None:
    builtin = summarize(lines([False]), wall_time_s=1.0).leaderboard  # no bricks, no tokens
    assert builtin is not None
    assert (builtin.first_attempts, builtin.prompt_tokens_per_brick) == (None, None)
    classical = lines([True], method="classical", llm="none", bricks=(brick(0.03, 0.1),))
    board = summarize(classical, wall_time_s=1.0).leaderboard
    assert board is not None and board.refusals_per_brick is None
    assert "Refusals / brick" not in summary_markdown(summarize(classical, wall_time_s=1.0))


def call(agent: str, attempt: int, outcome: Outcome) -> AgentCall:
    made = AgentCall(
        call=0, agent=agent, brick=0, target=0, attempt=attempt, prompt_chars=1, answer={}
    )
    made.conclude(outcome)
    return made


def test_first_attempts_count_calls_of_attempt_one_and_those_accepted_or_executed() -> None:
    transcript = [
        call("pre_grasp", 1, Outcome.REFUSED),
        call("pre_grasp", 2, Outcome.ACCEPTED),  # a second attempt: not counted
        call("descent", 1, Outcome.ACCEPTED),
        call("single_agent", 1, Outcome.EXECUTED),
        call("pre_grasp", 1, Outcome.ACCEPTED),
        call("grasp", 1, Outcome.PENDING),  # the trial stopped first
    ]
    assert first_attempts_of(transcript) == {
        "pre_grasp": FirstAttempts(asked=2, accepted=1),
        "descent": FirstAttempts(asked=1, accepted=1),
        "single_agent": FirstAttempts(asked=1, accepted=1),
        "grasp": FirstAttempts(asked=1, accepted=0),
    }
    assert first_attempts_of([]) == {}
    assert "first_attempts" not in json.loads(result(0).model_dump_json())  # as classical's


# --- the report -------------------------------------------------------------------------


def write_run(directory: Path, run: RunManifest, trials: Sequence[TrialResult]) -> Path:
    directory.mkdir()
    (directory / "run.json").write_text(run.model_dump_json())
    (directory / "results.jsonl").write_text("".join(t.model_dump_json() + "\n" for t in trials))
    return directory


def classical(pattern: str = "pyramid", digest: str = "0" * 64) -> RunManifest:
    config = TrialConfig(llm=None, physics=PRECISE)
    return RunManifest.sealed("classical", pattern, digest, 0, config)


def script_lines(successes: Sequence[bool], pattern: str = "pyramid") -> list[TrialResult]:
    return lines(successes, method="classical", llm="none", pattern=pattern)


@pytest.fixture
def report(tmp_path: Path) -> Path:
    """The agents succeed in 5 of 6 trials of the pyramid and 3 of 3 of a second pattern,
    the classical script in none of 8 and 1 of 3; the agents under low noise are not paired
    with either."""
    grid = "1" * 64
    runs = [
        write_run(tmp_path / "a", manifest(physics=PRECISE), lines([True] * 5 + [False])),
        write_run(tmp_path / "c", classical(), script_lines([False] * 8)),
        write_run(
            tmp_path / "a_grid",
            RunManifest.sealed("agents", "grid", grid, 0, TrialConfig(physics=PRECISE)),
            lines([True] * 3, pattern="grid"),
        ),
        write_run(
            tmp_path / "c_grid", classical("grid", grid), script_lines([True, False, False], "grid")
        ),
        write_run(
            tmp_path / "a_noisy",
            manifest(physics=PRECISE, noise=NOISE["low"]),
            lines([True] * 6, noise="low"),
        ),
    ]
    build_report(runs, tmp_path / "report")
    return tmp_path / "report"


def test_the_report_shows_success_with_its_wilson_interval(report: Path) -> None:
    table = (report / "table.md").read_text()
    assert (
        f"| {AGENTS} | 5/6 (83 %, 95 % CI 44–97 %) | 3/3 (100 %, 95 % CI 44–100 %) | "
        "8/9 (89 %, 95 % CI 57–98 %) |"
    ) in table
    line = next(
        r
        for r in csv.DictReader((report / "table.csv").open())
        if (r["method"], r["pattern"]) == (AGENTS, "pyramid")
    )
    interval = wilson(5, 6)
    assert interval is not None
    assert (float(line["success_ci_low"]), float(line["success_ci_high"])) == (
        interval.low,
        interval.high,
    )
    offsets = bootstrap_mean([0.0, 0.1, 0.2, 0.3, 0.4])
    assert offsets is not None and float(line["center_offset_cm_ci_low"]) == offsets.low
    assert f"| **0.200** [{offsets.low:.3f}, {offsets.high:.3f}] |" in table  # the best in bold
    assert "9/10 (90 %" not in table


def test_table_i_over_all_trials_gives_a_method_without_success_its_figures(
    report: Path,
) -> None:
    """The script succeeded in none of its 8 pyramid trials: dashes in Table I, its means
    over all trials beside it, in table.md, report.html, table.tex and table.csv."""
    markdown = (report / "table.md").read_text()
    offsets = np.arange(8) / 10  # 0.35 over all trials
    interval = bootstrap_mean(offsets)
    assert interval is not None
    over_all = f"0.350 [{interval.low:.3f}, {interval.high:.3f}]"
    rows = table_after(markdown, "Table I over all trials:")
    script = next(row for row in rows if row.startswith(f"| {CLASSICAL} |"))
    assert script.startswith(f"| {CLASSICAL} | **0.020** [0.020, 0.020] | {over_all} | ")
    successful = markdown.split("Table I over all trials:")[0]
    assert f"| {CLASSICAL} | – | – | – | " in successful  # no successful pyramid trial
    html = (report / "report.html").read_text()
    section = html.split('id="table-i-all-trials"')[1].split("</table>")[0]
    assert f'<td>{CLASSICAL}</td><td class="best">0.020<br>' in section
    assert f"<td>0.350<br><small>[{interval.low:.3f}, {interval.high:.3f}]</small></td>" in section
    latex = (report / "table.tex").read_text()
    assert latex.count(r"\begin{tabular}") == 3  # Table I, over all trials, success
    assert r"classical, precise & -- & -- & --" in latex.split("% Table I over all trials")[0]
    assert r"classical, precise & \textbf{0.020} & 0.350 & 99.00" in latex
    line = next(
        r
        for r in csv.DictReader((report / "table.csv").open())
        if (r["method"], r["pattern"]) == (CLASSICAL, "pyramid")
    )
    assert (line["center_offset_cm_mean"], float(line["center_offset_cm_all_trials_mean"])) == (
        "",
        pytest.approx(0.35),
    )
    assert float(line["center_offset_cm_all_trials_ci_low"]) == interval.low


def test_an_average_is_given_only_for_a_method_with_figures_on_every_pattern(
    report: Path,
) -> None:
    """The script has figures on the grid only and the agents under noise ran the pyramid
    only: neither gets an Average (a mean over other patterns does not compare), so the
    agents' Average, alone, is not bold. Over all trials the script ran both patterns."""
    markdown = (report / "table.md").read_text()
    table_i = markdown.split("\n\n", 1)[0].splitlines()[2:]
    rows = {row.split(" | ")[0][2:]: row for row in table_i}
    assert rows[CLASSICAL].endswith("| – | – | – |")
    assert rows[f"{AGENTS}, noise low"].endswith("| – | – | – |")
    assert rows[AGENTS].endswith("| 0.020 | 0.150 | 99.00 |")  # (0.2 + 0.1) / 2, not bold
    over_all = table_after(markdown, "Table I over all trials:")
    rows = {row.split(" | ")[0][2:]: row for row in over_all}
    assert rows[CLASSICAL].endswith("| **0.020** | 0.225 | **99.00** |")  # (0.35 + 0.1) / 2
    assert rows[AGENTS].endswith("| **0.020** | **0.175** | **99.00** |")
    averages = [
        r for r in csv.DictReader((report / "table.csv").open()) if r["pattern"] == "Average"
    ]
    assert [(r["method"], r["center_offset_cm_mean"]) for r in averages][1:] == [
        (CLASSICAL, ""),
        (f"{AGENTS}, noise low", ""),
    ]
    assert float(averages[0]["center_offset_cm_mean"]) == pytest.approx(0.15)
    assert float(averages[1]["center_offset_cm_all_trials_mean"]) == pytest.approx(0.225)


def test_rows_on_the_same_trial_seeds_are_compared_by_mcnemars_test(report: Path) -> None:
    """Pyramid: 6 trials in common (the script ran 8), the agents alone succeed in 5, the
    script alone in none: p = 2/32. The second pattern: 3 in common, b = 2, c = 0, p = 2/4.
    Over both: b = 7, c = 0, p = 2/128. The agents under noise pair with neither."""
    rows = table_after((report / "table.md").read_text(), "Paired comparisons.")
    assert rows == [
        f"| {AGENTS} | {CLASSICAL} | pyramid | 6 | 5 | 0 | 5 | 0 | 0.0625 |",
        f"| {AGENTS} | {CLASSICAL} | grid | 3 | 3 | 1 | 2 | 0 | 0.5 |",
        f"| {AGENTS} | {CLASSICAL} | all | 9 | 8 | 1 | 7 | 0 | 0.0156 |",
    ]
    assert mcnemar_exact(2, 0).p == 0.5 and mcnemar_exact(7, 0).p == pytest.approx(0.015625)
    html = (report / "report.html").read_text()
    assert f"<td>{AGENTS}</td><td>{CLASSICAL}</td><td>all</td><td>9</td>" in html


def test_a_rung_of_verification_other_than_the_methods_own_is_a_row_of_its_own(
    tmp_path: Path,
) -> None:
    runs = [
        write_run(tmp_path / "full", manifest(physics=PRECISE), lines([True] * 2, verify="full")),
        write_run(
            tmp_path / "gates",
            manifest(physics=PRECISE, verify=Verification.GATES),
            lines([False] * 2, verify="gates"),
        ),
    ]
    report = build_report(runs, tmp_path / "report")
    assert report.table.rows == [AGENTS, "agents (builtin, tools check, verify gates), precise"]
    (pair,) = report.table.pairs
    assert (pair.common, pair.test.b, pair.test.c) == (2, 2, 0)


def test_the_ladder_sets_the_rungs_side_by_side_with_their_tests_and_catches(
    tmp_path: Path,
) -> None:
    """The single agent succeeds in 3 of 5, the gated rung in 5 of 5 (b 0, c 2: p = 0.5),
    the method in 4 of 5; the method's corrupted answers: two caught before the move by
    the descent's plan, one after by sigma_5, one missed that did no harm."""
    single = RunManifest.sealed(
        "single-agent", "pyramid", "0" * 64, 0, TrialConfig(physics=PRECISE)
    )
    caught = AnswerErrorCounts(
        corrupted=4,
        by_kind={K.SIGN_FLIP: 4},
        caught={K.SIGN_FLIP: {Caught.BEFORE: 2, Caught.AFTER: 1, Caught.MISSED: 1}},
        checks={
            "descent_plan:grip_offset_m": {K.SIGN_FLIP: 2},
            "sigma5_placement:e_xy_m": {K.SIGN_FLIP: 1},
        },
        led_to={K.SIGN_FLIP: {"harmless": 1}},
    )
    runs = [
        write_run(
            tmp_path / "single",
            single,
            lines([True, False, True, False, True], method="single-agent", verify="none"),
        ),
        write_run(
            tmp_path / "gates",
            manifest(physics=PRECISE, verify=Verification.GATES),
            lines([True] * 5, verify="gates"),
        ),
        write_run(
            tmp_path / "full",
            manifest(physics=PRECISE),
            [
                t.model_copy(update={"answer_errors": caught if t.trial == 0 else None})
                for t in lines([True, True, True, True, False], verify="full")
            ],
        ),
    ]
    report = build_report(runs, tmp_path / "report")
    condition = "builtin, tools check, precise, noise none, no answer errors"
    cells = [row.cells for row in report.table.ladder]
    assert [c[:4] for c in cells] == [
        [condition, "single agent", "3/5 (23–88 %)", "–"],
        [condition, "σ1–σ6 only", "5/5 (57–100 %)", "0.5 (b 0, c 2)"],
        [condition, "both (the method)", "4/5 (38–96 %)", "1 (b 1, c 2)"],
    ]
    assert cells[2][4:] == [
        "4",
        "2",
        "1",
        "1 (0)",
        "descent_plan:grip_offset_m 2, sigma5_placement:e_xy_m 1",
    ]
    rows = table_after((tmp_path / "report" / "table.md").read_text(), "The ablation ladder.")
    assert rows[0].startswith(f"| {condition} | single agent | 3/5 (23–88 %) |")
