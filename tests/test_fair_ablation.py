"""The ablation's arms differ only in verification (scripted FakeWorld, the real orchestrator).

The single agent answers the same stages as the six agents, through the same moves and
controller primitives, with the same validation and retry budget; each rung of
verification refuses only what it enforces and records the rest; and every pre-move check
accepts an answer the physics allows, however it differs from the built-in's.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from conftest import assert_clean_error, cli
from fake_world import FakeWorld, presses
from test_orchestrator_fake import (
    BRICKS,
    Scripted,
    calls,
    failed_checks,
    gates_of,
    shifted,
    with_waypoint,
)

from actionreasoning.agents.calls import BuildResult
from actionreasoning.agents.orchestrator import MEMORY_DIGITS, Budgets, Orchestrator
from actionreasoning.agents.outputs import (
    AgentAnswer,
    GraspAnswer,
    SingleAgentAnswer,
    WaypointProposal,
)
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.agents.verification import Verification
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, run_trial
from actionreasoning.world.geometry import quat_yaw
from actionreasoning.world.models import GoalPattern
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, SceneSpec
from actionreasoning.world.success import SuccessRule
from actionreasoning.world.tolerances import Tolerances

SPEC = SceneSpec()
TOL = Tolerances()
RULE = SuccessRule()
#: A workspace position no waypoint may have.
OUTSIDE = (2.0, 0.0, 0.2)


@pytest.fixture
def one_brick(wall: GoalPattern) -> GoalPattern:
    return wall.model_copy(update={"targets": wall.targets[:1]})


def build(
    world: FakeWorld,
    reasoner: Scripted | None = None,
    verify: Verification = Verification.FULL,
    single: bool = False,
) -> BuildResult:
    orchestrator = Orchestrator(world, reasoner or Scripted(), verify=verify, single_agent=single)
    return orchestrator.build(world.goal)


def assert_within_the_rule(world: FakeWorld, result: BuildResult) -> None:
    """Every target holds its brick within the success rule, and the hand is empty."""
    assert result.failure is None, result.failure
    assert sorted(result.placements) == [t.index for t in world.goal.targets]
    for target, brick in result.placements.items():
        slot = world.goal.targets[target].pose
        placed = world.bricks[brick].pose
        assert math.dist(placed.position_m, slot.position_m) <= RULE.max_center_offset_cm / 100
    assert world.held is None


# --- the single agent: the same stages, validation and budget --------------------------
def test_the_single_agent_answers_the_six_agents_stages_through_the_same_moves(
    kinematics, one_brick
) -> None:
    agents_world = FakeWorld(one_brick, BRICKS, *kinematics)
    agents = build(agents_world)
    single_world = FakeWorld(one_brick, BRICKS, *kinematics)
    single = build(single_world, verify=Verification.NONE, single=True)
    assert_within_the_rule(single_world, single)
    assert [c.agent for c in single.transcript] == ["single_agent"] * len(agents.transcript)
    assert [c.answer["step"] for c in single.transcript] == [c.agent for c in agents.transcript]
    # The same primitives: the hover over the slot, the guarded set-down, the retreat.
    assert [(m.stage, m.stop_on_contact) for m in single_world.moves] == [
        (m.stage, m.stop_on_contact) for m in agents_world.moves
    ]
    # Every verdict measured and recorded; none but validation may refuse.
    assert all(not g.enforced for c in single.transcript for g in c.gates)


def test_a_refused_single_agent_answer_is_asked_again_within_the_same_budget(
    kinematics, one_brick
) -> None:
    """An answer refused by validation (here a waypoint outside the workspace) goes back to
    the single agent as to any agent, and the next one is accepted."""
    outside = with_waypoint(lambda w: w.model_copy(update={"position_m": OUTSIDE}))
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    reasoner = Scripted({"single_agent": [None, outside]})  # its descent, the second call
    result = build(world, reasoner, Verification.NONE, single=True)
    assert_within_the_rule(world, result)
    refused, accepted = result.transcript[1:3]
    assert (refused.outcome, refused.attempt, refused.answer["step"]) == ("refused", 1, "descent")
    assert refused.caught_by == "descent_answer:valid_answer"
    assert (accepted.outcome, accepted.attempt, accepted.answer["step"]) == (
        "accepted",
        2,
        "descent",
    )
    again = reasoner.requests[2]
    assert again.memory.last_feedback == refused.feedback
    assert [m.stage for m in world.moves].count("descent") == 1  # the refused one never moved


def test_the_single_agents_budget_is_the_agents(kinematics, one_brick) -> None:
    outside = with_waypoint(lambda w: w.model_copy(update={"position_m": OUTSIDE}))
    attempts = Budgets().attempts_per_agent
    for single in (False, True):
        world = FakeWorld(one_brick, BRICKS, *kinematics)
        key = "single_agent" if single else "descent"
        script = [None, *[outside] * attempts] if single else [outside] * attempts
        verify = Verification.NONE if single else Verification.FULL
        result = build(world, Scripted({key: script}), verify, single)
        assert result.failure is not None
        assert (result.failure.reason, result.failure.agent) == ("invalid_output", "descent")
        assert result.failure.detail.startswith(f"{attempts} answers refused")
        assert [c.outcome for c in calls(result, key)][-attempts:] == ["refused"] * attempts


def test_a_single_agent_step_with_a_missing_field_is_refused(kinematics, one_brick) -> None:
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    no_waypoint = SingleAgentAnswer(step="descent", gripper_opening_m=0.135)
    result = build(world, Scripted({"single_agent": [None, no_waypoint]}), Verification.NONE, True)
    assert_within_the_rule(world, result)
    refused = result.transcript[1]
    assert refused.outcome == "refused" and refused.category == "schema"
    assert refused.caught_by == "descent_answer:answer_complete"
    assert "the answer needs gripper_opening_m, waypoint; missing: waypoint" in refused.feedback
    assert [m.stage for m in world.moves].count("descent") == 1


def test_a_single_agent_answer_for_another_step_is_refused(kinematics, one_brick) -> None:
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    up = WaypointProposal(position_m=(0.5, -0.3, 0.3), quat_xyzw=(1.0, 0.0, 0.0, 0.0))
    lift = SingleAgentAnswer(step="lift", waypoint=up)
    result = build(world, Scripted({"single_agent": [None, lift]}), Verification.NONE, True)
    assert_within_the_rule(world, result)
    refused = result.transcript[1]
    assert refused.outcome == "refused" and refused.caught_by == "descent_answer:valid_answer"
    assert "step 'lift' answered; memory.step asks for 'descent'" in refused.feedback


# --- the rungs: what each enforces, and what it records -----------------------------------
#: A descent 4 mm off along the brick: its plan's forecast of sigma_3 fails.
OFF_ALONG = 0.004


def along(distance_m: float):
    yaw = quat_yaw(BRICKS[0].quat_xyzw)
    return shifted(distance_m * math.cos(yaw), distance_m * math.sin(yaw))


def test_with_the_gates_only_a_failed_plan_is_recorded_and_sigma_3_refuses_after_the_move(
    kinematics, one_brick
) -> None:
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    reasoner = Scripted({"descent": [along(OFF_ALONG)]})
    result = build(world, reasoner, Verification.GATES)
    assert_within_the_rule(world, result)
    # The grasp's memory holds m_1, m_2: the descent's decision and the check it failed.
    m_1, m_2 = reasoner.asked("grasp")[0].memory.this_brick
    assert (m_1.agent, m_1.passed, m_2.agent, m_2.passed) == ("pre_grasp", True, "descent", False)
    assert m_2.failed == ("descent_plan",) and m_2.waypoint is not None
    descent = calls(result, "descent")[0]
    (plan,) = [g for g in descent.gates if g.gate == "descent_plan"]
    assert not plan.passed and not plan.enforced and descent.outcome == "executed"
    assert descent.caught_by == "missed"
    # It ran, and sigma_3 measured the grip it made 4 mm off: refused, after the move.
    grasp = calls(result, "grasp")[0]
    assert (grasp.outcome, grasp.caught_by) == ("refused", "sigma3_grasp:pose_error_m")
    assert failed_checks(grasp)["pose_error_m"] == pytest.approx(OFF_ALONG, abs=1e-6)


def test_with_the_checks_only_a_failed_plan_refuses_before_the_move(kinematics, one_brick) -> None:
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    result = build(world, Scripted({"descent": [along(OFF_ALONG)]}), Verification.CHECKS)
    assert_within_the_rule(world, result)
    refused = calls(result, "descent")[0]
    assert (refused.outcome, refused.caught_by) == ("refused", "descent_plan:grip_offset_m")
    assert [m.stage for m in world.moves].count("descent") == 1


def test_with_the_checks_only_a_failed_gate_is_recorded_and_the_build_goes_on(
    kinematics, one_brick
) -> None:
    """sigma_2 finds a pad pressing on the brick: recorded, and, not enforced, no back-up
    and no second descent."""
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    world.script("descent", presses(TOL.sidewall_contact_n + 1.0))
    result = build(world, verify=Verification.CHECKS)
    descents = calls(result, "descent")
    assert len(descents) == 1 and descents[0].outcome == "executed"
    assert gates_of(descents[0]) == [("descent_plan", True), ("sigma2_descent", False)]
    assert [g.enforced for g in descents[0].gates] == [True, False]
    assert [m.stage for m in world.moves].count("descent") == 1  # no back-up


@pytest.mark.parametrize("rung", list(Verification))
def test_every_rung_enforces_validation(kinematics, one_brick, rung: Verification) -> None:
    outside = with_waypoint(lambda w: w.model_copy(update={"position_m": OUTSIDE}))
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    result = build(world, Scripted({"lift": [outside]}), rung)
    assert_within_the_rule(world, result)
    refused = calls(result, "lift")[0]
    assert (refused.outcome, refused.caught_by) == ("refused", "lift_answer:valid_answer")


# --- the pre-move checks accept any answer the physics allows ---------------------------
def _across_m(distance_m: float) -> tuple[float, float]:
    """The world (x, y) of ``distance_m`` across brick 0's width."""
    yaw = quat_yaw(BRICKS[0].quat_xyzw)
    return -distance_m * math.sin(yaw), distance_m * math.cos(yaw)


