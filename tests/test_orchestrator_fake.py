"""The gated orchestrator on a scripted FakeWorld: every gate's pass and refusal, retries,
re-grasps and raise-and-retry, fast. The real-scene trials are in test_orchestrator.py."""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np
import pytest
from conftest import SMALL_PATTERN
from fake_world import (
    Deviation,
    FakeWorld,
    lands_off,
    one_pad_misses,
    out_of_reach,
    presses,
    rolls,
    shoves,
    slips,
    stalls,
)

from actionreasoning.agents.calls import BuildResult
from actionreasoning.agents.orchestrator import Budgets, Orchestrator
from actionreasoning.agents.outputs import (
    AgentAnswer,
    GraspAnswer,
    PreGraspAnswer,
    WaypointProposal,
)
from actionreasoning.agents.put_down import SET_ASIDE_MARGIN_M
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.agents.transcript import AgentCall
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.sim.collision import CollisionChecker
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import quat_yaw, top_down_quat, yaw_quat
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.models import READY_POSE, GoalPattern, Pose
from actionreasoning.world.motion import Motion
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, SceneSpec
from actionreasoning.world.tolerances import Tolerances

SPEC = SceneSpec()
#: Where the three bricks lie at the start (in the pick area, yaws as drawn).
BRICKS = sample_pick_poses(np.random.default_rng(0), 3, SPEC)

Change = AgentAnswer | Callable[[AgentAnswer], AgentAnswer] | None


@pytest.fixture(scope="session")
def kinematics() -> Iterator[tuple[KinematicArm, CollisionChecker]]:
    """The arm's kinematic copy and its collision checker, shared by every fake world."""
    arm = KinematicArm()
    yield arm, CollisionChecker(arm)
    arm.close()


@pytest.fixture(scope="session")
def wall(tmp_path_factory: pytest.TempPathFactory) -> GoalPattern:
    """Two bricks side by side and one on top."""
    path = tmp_path_factory.mktemp("patterns") / "small.json"
    path.write_text(json.dumps(SMALL_PATTERN))
    return load_pattern(path, SPEC)


@pytest.fixture
def one_brick(wall: GoalPattern) -> GoalPattern:
    return wall.model_copy(update={"targets": wall.targets[:1]})


@pytest.fixture
def world(kinematics, one_brick: GoalPattern) -> FakeWorld:
    """A fake world with the three bricks, to build the first target."""
    return FakeWorld(one_brick, BRICKS, *kinematics)


@dataclass
class Scripted:
    """The built-in reasoner, except for the scripted next answers of some agents: an answer
    as it stands, a change of the built-in's answer, or None for the built-in's own."""

    script: dict[str, list[Change]] = field(default_factory=dict)
    name: str = "scripted"
    builtin: BuiltinReasoner = field(default_factory=BuiltinReasoner)
    requests: list[AgentRequest] = field(default_factory=list)

    def decide(self, request: AgentRequest) -> AgentReply:
        self.requests.append(request)
        pending = self.script.get(request.spec.key, [])
        change = pending.pop(0) if pending else None
        if isinstance(change, AgentAnswer):
            return AgentReply(answer=change)
        reply = self.builtin.decide(request)
        return reply if change is None else AgentReply(answer=change(reply.answer))

    def asked(self, agent: str) -> list[AgentRequest]:
        return [r for r in self.requests if r.spec.key == agent]


def build(
    world: FakeWorld, reasoner: Scripted | None = None, budgets: Budgets = Budgets()
) -> BuildResult:
    return Orchestrator(world, reasoner or Scripted(), budgets=budgets).build(world.goal)


def calls(result: BuildResult, agent: str) -> list[AgentCall]:
    return [c for c in result.transcript if c.agent == agent]


def failed_checks(call: AgentCall) -> dict[str, float]:
    return {c.name: c.value for g in call.gates for c in g.checks if not c.passed}


def assert_built(world: FakeWorld, result: BuildResult) -> None:
    """Every target of the world's goal holds its brick, placed on it exactly."""
    assert result.failure is None, result.failure
    assert sorted(result.placements) == [t.index for t in world.goal.targets]
    for target, brick in result.placements.items():
        slot = world.goal.targets[target].pose
        placed = world.bricks[brick].pose
        assert math.dist(placed.position_m, slot.position_m) < 1e-6
        assert abs(quat_yaw(placed.quat_xyzw) - quat_yaw(slot.quat_xyzw)) % math.pi < 1e-6
    assert world.held is None


