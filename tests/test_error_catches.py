"""What caught each corrupted answer (before the move, after it, missed and what the miss led
to) and the refused answers nobody corrupted, classified from hand-built transcripts; then
counted in a results line, summed in summary.md and shown by the report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import cli
from test_run_dir import manifest

from actionreasoning.agents.answer_errors import (
    AnswerCorruption,
    AnswerErrors,
    Caught,
    CorruptionKind,
)
from actionreasoning.agents.catches import HARMLESS, Catch, catches, premove_refusals
from actionreasoning.agents.transcript import AgentCall, CheckRecord, GateRecord, Outcome
from actionreasoning.agents.verification import judged_after_move
from actionreasoning.errors import ConfigError
from actionreasoning.records import Failure
from actionreasoning.runs.run_dir import open_run
from actionreasoning.runs.summary import summarize, summary_markdown
from actionreasoning.trial.results import AnswerErrorCounts, PlacementMetrics, TrialResult
from actionreasoning.trial.rules import trial_seed

K = CorruptionKind
FAILURE = Failure(reason="budget_exhausted", agent="lift", detail="3 answers refused")


def verdict(name: str, check: str = "", enforced: bool = True) -> GateRecord:
    """A verdict named ``name`` that failed on ``check`` (passed without one)."""
    checks = [CheckRecord(name=check or "c", value=1.0, relation="<=", threshold=0.5, passed=False)]
    if not check:
        checks[0] = checks[0].model_copy(update={"value": 0.0, "passed": True})
    return GateRecord(
        gate=name,
        passed=not check,
        checks=checks,
        enforced=enforced,
        after_move=judged_after_move(name),
    )


def call(
    agent: str,
    outcome: Outcome,
    *gates: GateRecord,
    kind: CorruptionKind | None = None,
    brick: int = 0,
    step: str | None = None,
) -> AgentCall:
    """One call of ``agent`` (the single agent's at ``step``) about ``brick``, its answer
    corrupted by ``kind`` if given."""
    corruption = None if kind is None else AnswerCorruption(kind=kind, detail="d", original={})
    return AgentCall(
        call=0, agent=agent, brick=brick, target=brick, attempt=1, prompt_chars=1,
        answer={} if step is None else {"step": step}, gates=list(gates), outcome=outcome,
        corruption=corruption,
    )  # fmt: skip


def corrupted(made: AgentCall, kind: CorruptionKind) -> AgentCall:
    """The call with its answer corrupted by ``kind``."""
    record = AnswerCorruption(kind=kind, detail="d", original={})
    return made.model_copy(update={"corruption": record})


def numbered(*calls: AgentCall) -> list[AgentCall]:
    return [c.model_copy(update={"call": i}) for i, c in enumerate(calls)]


ACCEPTED = Outcome.ACCEPTED


def cycle(brick: int = 0) -> list[AgentCall]:
    """A clean cycle of the six agents on ``brick``, each accepted."""
    return [
        call(agent, ACCEPTED, verdict(gate), brick=brick)
        for agent, gate in (
            ("pre_grasp", "sigma1_pre_grasp"),
            ("descent", "sigma2_descent"),
            ("grasp", "sigma3_grasp"),
            ("lift", "sigma4_lift"),
            ("placement", "sigma5_placement"),
            ("release", "sigma6_return"),
        )
    ]


@pytest.mark.parametrize(
    ("made", "caught", "check"),
    [
        (call("lift", Outcome.REFUSED, verdict("lift_answer", "valid_answer")), "before",
         "lift_answer:valid_answer"),
        (call("descent", Outcome.REFUSED, verdict("controller", "reachable")), "before",
         "controller:reachable"),
        (call("descent", Outcome.REFUSED, verdict("descent_plan", "turn_deg")), "before",
         "descent_plan:turn_deg"),
        (call("pre_grasp", Outcome.REFUSED, verdict("pre_grasp_choice", "brick_free")), "before",
         "pre_grasp_choice:brick_free"),
        (call("pre_grasp", Outcome.REFUSED, verdict("pre_grasp_plan"),
              verdict("sigma1_pre_grasp", "clearance_m")), "before",
         "sigma1_pre_grasp:clearance_m"),
        (call("release", Outcome.REFUSED, verdict("sigma6_return", "return_clearance_m")), "before",
         "sigma6_return:return_clearance_m"),
        (call("descent", Outcome.REFUSED, verdict("descent_plan"),
              verdict("sigma2_descent", "sidewall_force_n")), "after",
         "sigma2_descent:sidewall_force_n"),
        (call("grasp", Outcome.REFUSED, verdict("sigma3_grasp", "normal_force_n")), "after",
         "sigma3_grasp:normal_force_n"),
        (call("lift", Outcome.REGRASP, verdict("lift_plan"), verdict("sigma4_lift", "tilt_deg")),
         "after", "sigma4_lift:tilt_deg"),
        (call("placement", Outcome.RAISED, verdict("sigma5_placement", "e_xy_m")), "after",
         "sigma5_placement:e_xy_m"),
        # A rung that does not enforce the plan: the gate after the move caught it.
        (call("descent", Outcome.REFUSED, verdict("descent_plan", "turn_deg", enforced=False),
              verdict("sigma2_descent", "brick_shift_m")), "after", "sigma2_descent:brick_shift_m"),
        (call("lift", Outcome.REFUSED), "before", "refused"),  # no verdict on record
        (call("lift", Outcome.FAILED), "trial_stopped", None),
        (call("lift", Outcome.PENDING), "trial_stopped", None),
    ],
)  # fmt: skip
def test_a_caught_answer_is_caught_before_or_after_the_move_by_its_check(
    made: AgentCall, caught: str, check: str | None
) -> None:
    (found,) = catches([corrupted(made, K.SIGN_FLIP)])
    assert found == Catch(K.SIGN_FLIP, Caught(caught), check)


def test_a_miss_leads_to_the_next_check_that_refused_anything_in_its_bricks_cycle() -> None:
    first, *rest = cycle()
    near = corrupted(first, K.NEAR_OFFSET)
    descent = call("descent", Outcome.REFUSED, verdict("sigma2_descent", "sidewall_force_n"))
    (found,) = catches(numbered(near, descent, *rest))
    assert found == Catch(K.NEAR_OFFSET, Caught.MISSED, led_to="sigma2_descent:sidewall_force_n")
    # A check refusing an answer on the next brick is not the miss's doing.
    later = call("pre_grasp", Outcome.REFUSED, verdict("pre_grasp_plan", "grasp_offset_m"), brick=1)
    (found,) = catches(numbered(near, *rest, later))
    assert found.led_to == HARMLESS
    # Put down by sigma_4, the cycle starts again at Ag1: still the same brick's.
    put_down = call("lift", Outcome.REGRASP, verdict("sigma4_lift", "relative_speed_mps"))
    (found,) = catches(numbered(near, *rest[:2], put_down, first, *rest))
    assert found.led_to == "sigma4_lift:relative_speed_mps"


def test_a_miss_with_nothing_refused_after_it_leads_to_the_trials_end() -> None:
    first, *rest = cycle()
    missed = corrupted(rest[2], K.TOO_FAST)
    unfinished = numbered(first, rest[0], rest[1], missed, rest[3])  # no release
    assert catches(unfinished, FAILURE)[0].led_to == "budget_exhausted"
    assert catches(unfinished)[0].led_to == HARMLESS  # the trial ended well
    whole = numbered(first, *rest[:2], missed, *rest[3:])
    assert catches(whole, FAILURE)[0].led_to == HARMLESS  # placed before the trial ended
    assert catches(whole, FAILURE, misplaced={0})[0].led_to == "misplaced"
    assert catches(whole, FAILURE, misplaced={1})[0].led_to == HARMLESS


def test_a_miss_past_a_check_its_rung_does_not_enforce_would_have_been_caught_by_it() -> None:
    executed = call(
        "lift", Outcome.EXECUTED, verdict("lift_plan", "speed_mps", enforced=False),
        verdict("sigma4_lift"), verdict("other_plan", "x", enforced=False), kind=K.TOO_FAST,
    )  # fmt: skip
    placement = call("placement", Outcome.RAISED, verdict("sigma5_placement", "e_theta_deg"))
    (found,) = catches(numbered(executed, placement), FAILURE)
    assert found == Catch(
        K.TOO_FAST,
        Caught.MISSED,
        led_to="sigma5_placement:e_theta_deg",
        would_catch="lift_plan:speed_mps",
    )


def test_the_single_agents_cycle_ends_at_its_release_step() -> None:
    def step(name: str, kind: CorruptionKind | None = None, brick: int = 0) -> AgentCall:
        return call("single_agent", Outcome.EXECUTED, kind=kind, brick=brick, step=name)

    steps = ["pre_grasp", "descent", "grasp", "lift", "transfer", "placement", "release"]
    transcript = numbered(
        step("descent", K.NEAR_YAW), *(step(s) for s in steps[2:]), step("retreat"),
        step("pre_grasp", brick=1), step("descent", brick=1),
    )  # fmt: skip
    failure = Failure(reason="unreachable", agent="single_agent", detail="d")
    (found,) = catches(transcript, failure, misplaced={0})
    assert found == Catch(K.NEAR_YAW, Caught.MISSED, led_to="misplaced")
    (found,) = catches(transcript[:4], failure)  # stopped before its release
    assert found.led_to == "unreachable"


def test_repeats_are_marked() -> None:
    repeat = AnswerCorruption(kind=K.YAW_90, detail="d", original={}, repeated=True)
    made = call("descent", Outcome.REFUSED, verdict("descent_plan", "turn_deg"))
    (found,) = catches([made.model_copy(update={"corruption": repeat})])
    assert found.repeated and found.caught is Caught.BEFORE


def test_premove_refusals_count_checks_refusing_answers_nobody_corrupted() -> None:
    transcript = numbered(
        call("pre_grasp", Outcome.REFUSED, verdict("pre_grasp_plan", "grasp_offset_m")),
        call("pre_grasp", Outcome.REFUSED, verdict("pre_grasp_plan"),
             verdict("sigma1_pre_grasp", "clearance_m")),
        call("release", Outcome.REFUSED, verdict("sigma6_return", "return_clearance_m")),
        call("release", Outcome.REFUSED, verdict("sigma6_return", "return_clearance_m")),
        # Left out: corrupted, validation, after the move, not enforced, no verdict.
        call("descent", Outcome.REFUSED, verdict("descent_plan", "turn_deg"), kind=K.YAW_90),
        call("lift", Outcome.REFUSED, verdict("lift_answer", "valid_answer")),
        call("descent", Outcome.REFUSED, verdict("controller", "reachable")),
        call("grasp", Outcome.REFUSED, verdict("sigma3_grasp", "normal_force_n")),
        call("lift", Outcome.REGRASP, verdict("sigma4_lift", "tilt_deg")),
        call("lift", Outcome.EXECUTED, verdict("lift_plan", "speed_mps", enforced=False)),
        call("lift", Outcome.REFUSED),
    )  # fmt: skip
    assert premove_refusals(transcript) == {
        "pre_grasp_plan:grasp_offset_m": 1,
        "sigma1_pre_grasp:clearance_m": 1,
        "sigma6_return:return_clearance_m": 2,
    }
    assert premove_refusals(cycle()) == {}


# --- counted, summed and shown ------------------------------------------------------------


def line(trial: int, counts: AnswerErrorCounts | None, premove: dict[str, int]) -> TrialResult:
    metrics = PlacementMetrics(
        center_offset_cm=0.1, rotation_error_deg=0.1, symmetric_rotation_error_deg=0.1, iou=0.9
    )
    return TrialResult(
        method="agents", pattern="pyramid", physics="paper", tools="check", seed=0, trial=trial,
        trial_seed=trial_seed(0, trial), success=True, llm="builtin", bricks=(),
        bricks_placed=0, metrics=metrics, failure=None, sim_steps=1, answer_errors=counts,
        premove_refusals=premove,
    )  # fmt: skip


def transcript_counts() -> AnswerErrorCounts:
    """The counts of a trial: a near-miss caught before the move, one after, one missed."""
    plan = verdict("descent_plan", "grasp_offset_m")
    missed = call("lift", Outcome.EXECUTED, verdict("lift_plan", "turn_deg", enforced=False),
                  kind=K.NEAR_YAW)  # fmt: skip
    return AnswerErrorCounts.of(
        numbered(
            call("descent", Outcome.REFUSED, plan, kind=K.NEAR_OFFSET),
            call("descent", Outcome.REFUSED, verdict("sigma2_descent", "brick_shift_m"),
                 kind=K.NEAR_OFFSET),
            missed,
            call("placement", Outcome.RAISED, verdict("sigma5_placement", "e_theta_deg")),
        ),
        FAILURE,
    )  # fmt: skip


def test_counts_in_a_results_line_and_summed_in_the_summary() -> None:
    counts = transcript_counts()
    assert counts.caught == {
        K.NEAR_OFFSET: {Caught.BEFORE: 1, Caught.AFTER: 1},
        K.NEAR_YAW: {Caught.MISSED: 1},
    }
    assert counts.checks == {
        "descent_plan:grasp_offset_m": {K.NEAR_OFFSET: 1},
        "sigma2_descent:brick_shift_m": {K.NEAR_OFFSET: 1},
    }
    assert counts.led_to == {K.NEAR_YAW: {"sigma5_placement:e_theta_deg": 1}}
    assert counts.would_catch == {K.NEAR_YAW: {"lift_plan:turn_deg": 1}}
    stored = line(0, counts, {"sigma1_pre_grasp:clearance_m": 1})
    assert TrialResult.model_validate_json(stored.model_dump_json()) == stored
    clean = json.loads(line(0, None, {}).model_dump_json())
    assert "premove_refusals" not in clean and "answer_errors" not in clean
    results = [stored, line(1, counts, {"sigma1_pre_grasp:clearance_m": 2, "a_plan:b": 1})]
    errors = AnswerErrors(rate=0.2, persistence=0.5)
    summary = summarize(results, 1.0, answer_errors=errors)
    assert summary.premove_refusals == {"a_plan:b": 1, "sigma1_pre_grasp:clearance_m": 3}
    totals = summary.answer_errors
    assert totals is not None and totals.persistence == 0.5
    assert totals.caught[K.NEAR_OFFSET] == {Caught.BEFORE: 2, Caught.AFTER: 2}
    dumped = json.loads(summary.model_dump_json())["answer_errors"]
    assert dumped["persistence"] == 0.5 and dumped["led_to"] == {
        "near_yaw": {"sigma5_placement:e_theta_deg": 2}
    }
    markdown = summary_markdown(summary)
    assert "(all kinds, persistence 0.5); 6 answers corrupted." in markdown
    assert (
        "| Kind | Meaning | Answers | Repeats | Before the move | After the move | Missed "
        "| Trial stopped |" in markdown
    )
    assert f"| `near_offset` | {K.NEAR_OFFSET.meaning} | 4 | 0 | 2 | 2 | 0 | 0 |" in markdown
    assert "| Caught by | `near_offset` | Total |" in markdown
    assert "| `sigma2_descent:brick_shift_m` | 2 | 2 |" in markdown
    assert "| `near_yaw` | `sigma5_placement:e_theta_deg` 2 | `lift_plan:turn_deg` 2 |" in markdown
    assert "| `sigma1_pre_grasp:clearance_m` | 3 |" in markdown
    plain = summarize([line(0, None, {"a_plan:b": 1})], 1.0)
    assert plain.answer_errors is None and "| `a_plan:b` | 1 |" in summary_markdown(plain)


def test_the_report_shows_where_errors_were_caught_and_the_premove_refusals(
    tmp_path: Path,
) -> None:
    run = tmp_path / "run"
    setting = AnswerErrors(rate=0.2, persistence=0.5)
    assert open_run(run, manifest(answer_errors=setting)) == []
    counts = transcript_counts()
    lines = [line(t, counts, {"sigma1_pre_grasp:clearance_m": 1}) for t in range(2)]
    (run / "results.jsonl").write_text("".join(r.model_dump_json() + "\n" for r in lines))
    shown = cli("report", str(run), "--out", str(tmp_path / "report"))
    assert shown.returncode == 0, shown.stderr
    table = (tmp_path / "report" / "table.md").read_text()
    label = "agents (builtin, tools check), paper, answer errors 0.2 (persistence 0.5)"
    assert (
        f"| {label} | pyramid | 0.2 | 0.5 | 6 | near_offset 4, near_yaw 2 | 2 | 2 | 2 | 0 | "
        "descent_plan:grasp_offset_m 2, sigma2_descent:brick_shift_m 2 | "
        "sigma5_placement:e_theta_deg 2 | lift_plan:turn_deg 2 |"
    ) in table
    assert f"| {label} | pyramid | `sigma1_pre_grasp:clearance_m` | 2 |" in table
    page = (tmp_path / "report" / "report.html").read_text()
    assert 'id="answer-errors"' in page and 'id="premove-refusals"' in page


def test_a_resume_under_another_persistence_is_refused_naming_it(tmp_path: Path) -> None:
    def setting(persistence: float) -> AnswerErrors:
        return AnswerErrors(rate=0.2, persistence=persistence)

    assert open_run(tmp_path, manifest(answer_errors=setting(0.5))) == []
    (tmp_path / "results.jsonl").write_text(line(0, None, {}).model_dump_json() + "\n")
    assert len(open_run(tmp_path, manifest(answer_errors=setting(0.5)))) == 1
    for other, shown in ((0.25, "0.25"), (0.0, "None")):
        with pytest.raises(ConfigError, match=rf"answer_errors.persistence 0.5 there, {shown} now"):
            open_run(tmp_path, manifest(answer_errors=setting(other)))
    stored = json.loads((tmp_path / "run.json").read_text())["config"]["answer_errors"]
    assert stored["persistence"] == 0.5
    default = json.loads(manifest().model_dump_json())["config"]["answer_errors"]
    assert "persistence" not in default  # run.json at persistence 0 as before it existed