def _across(distance_m: float):
    """A change of a waypoint: shifted across brick 0's width."""
    return shifted(*_across_m(distance_m))


def _raised(dz: float):
    return with_waypoint(
        lambda w: w.model_copy(update={"position_m": (*w.position_m[:2], w.position_m[2] + dz)})
    )


def _both(*changes):
    def change(answer: AgentAnswer) -> AgentAnswer:
        for one in changes:
            answer = one(answer)
        return answer

    return change


def _wide_open(answer: AgentAnswer) -> AgentAnswer:
    return answer.model_copy(update={"gripper_opening_m": GRIPPER_GAP_M[1]})


def _slanted_lift(answer: AgentAnswer) -> AgentAnswer:
    """4 cm sideways and 3 cm higher, slow enough for v_lift over the longer way."""
    waypoint = answer.waypoint  # type: ignore[attr-defined]
    x, y, z = waypoint.position_m
    moved = waypoint.model_copy(
        update={"position_m": (x + 0.04, y, z + 0.03), "duration_s": waypoint.duration_s * 1.3}
    )
    return answer.model_copy(update={"waypoint": moved})


#: Per agent: a physically valid answer unlike the built-in's, as a change of its answer.
NON_CANONICAL = {
    # 6 mm off the brick's centre and 4 cm higher: the descent goes to the centre anyway.
    "pre_grasp": _both(shifted(0.006, -0.002), _raised(0.04)),
    # 8 mm across the width, wide open: the pads pass the walls and centre the brick.
    "descent": _both(_across(0.008), _wide_open),
    "lift": _slanted_lift,
    # 5 mm off the slot: within the success rule and sigma_5's seat.
    "placement": shifted(0.005, 0.0),
    # Another pose to wait at: 10 cm away, turned 30 deg.
    "release": _both(shifted(0.1, 0.05), _raised(0.05)),
}