def moved(waypoint: WaypointProposal, dx: float = 0.0, z: float | None = None):
    """The waypoint shifted by ``dx`` along x, or put at height ``z``."""
    x, y, z0 = waypoint.position_m
    return waypoint.model_copy(update={"position_m": (x + dx, y, z0 if z is None else z)})


def with_waypoint(change: Callable[[WaypointProposal], WaypointProposal]):
    """A change of an answer's waypoint."""
    return lambda answer: answer.model_copy(update={"waypoint": change(answer.waypoint)})


# --- the whole cycle ----------------------------------------------------------------------
def test_the_wall_is_built_with_every_gate_passed(kinematics, wall) -> None:
    world = FakeWorld(wall, BRICKS, *kinematics)
    result = build(world)
    assert_built(world, result)
    assert result.decisions == 3 * 7 and result.fallbacks == 0
    gates = [[g.gate for g in c.gates] for c in result.transcript[:7]]
    assert gates == [
        ["sigma1_pre_grasp"],
        ["sigma2_descent"],
        ["sigma3_grasp"],
        ["lift_plan", "sigma4_lift"],
        [],  # the carry over the slot: checked paths, no gate
        ["sigma5_placement"],
        ["sigma6_return"],
    ]
    assert all(
        c.outcome == "accepted" and all(g.passed for g in c.gates) for c in result.transcript
    )
    # Every set-down is a guarded move that stops as its brick touches down.
    set_downs = [m for m in world.moves if m.stop_on_contact is not None]
    assert [m.stop_on_contact for m in set_downs] == [0, 1, 2]
    assert all(m.motion.stopped_on_contact for m in set_downs)
    assert world.tool == READY_POSE  # each release ends at the ready pose


# --- Ag1 pre-grasp: verification and sigma_1 ---------------------------------------------
READY = WaypointProposal(position_m=READY_POSE.position_m, quat_xyzw=READY_POSE.quat_xyzw)
#: The tool at brick 1's centre, turned across it: its fingers in the brick.
INTO_BRICK_1 = WaypointProposal(
    position_m=BRICKS[1].position_m,
    quat_xyzw=top_down_quat(quat_yaw(BRICKS[1].quat_xyzw) + math.pi / 2),
)
DOUBLED = {"quat_xyzw": (0.0, 0.0, 0.0, 2.0)}
BAD_PRE_GRASPS = {
    "incomplete": (
        PreGraspAnswer(brick_id=0, target_index=0),
        "invalid_output",
        "the answer needs brick_id, target_index and waypoint",
    ),
    "unknown brick": (
        PreGraspAnswer(brick_id=7, target_index=0, waypoint=READY),
        "invalid_choice",
        "brick 7 does not exist or is already placed",
    ),
    "unknown target": (
        PreGraspAnswer(brick_id=0, target_index=5, waypoint=READY),
        "invalid_choice",
        "target 5 does not exist or is already built",
    ),
    "not a unit quaternion": (
        PreGraspAnswer(
            brick_id=0,
            target_index=0,
            waypoint=READY.model_copy(update={"quat_xyzw": (0, 0, 0, 2)}),
        ),
        "invalid_output",
        "quaternion norm 2.0000 is not 1",
    ),
    "sigma1: fingers in another brick": (
        PreGraspAnswer(brick_id=0, target_index=0, waypoint=INTO_BRICK_1),
        "collision",
        "sigma1_pre_grasp failed: clearance_m = -",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_PRE_GRASPS))
def test_a_refused_pre_grasp_spends_the_budget_and_ends_typed(world, case: str) -> None:
    answer, reason, feedback = BAD_PRE_GRASPS[case]
    reasoner = Scripted({"pre_grasp": [answer] * 3})
    result = build(world, reasoner)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == (reason, "pre_grasp")
    assert feedback in result.failure.detail
    assert [(c.attempt, c.outcome) for c in result.transcript] == [
        (1, "refused"),
        (2, "refused"),
        (3, "refused"),
    ]
    assert all(feedback in c.feedback for c in result.transcript)
    asked = reasoner.asked("pre_grasp")
    assert feedback in asked[2].memory.last_feedback
    assert asked[2].memory.retries == {"pre_grasp": 2}
    assert world.moves == [] and result.placements == {}


def test_a_target_on_unbuilt_supports_is_refused(kinematics, wall) -> None:
    world = FakeWorld(wall, BRICKS, *kinematics)
    too_early = PreGraspAnswer(brick_id=0, target_index=2, waypoint=READY)
    result = build(world, Scripted({"pre_grasp": [too_early] * 3}))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("invalid_choice", "pre_grasp")
    assert "target 2 rests on targets [0, 1], not built yet" in result.failure.detail
    assert world.moves == []


def test_a_refused_answer_is_asked_again_with_feedback_and_then_accepted(world) -> None:
    bad = PreGraspAnswer(brick_id=0, target_index=0, waypoint=INTO_BRICK_1)
    reasoner = Scripted({"pre_grasp": [bad]})
    result = build(world, reasoner)
    assert_built(world, result)
    refused, accepted = calls(result, "pre_grasp")
    assert (refused.outcome, accepted.outcome) == ("refused", "accepted")
    assert failed_checks(refused)["clearance_m"] < 0.0
    again = reasoner.asked("pre_grasp")[1]
    assert again.memory.last_feedback == refused.feedback
    assert again.memory.retries == {"pre_grasp": 1}
    assert result.decisions == 8
    assert [m.stage for m in world.moves].count("pre_grasp") == 1  # the refused one never moved


# --- Ag2 descent: verification and sigma_2 ------------------------------------------------
def test_a_descent_opening_too_narrow_is_refused_before_it_moves(world) -> None:
    narrow = Scripted({"descent": [lambda a: a.model_copy(update={"gripper_opening_m": 0.1})]})
    result = build(world, narrow)
    assert_built(world, result)
    refused, _ = calls(result, "descent")
    assert refused.feedback == "opening 0.100 m < brick width 0.095 + delta"
    assert [m.stage for m in world.moves].count("descent") == 1


def test_a_descent_into_the_ground_is_refused_until_the_budget_is_spent(world) -> None:
    into_ground = with_waypoint(lambda w: moved(w, z=0.0))
    result = build(world, Scripted({"descent": [into_ground] * 3}))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("collision", "descent")
    assert "descent path collides" in result.failure.detail
    assert [c.outcome for c in calls(result, "descent")] == ["refused"] * 3
    assert [m.stage for m in world.moves] == ["pre_grasp"]


def test_a_pad_pressing_on_the_brick_fails_sigma2_and_the_descent_is_retried(world) -> None:
    world.script("descent", presses(6.0))
    result = build(world)
    assert_built(world, result)
    refused, accepted = calls(result, "descent")
    assert failed_checks(refused) == {"sidewall_force_n": 6.0}
    assert refused.feedback.startswith("sigma2_descent failed: sidewall_force_n = 6, needs <= 1")
    assert accepted.outcome == "accepted" and accepted.gates[0].passed


def test_a_brick_shoved_on_the_descent_fails_sigma2_and_is_grasped_where_it_went(world) -> None:
    world.script("descent", shoves(0.03))
    result = build(world)
    assert_built(world, result)
    refused, accepted = calls(result, "descent")
    assert failed_checks(refused)["brick_shift_m"] == pytest.approx(0.03)
    # Asked again, the descent goes to the brick where it is now.
    x, y, _ = BRICKS[0].position_m
    yaw = quat_yaw(BRICKS[0].quat_xyzw)
    shoved = (x + 0.03 * math.cos(yaw), y + 0.03 * math.sin(yaw))
    assert accepted.answer["waypoint"]["position_m"][:2] == pytest.approx(shoved)


def test_a_descent_blocked_every_time_ends_the_trial(world) -> None:
    world.script("descent", presses(6.0), times=3)
    result = build(world)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("descent_blocked", "descent")
    assert "sidewall_force_n = 6" in result.failure.detail


# --- Ag3 grasp: sigma_3 -------------------------------------------------------------------
def test_a_grasp_answer_that_does_not_close_is_refused(world) -> None:
    result = build(world, Scripted({"grasp": [GraspAnswer(close=False)]}))
    assert_built(world, result)
    refused, _ = calls(result, "grasp")
    assert refused.feedback == "the gripper is at the grasp pose: answer close = true"