@dataclass
class CloseAcross(Scripted):
    """The built-in reasoner, but its first grasp closes 6 mm across the brick from where
    the tool is (a corrected pose given at once; the closing centres the brick)."""

    def decide(self, request: AgentRequest) -> AgentReply:
        reply = super().decide(request)
        if request.spec.key != "grasp" or len(self.asked("grasp")) > 1:
            return reply
        tool = request.view.robot.tool_pose
        here = WaypointProposal(position_m=tool.position_m, quat_xyzw=tool.quat_xyzw)
        there = shifted(*_across_m(0.006))(GraspAnswer(close=True, waypoint=here))
        return AgentReply(answer=there)


@pytest.mark.parametrize("agent", sorted(NON_CANONICAL))
def test_a_physically_valid_answer_unlike_the_built_ins_is_accepted_and_the_build_succeeds(
    kinematics, one_brick, agent: str
) -> None:
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    change = NON_CANONICAL[agent]
    result = build(world, Scripted({agent: [change]}))
    assert_within_the_rule(world, result)
    first = calls(result, agent)[0]
    assert first.outcome == "accepted" and first.attempt == 1, first.feedback
    reference = calls(build(FakeWorld(one_brick, BRICKS, *kinematics)), agent)[0]
    assert first.answer["waypoint"] != reference.answer["waypoint"]


def test_a_grasp_closed_off_across_the_brick_is_accepted_and_the_build_succeeds(
    kinematics, one_brick
) -> None:
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    result = build(world, CloseAcross())
    assert_within_the_rule(world, result)
    first = calls(result, "grasp")[0]
    assert first.outcome == "accepted" and first.answer["waypoint"] is not None
    assert gates_of(first) == [("grasp_plan", True), ("sigma3_grasp", True)]


@dataclass
class NonCanonical:
    """The built-in reasoner, each of whose answers is changed into another the physics
    allows (NON_CANONICAL; the grasp closes 3 mm across the brick; the slot is shifted only
    at the set-down, the carry's hover being no seat)."""

    name: str = "non-canonical"
    builtin: BuiltinReasoner = field(default_factory=BuiltinReasoner)

    def decide(self, request: AgentRequest) -> AgentReply:
        answer = self.builtin.decide(request).answer
        key, memory = str(request.spec.key), request.memory
        if key == "grasp":
            tool = request.view.robot.tool_pose
            yaw = quat_yaw(tool.quat_xyzw)
            x, y, z = tool.position_m
            across = (x - 0.003 * math.sin(yaw), y + 0.003 * math.cos(yaw), z)
            here = WaypointProposal(position_m=across, quat_xyzw=tool.quat_xyzw)
            return AgentReply(answer=GraspAnswer(close=True, waypoint=here))
        if key == "placement" and memory.phase != "set_down":
            return AgentReply(answer=answer)
        change = NON_CANONICAL.get(key)
        if key == "descent":  # across this trial's brick: the tool's y axis
            tool = request.view.robot.tool_pose
            yaw = quat_yaw(tool.quat_xyzw)
            change = _both(shifted(-0.008 * math.sin(yaw), 0.008 * math.cos(yaw)), _wide_open)
        if change is None or getattr(answer, "waypoint", None) is None:
            return AgentReply(answer=answer)
        return AgentReply(answer=change(answer))