def test_a_pad_that_misses_fails_sigma3_and_the_grasp_is_tried_again(world) -> None:
    world.script("grasp", one_pad_misses())
    result = build(world)
    assert_built(world, result)
    refused, accepted = calls(result, "grasp")
    assert failed_checks(refused) == {"normal_force_n": 0.0}
    assert refused.feedback.startswith("sigma3_grasp failed: normal_force_n = 0, needs >= ")
    measured = {c.name: c.value for c in accepted.gates[0].checks}
    assert measured["normal_force_n"] == 40.0 and measured["pose_error_m"] < 1e-9


def test_a_descent_that_stops_short_fails_every_grasp_on_its_pose_error(world) -> None:
    world.script("descent", stalls(0.01))
    result = build(world)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("grasp_failed", "grasp")
    (descent,) = [m for m in world.moves if m.stage == "descent"]
    assert not descent.motion.converged
    assert descent.motion.position_error_m == pytest.approx(0.01)
    grasps = calls(result, "grasp")
    assert len(grasps) == 3
    assert all(failed_checks(c).keys() == {"pose_error_m"} for c in grasps)
    assert failed_checks(grasps[0])["pose_error_m"] == pytest.approx(0.01)
    assert world.held is None and world.width == GRIPPER_GAP_M[1]  # let go after each


# --- Ag4 lift: the lift plan, reach and sigma_4 -------------------------------------------
def test_a_sideways_lift_is_refused_before_it_moves(world) -> None:
    result = build(world, Scripted({"lift": [with_waypoint(lambda w: moved(w, dx=0.04))]}))
    assert_built(world, result)
    refused, accepted = calls(result, "lift")
    assert [g.gate for g in refused.gates] == ["lift_plan"]
    assert "sideways_m = 0.04" in refused.feedback
    assert [g.gate for g in accepted.gates] == ["lift_plan", "sigma4_lift"]
    lifts = [m for m in world.moves if m.stage == "lift"]
    assert len(lifts) == 1 and lifts[0].waypoint.position_m == tuple(
        accepted.answer["waypoint"]["position_m"]
    )


def test_a_lift_out_of_reach_is_asked_again(world) -> None:
    world.script("lift", out_of_reach())
    result = build(world)
    assert_built(world, result)
    refused, _ = calls(result, "lift")
    assert refused.feedback.startswith("unreachable: pose (")
    assert refused.gates[0].passed  # planned fine; the arm did not get there


def test_a_lift_never_in_reach_ends_the_trial_unreachable(world) -> None:
    world.script("lift", out_of_reach(), times=3)
    result = build(world)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("unreachable", "lift")
    assert world.held == 0  # still in the hand where it was grasped


def test_a_slip_in_the_lift_puts_the_brick_back_and_grasps_it_again(world) -> None:
    world.script("lift", slips(speed_mps=0.02))
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    slipped, lifted = calls(result, "lift")
    assert slipped.outcome == "regrasp"
    assert failed_checks(slipped) == {"relative_speed_mps": 0.02}
    again = result.transcript[result.transcript.index(slipped) + 1]
    assert (again.agent, again.answer["brick_id"]) == ("pre_grasp", 0)
    second = reasoner.asked("pre_grasp")[1]
    assert second.memory.regrasps == 1
    assert second.memory.last_feedback.startswith("sigma4_lift failed: relative_speed_mps = 0.02")
    # Put back flat where it was grasped.
    back = second.state.brick(0)
    assert back.status == "in_pick_area"
    assert math.dist(back.pose.position_m, BRICKS[0].position_m) < 1e-3
    assert lifted.outcome == "accepted"


def test_slips_past_the_regrasp_budget_end_the_trial_as_grasp_slip(world) -> None:
    world.script("lift", slips(), times=math.inf)
    result = build(world, budgets=Budgets(regrasps=1))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("grasp_slip", "lift")
    assert [c.outcome for c in calls(result, "lift")] == ["regrasp", "regrasp"]
    assert result.placements == {} and world.held is None


# --- Ag5 placement: re-grasp and sigma_5 raise-and-retry ----------------------------------
def test_a_brick_rolled_in_the_hand_is_set_aside_and_grasped_again(world, one_brick) -> None:
    world.script("placement", rolls(30.0))  # on the carry over the slot
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    (asked,) = [c for c in result.transcript if c.outcome == "regrasp"]
    assert asked.agent == "placement" and asked.answer["regrasp"] is True
    assert (
        asked.feedback
        == "placement asked for a re-grasp; the brick had rolled 30.0 deg in the hand"
    )
    second = reasoner.asked("pre_grasp")[1]
    assert second.memory.regrasps == 1 and second.memory.last_feedback == asked.feedback
    # Set down level on free ground near by, clear of the target.
    aside = second.state.brick(0)
    assert aside.status == "dropped" and aside.pickable
    box = Box(aside.pose.position_m, aside.pose.quat_xyzw, aside.size_m, id=0)
    target = one_brick.targets[0]
    slot = Box(target.pose.position_m, target.pose.quat_xyzw, target.size_m, id=1)
    assert box.footprint.distance(slot.footprint) > SET_ASIDE_MARGIN_M / 2