@pytest.mark.slow
def test_a_trial_answered_unlike_the_built_in_at_every_stage_succeeds_in_the_simulator() -> None:
    """Paper physics, pyramid, trial 0: every answer differs from the built-in's and the
    physics allows it; every pre-move check accepts it at once, and the trial succeeds."""
    spec = TrialSpec(
        method=Method.AGENTS,
        pattern_name="pyramid",
        goal=load_pattern("pyramid", SceneSpec()),
        run_seed=0,
        trial=0,
    )
    run = run_trial(spec, reasoner=NonCanonical())
    assert run.result.success, run.result.failure
    for call in run.transcript:
        plans = [g for g in call.gates if g.gate.endswith(("_plan", "_choice"))]
        assert all(g.passed for g in plans), (call.agent, call.feedback)
    assert {c.agent for c in run.transcript if c.attempt > 1} <= {"placement"}  # sigma_5 only


def test_memory_carries_the_earlier_agents_decisions_for_this_brick(kinematics, one_brick) -> None:
    """m_1 ... m_(i-1): each agent reads the decisions accepted before it in this brick's
    cycle (not their rationales), in order, each with its verdict."""
    reasoner = Scripted()
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    result = build(world, reasoner)
    asked = [(r.spec.key, r.memory.this_brick) for r in reasoner.requests]
    for (agent, memory), before in zip(asked, range(len(asked)), strict=True):
        assert [m.agent for m in memory] == [key for key, _ in asked[:before]], agent
    answers = [c.answer for c in result.transcript]
    for m_i, answer in zip(asked[-1][1], answers, strict=False):
        decided = m_i.model_dump(mode="json", exclude={"agent", "phase", "passed", "failed"})
        assert m_i.passed and _within({k: v for k, v in decided.items() if v is not None}, answer)


def _within(part: object, whole: object) -> bool:
    """Whether ``part`` is ``whole`` with some of its mapping fields (defaults) left out and
    its numbers recalled to MEMORY_DIGITS decimals."""
    if isinstance(part, dict) and isinstance(whole, dict):
        return all(name in whole and _within(value, whole[name]) for name, value in part.items())
    if isinstance(part, list) and isinstance(whole, list):
        return len(part) == len(whole) and all(map(_within, part, whole))
    if isinstance(part, float):
        return part == round(float(whole), MEMORY_DIGITS)  # type: ignore[arg-type]
    return part == whole


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--method", "single-agent", "--verify", "gates"), "drop --verify gates"),
        (("--method", "classical", "--verify", "full"), "drop --verify full"),
    ],
)
def test_a_rung_the_method_cannot_run_is_refused_in_one_line(
    tmp_path: Path, args: tuple[str, ...], needle: str
) -> None:
    result = cli("eval", *args, "--trials", "1", "--out", str(tmp_path / "o"))
    assert_clean_error(result, needle)
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_the_rung_is_recorded_in_run_json_and_on_every_line(tmp_path: Path, small_pattern) -> None:
    out = tmp_path / "gates"
    args = ("--pattern", str(small_pattern), "--physics", "precise", "--trials", "1")
    result = cli("eval", "--verify", "gates", *args, "--transcripts", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert json.loads((out / "run.json").read_text())["config"]["verify"] == "gates"
    (line,) = (out / "results.jsonl").read_text().splitlines()
    assert json.loads(line)["verify"] == "gates"
    calls = [json.loads(c) for c in (out / "transcripts" / "trial_000.jsonl").open()]
    enforced = {g["gate"]: g["enforced"] for c in calls for g in c["gates"]}
    assert enforced["descent_plan"] is False and enforced["sigma2_descent"] is True
    single = tmp_path / "single"
    assert cli("eval", "--method", "single-agent", *args, "--out", str(single)).returncode == 0
    assert "verify" not in json.loads((single / "run.json").read_text())["config"]
    (line,) = (single / "results.jsonl").read_text().splitlines()
    assert json.loads(line)["verify"] == "none"