def test_a_misaligned_set_down_is_raised_and_placed_again(world) -> None:
    world.script("placement", lands_off((0.005, 0.0, 0.0)))
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    carry, raised, corrected = calls(result, "placement")
    assert [carry.outcome, raised.outcome, corrected.outcome] == ["accepted", "raised", "accepted"]
    assert failed_checks(raised) == {"e_xy_m": pytest.approx(0.005)}
    assert reasoner.asked("placement")[2].memory.last_feedback == raised.feedback
    # Raised straight up by delta_h from where it touched down, still held.
    guarded = next(i for i, m in enumerate(world.moves) if m.stop_on_contact is not None)
    touched, up = world.moves[guarded].waypoint, world.moves[guarded + 1].waypoint
    assert up.path == "linear"
    assert up.position_m[2] - touched.position_m[2] == pytest.approx(Tolerances().delta_h_m)
    assert "the set-down stopped on contact with the tool at z = " in raised.feedback


def test_a_set_down_that_met_no_support_says_so(world) -> None:
    landed = lands_off((0.005, 0.0, 0.0))

    def no_touch(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        return replace(landed.apply(world, waypoint, stop), stopped_on_contact=False)

    world.script("placement", Deviation("move", no_touch, only=landed.only))
    result = build(world, Scripted())
    assert_built(world, result)
    raised = calls(result, "placement")[1]
    assert raised.outcome == "raised"
    assert "the set-down ran all the way to the slot" in raised.feedback
    assert "stopped on contact" not in raised.feedback


def test_set_downs_misaligned_every_time_end_the_trial(world) -> None:
    world.script("placement", lands_off((0.005, 0.0, 0.0)), times=math.inf)
    result = build(world)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("placement_misaligned", "placement")
    assert "e_xy_m = 0.005" in result.failure.detail
    outcomes = [c.outcome for c in calls(result, "placement")]
    assert outcomes == ["accepted"] + ["raised"] * Budgets().placement_attempts


# --- Ag6 release: sigma_6 -----------------------------------------------------------------
INTO_GROUND = with_waypoint(lambda w: w.model_copy(update={"position_m": (0.6, -0.2, 0.005)}))


def test_a_return_into_the_ground_is_refused_and_asked_again(world) -> None:
    result = build(world, Scripted({"release": [INTO_GROUND]}))
    assert_built(world, result)
    refused, accepted = calls(result, "release")
    assert [g.gate for g in refused.gates] == ["sigma6_return"]
    assert "return_clearance_m" in refused.feedback and "retreat" not in refused.feedback
    assert accepted.gates[0].passed


def test_a_return_refused_every_time_keeps_the_brick_in_the_hand(world) -> None:
    result = build(world, Scripted({"release": [INTO_GROUND] * 3}))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("collision", "release")
    assert world.held == 0 and result.placements == {}


# --- which bricks can be picked -----------------------------------------------------------
def test_a_brick_dropped_flat_outside_the_pick_area_is_picked_from_there(
    kinematics, one_brick
) -> None:
    dropped = Pose(position_m=(0.55, 0.0, 0.03), quat_xyzw=yaw_quat(0.4))
    world = FakeWorld(one_brick, [dropped], *kinematics)
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    assert reasoner.asked("pre_grasp")[0].state.brick(0).status == "dropped"


def test_a_toppled_last_brick_ends_the_trial_with_no_brick_left(kinematics, one_brick) -> None:
    on_its_side = Pose(
        position_m=(0.3, -0.45, 0.0475), quat_xyzw=(math.sqrt(0.5), 0, 0, math.sqrt(0.5))
    )
    world = FakeWorld(one_brick, [on_its_side], *kinematics)
    result = build(world)
    assert result.failure is not None
    assert result.failure.reason == "no_brick_left"
    assert "brick 0 toppled" in result.failure.detail
    assert result.transcript == [] and world.moves == []
