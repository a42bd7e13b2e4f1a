"""The gated orchestrator on a scripted FakeWorld: every gate's pass and refusal, retries,
re-grasps and raise-and-retry, fast. The real-scene trials are in test_orchestrator.py."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import pytest
from fake_world import (
    Deviation,
    FakeWorld,
    closes_off,
    creeps,
    falls_out,
    lands_off,
    lets_go_off,
    one_pad_misses,
    out_of_reach,
    presses,
    rolls,
    shoves,
    slips,
    stalls,
)
from scipy.spatial.transform import Rotation
from shapely.geometry import Polygon

from actionreasoning.agents.calls import AgentCaller, BuildResult
from actionreasoning.agents.orchestrator import (
    HOVER_STEP_M,
    ROLL_WATCH_S,
    SETTLE_S,
    Budgets,
    Orchestrator,
)
from actionreasoning.agents.outputs import (
    AgentAnswer,
    DescentAnswer,
    GraspAnswer,
    LiftAnswer,
    PlacementAnswer,
    PreGraspAnswer,
    ReleaseAnswer,
    WaypointProposal,
)
from actionreasoning.agents.put_down import SET_ASIDE_MARGIN_M, SET_ASIDE_SLACK_M, PutDown
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.agents.tiers import DEFAULT_TIER, ToolTier
from actionreasoning.agents.transcript import AgentCall
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.tools import formulas
from actionreasoning.tools.geometry import alignment_of
from actionreasoning.world.boxes import Box
from actionreasoning.world.cameras import TOP_DOWN
from actionreasoning.world.geometry import quat_yaw, tilt_deg, top_down_quat, wrap_angle, yaw_quat
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.models import READY_POSE, BrickState, GoalPattern, Pose, Progress
from actionreasoning.world.motion import Motion
from actionreasoning.world.physics import GRAVITY_MPS2
from actionreasoning.world.scene_spec import (
    FINGERTIPS_BEYOND_TCP_M,
    GRIPPER_GAP_M,
    ReachBand,
    SceneSpec,
)
from actionreasoning.world.tolerances import LIFT_SUPPORT_M, Tolerances

SPEC = SceneSpec()
#: Where the three bricks lie at the start (in the pick area, yaws as drawn).
BRICKS = sample_pick_poses(np.random.default_rng(0), 3, SPEC)
#: The thresholds a build of the one-brick goal runs under (exact sensors, no joints).
TOL = Tolerances()
#: A pad force just past what slides the brick over the ground (sigma_2's threshold).
PRESSING_N = TOL.sidewall_contact_n + 1.0

Change = AgentAnswer | Callable[[AgentAnswer], AgentAnswer] | None


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
    world: FakeWorld,
    reasoner: Scripted | None = None,
    budgets: Budgets = Budgets(),
    tier: ToolTier = DEFAULT_TIER,
) -> BuildResult:
    return Orchestrator(world, reasoner or Scripted(), budgets=budgets, tier=tier).build(world.goal)


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


def shifted(dx: float, dy: float, turn_deg: float = 0.0):
    """A change of an answer's waypoint: shifted by (``dx``, ``dy``) and turned ``turn_deg``
    about the vertical through the tool centre point."""

    def change(waypoint: WaypointProposal) -> WaypointProposal:
        x, y, z = waypoint.position_m
        turn = Rotation.from_euler("z", turn_deg, degrees=True)
        quat = tuple(float(q) for q in (turn * Rotation.from_quat(waypoint.quat_xyzw)).as_quat())
        return waypoint.model_copy(update={"position_m": (x + dx, y + dy, z), "quat_xyzw": quat})

    return with_waypoint(change)


def along_brick(distance_m: float, brick: int = 0):
    """A change of an answer's waypoint: shifted along brick ``brick``'s length."""
    yaw = quat_yaw(BRICKS[brick].quat_xyzw)
    return shifted(distance_m * math.cos(yaw), distance_m * math.sin(yaw))


def along_error(distance_m: float, brick: int = 0) -> tuple[float, float, float]:
    """The feedback's (e_x_m, e_y_m, e_theta_deg) of a pose off along brick ``brick``."""
    yaw = quat_yaw(BRICKS[brick].quat_xyzw)
    return (distance_m * math.cos(yaw), distance_m * math.sin(yaw), 0.0)


def gates_of(call: AgentCall) -> list[tuple[str, bool]]:
    return [(g.gate, g.passed) for g in call.gates]


def checked(call: AgentCall, gate: str) -> dict[str, float]:
    """Every check of ``gate`` in ``call`` with its measured value."""
    (record,) = [g for g in call.gates if g.gate == gate]
    return {c.name: c.value for c in record.checks}


def xy(call: AgentCall) -> tuple[float, float]:
    """The x, y of a call's answered waypoint."""
    x, y, _ = call.answer["waypoint"]["position_m"]
    return x, y


def yaw_deg(call: AgentCall) -> float:
    return math.degrees(quat_yaw(tuple(call.answer["waypoint"]["quat_xyzw"])))


def turned_deg(a: float, b: float) -> float:
    """``a`` minus ``b`` (deg), wrapped to [-180, 180)."""
    return math.degrees(wrap_angle(math.radians(a - b)))


def speed_of_lift(call: AgentCall) -> float:
    """The mean speed of a lift answer, as the lift's plan measured it."""
    return checked(call, "lift_plan")["speed_mps"]


def beside(pose: Pose, gap_m: float) -> Pose:
    """A brick lying ``gap_m`` beside one at ``pose``, across its width, turned alike."""
    yaw = quat_yaw(pose.quat_xyzw)
    x, y, z = pose.position_m
    d = SPEC.brick_size_m[1] + gap_m
    return Pose(
        position_m=(x - d * math.sin(yaw), y + d * math.cos(yaw), z), quat_xyzw=pose.quat_xyzw
    )


def assert_set_aside(brick: BrickState, others: list[Pose]) -> None:
    """A brick set down for a re-grasp: lying flat, pickable, inside the measured reach band
    with room for a landing off by SET_ASIDE_SLACK_M, clear of the ``others``."""
    assert brick.pickable and tilt_deg(brick.pose.quat_xyzw) < 1e-6
    band = ReachBand()
    radius = math.hypot(*brick.pose.position_m[:2])
    assert band.min_radius_m + SET_ASIDE_SLACK_M <= radius <= band.max_radius_m - SET_ASIDE_SLACK_M
    box = Box(brick.pose.position_m, brick.pose.quat_xyzw, brick.size_m, id=0).footprint
    for other in others:
        taken = Box(other.position_m, other.quat_xyzw, SPEC.brick_size_m, id=1).footprint
        assert box.distance(taken) >= SET_ASIDE_MARGIN_M - 1e-9


# --- the whole cycle ----------------------------------------------------------------------
def test_the_wall_is_built_with_every_gate_passed(kinematics, wall) -> None:
    world = FakeWorld(wall, BRICKS, *kinematics)
    result = build(world)
    assert_built(world, result)
    assert result.decisions == 3 * 7 and result.fallbacks == 0
    gates = [[g.gate for g in c.gates] for c in result.transcript[:7]]
    assert gates == [
        ["pre_grasp_choice", "pre_grasp_plan", "sigma1_pre_grasp"],
        ["descent_plan", "sigma2_descent"],
        ["sigma3_grasp"],
        ["lift_plan", "sigma4_lift"],
        ["placement_plan"],  # the carry over the slot: checked before it moves, no gate after
        ["placement_plan", "sigma5_placement"],
        ["release_plan", "sigma6_return", "sigma6_at_rest"],  # the brick judged at rest
    ]
    assert all(
        c.outcome == "accepted" and all(g.passed for g in c.gates) for c in result.transcript
    )
    # Every set-down is a guarded move that stops as its brick touches down.
    set_downs = [m for m in world.moves if m.stop_on_contact is not None]
    assert [m.stop_on_contact for m in set_downs] == [0, 1, 2]
    assert all(m.motion.stopped_on_contact for m in set_downs)
    # The carry ends over the slot at the height it was lifted to: no hover below it.
    lifts = [m for m in world.moves if m.stage == "lift"]
    carries = [
        m
        for i, m in enumerate(world.moves)
        if m.stage == "placement" and world.moves[i - 1].stage == "lift"
    ]
    assert [m.waypoint.position_m[2] for m in carries] == [m.waypoint.position_m[2] for m in lifts]
    for carry, set_down in zip(carries, set_downs, strict=True):
        assert carry.waypoint.position_m[:2] == set_down.waypoint.position_m[:2]
    assert world.tool == READY_POSE  # each release ends at the ready pose


# --- Ag1 pre-grasp: validation, the choice, the approach plan and sigma_1 ----------------
READY = WaypointProposal(position_m=READY_POSE.position_m, quat_xyzw=READY_POSE.quat_xyzw)
#: The tool at brick 1's centre, turned across it: its fingers in the brick.
INTO_BRICK_1 = WaypointProposal(
    position_m=BRICKS[1].position_m,
    quat_xyzw=top_down_quat(quat_yaw(BRICKS[1].quat_xyzw) + math.pi / 2),
)
#: A height straight over the first brick that the arm cannot reach pointing down.
UNREACHABLE_Z = 0.8
#: (the answer or a change of the built-in's, failure code, gate and check that refuse it,
#: what the feedback says)
BAD_PRE_GRASPS = {
    "incomplete": (
        PreGraspAnswer(brick_id=0, target_index=0),
        "invalid_output",
        ("pre_grasp_answer", "answer_complete"),
        "the answer needs brick_id, target_index, waypoint; missing: waypoint",
    ),
    "unknown brick": (
        PreGraspAnswer(brick_id=7, target_index=0, waypoint=READY),
        "invalid_output",
        ("pre_grasp_answer", "valid_answer"),
        "brick_id 7 names no brick (ids 0..2)",
    ),
    "unknown target": (
        PreGraspAnswer(brick_id=0, target_index=5, waypoint=READY),
        "invalid_output",
        ("pre_grasp_answer", "valid_answer"),
        "target_index 5 names no target (0..0)",
    ),
    "not a unit quaternion": (
        PreGraspAnswer(
            brick_id=0,
            target_index=0,
            waypoint=READY.model_copy(update={"quat_xyzw": (0, 0, 0, 2)}),
        ),
        "invalid_output",
        ("pre_grasp_answer", "valid_answer"),
        "quaternion norm 2.0000 is not 1",
    ),
    "approach in another brick": (
        PreGraspAnswer(brick_id=0, target_index=0, waypoint=INTO_BRICK_1),
        "invalid_output",
        ("pre_grasp_plan", "hover_clearance_m"),
        "pre_grasp_plan failed: hover_clearance_m = -",
    ),
    # Over the brick it chose, pointing down across it, but so high the arm cannot reach it:
    # only sigma_1's path check sees it.
    "sigma1: out of reach": (
        with_waypoint(lambda w: moved(w, z=UNREACHABLE_Z)),
        "collision",
        ("sigma1_pre_grasp", "reachable"),
        "sigma1_pre_grasp failed: reachable = 0",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_PRE_GRASPS))
def test_a_refused_pre_grasp_spends_the_budget_and_ends_typed(world, case: str) -> None:
    answer, reason, (gate, check), feedback = BAD_PRE_GRASPS[case]
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
    for call in result.transcript:
        # The refusing gate is the last one recorded: nothing after it ran.
        assert call.gates[-1].gate == gate and not call.gates[-1].passed
        assert all(g.passed for g in call.gates[:-1])
        assert check in failed_checks(call)
        assert call.feedback.startswith(f"{gate} failed: ") and feedback in call.feedback
    asked = reasoner.asked("pre_grasp")
    assert feedback in asked[2].memory.last_feedback
    assert asked[2].memory.retries == {"pre_grasp": 2}
    assert [r.gate for r in asked[2].memory.refusals] == [gate, gate]
    assert world.moves == [] and result.placements == {}


def test_a_target_on_unbuilt_supports_is_refused(kinematics, wall) -> None:
    world = FakeWorld(wall, BRICKS, *kinematics)
    too_early = PreGraspAnswer(brick_id=0, target_index=2, waypoint=READY)
    result = build(world, Scripted({"pre_grasp": [too_early] * 3}))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("invalid_choice", "pre_grasp")
    assert "target 2 rests on targets [0, 1], not built yet" in result.failure.detail
    assert gates_of(result.transcript[-1]) == [("pre_grasp_choice", False)]
    assert failed_checks(result.transcript[-1]) == {"target_buildable": 0.0}
    assert world.moves == []


def test_a_brick_already_placed_is_refused_as_not_free(kinematics, wall) -> None:
    world = FakeWorld(wall, BRICKS, *kinematics)
    again = PreGraspAnswer(brick_id=0, target_index=1, waypoint=READY)
    result = build(world, Scripted({"pre_grasp": [None, again]}))
    assert_built(world, result)
    refused = [c for c in result.transcript if c.outcome == "refused"]
    assert [c.agent for c in refused] == ["pre_grasp"]
    assert failed_checks(refused[0]) == {"brick_free": 0.0}
    assert "brick 0 is placed" in refused[0].feedback


def test_a_refused_answer_is_asked_again_with_feedback_and_then_accepted(world) -> None:
    bad = PreGraspAnswer(brick_id=0, target_index=0, waypoint=INTO_BRICK_1)
    reasoner = Scripted({"pre_grasp": [bad]})
    result = build(world, reasoner)
    assert_built(world, result)
    refused, accepted = calls(result, "pre_grasp")
    assert (refused.outcome, accepted.outcome) == ("refused", "accepted")
    assert gates_of(refused) == [("pre_grasp_choice", True), ("pre_grasp_plan", False)]
    (x, y, z), (bx, by, bz) = INTO_BRICK_1.position_m, BRICKS[0].position_m
    hover = z - FINGERTIPS_BEYOND_TCP_M - (bz + SPEC.brick_size_m[2] / 2)
    assert failed_checks(refused)["hover_clearance_m"] == pytest.approx(hover)
    again = reasoner.asked("pre_grasp")[1]
    assert again.memory.last_feedback == refused.feedback
    assert again.memory.retries == {"pre_grasp": 1}
    (refusal,) = again.memory.refusals
    assert (refusal.agent, refusal.gate, refusal.text()) == (
        "pre_grasp",
        "pre_grasp_plan",
        refused.feedback,
    )
    assert (refusal.measured.e_x_m, refusal.measured.e_y_m) == pytest.approx((bx - x, by - y))
    assert result.decisions == 8
    assert [m.stage for m in world.moves].count("pre_grasp") == 1  # the refused one never moved


def test_a_way_sigma1_refused_is_not_answered_again_the_next_grasp_is(
    kinematics, one_brick
) -> None:
    """sigma_1 found the way to the approach out of reach or not clear: the same answer would
    be refused again, so the built-in answers the next usable grasp (the other side of the
    brick, or the next brick)."""
    too_high = with_waypoint(lambda w: moved(w, z=UNREACHABLE_Z))
    first = calls(build(FakeWorld(one_brick, BRICKS, *kinematics)), "pre_grasp")
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    reasoner = Scripted({"pre_grasp": [too_high, too_high]})
    result = build(world, reasoner)
    assert_built(world, result)
    *refused, accepted = calls(result, "pre_grasp")
    assert [c.outcome for c in refused] == ["refused", "refused"]
    assert all(c.gates[-1].gate == "sigma1_pre_grasp" for c in refused)
    # Twice refused by sigma_1 (scripted): the third usable grasp, not the first.
    chosen = [(c.answer["brick_id"], round(yaw_deg(c), 6)) for c in (first[0], accepted)]
    assert chosen[0] != chosen[1]
    assert accepted.answer["rationale"].startswith("target 0 next")


# --- Ag2 descent: the descent plan and sigma_2 --------------------------------------------
def test_a_descent_opening_too_narrow_is_refused_before_it_moves(world) -> None:
    width = SPEC.brick_size_m[1]
    narrow_m = round(width + TOL.delta_m - 0.001, 4)  # a millimetre short of width + delta
    narrow = Scripted({"descent": [lambda a: a.model_copy(update={"gripper_opening_m": narrow_m})]})
    result = build(world, narrow)
    assert_built(world, result)
    refused, _ = calls(result, "descent")
    assert gates_of(refused) == [("descent_plan", False)]
    assert failed_checks(refused) == {"opening_m": narrow_m}
    assert refused.feedback.startswith(
        f"descent_plan failed: opening_m = {narrow_m:.4g}, needs >= {width + TOL.delta_m:.4g}"
    )
    assert [m.stage for m in world.moves].count("descent") == 1


def test_a_descent_into_the_ground_is_refused_until_the_budget_is_spent(world) -> None:
    into_ground = with_waypoint(lambda w: moved(w, z=0.0))
    result = build(world, Scripted({"descent": [into_ground] * 3}))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("collision", "descent")
    descents = calls(result, "descent")
    assert [c.outcome for c in descents] == ["refused"] * 3
    for call in descents:
        failed = failed_checks(call)
        assert gates_of(call) == [("descent_plan", False)]
        assert failed["way_clearance_m"] < 0.0  # the fingers in the ground
        assert failed["grip_offset_m"] == pytest.approx(SPEC.brick_size_m[2] / 2)
    assert "way_clearance_m = -" in result.failure.detail
    assert "closest: gripper_finger_left vs ground" in result.failure.detail
    assert [m.stage for m in world.moves] == ["pre_grasp"]


def test_a_pad_pressing_on_the_brick_fails_sigma2_and_the_descent_is_retried(world) -> None:
    world.script("descent", presses(PRESSING_N))
    result = build(world)
    assert_built(world, result)
    refused, accepted = calls(result, "descent")
    assert gates_of(refused) == [("descent_plan", True), ("sigma2_descent", False)]
    assert failed_checks(refused) == {"sidewall_force_n": PRESSING_N}
    assert refused.feedback.startswith(
        f"sigma2_descent failed: sidewall_force_n = {PRESSING_N:.4g}, "
        f"needs <= {TOL.sidewall_contact_n:.4g}"
    )
    assert gates_of(accepted) == [("descent_plan", True), ("sigma2_descent", True)]
    # Refused, the tool backs up the way it came, to where the descent started.
    down, back, again = [m for m in world.moves if m.stage == "descent"]
    (approach,) = [m for m in world.moves if m.stage == "pre_grasp"]
    assert (
        back.waypoint.position_m == approach.waypoint.position_m and back.waypoint.path == "linear"
    )
    assert again.waypoint.position_m == down.waypoint.position_m


def test_a_pad_touching_with_less_than_slides_the_brick_passes_sigma2(world) -> None:
    world.script("descent", presses(TOL.sidewall_contact_n / 2))
    result = build(world)
    assert_built(world, result)
    (descent,) = calls(result, "descent")
    assert checked(descent, "sigma2_descent")["sidewall_force_n"] == TOL.sidewall_contact_n / 2
    assert gates_of(descent) == [("descent_plan", True), ("sigma2_descent", True)]


def test_a_brick_shoved_on_the_descent_fails_sigma2_and_is_grasped_where_it_went(world) -> None:
    """sigma_2's correction: the feedback says where the brick went, and the retry goes there."""
    world.script("descent", shoves(0.03))
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    refused, accepted = calls(result, "descent")
    assert failed_checks(refused) == {"brick_shift_m": pytest.approx(0.03)}
    yaw = quat_yaw(BRICKS[0].quat_xyzw)
    shove = (0.03 * math.cos(yaw), 0.03 * math.sin(yaw))
    (refusal,) = reasoner.asked("descent")[1].memory.refusals
    assert refusal.gate == "sigma2_descent"
    assert (refusal.measured.e_x_m, refusal.measured.e_y_m) == pytest.approx(shove)
    # Asked again, the descent goes to the brick where it is now: moved by the refusal's shift.
    moved_by = (xy(accepted)[0] - xy(refused)[0], xy(accepted)[1] - xy(refused)[1])
    assert moved_by == pytest.approx((refusal.measured.e_x_m, refusal.measured.e_y_m), abs=1e-9)
    assert checked(accepted, "sigma2_descent")["brick_shift_m"] == 0.0


def test_a_descent_blocked_every_time_ends_the_trial(world) -> None:
    world.script("descent", presses(PRESSING_N), times=math.inf)
    result = build(world)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("descent_blocked", "descent")
    assert f"sidewall_force_n = {PRESSING_N:.4g}" in result.failure.detail


# --- Ag3 grasp: the close and sigma_3 -----------------------------------------------------
def test_a_grasp_answer_that_does_not_close_is_refused(world) -> None:
    result = build(world, Scripted({"grasp": [GraspAnswer(close=False)]}))
    assert_built(world, result)
    refused, _ = calls(result, "grasp")
    assert refused.feedback == (
        "grasp_plan failed: close = 0, needs >= 1; "
        "the gripper is at the grasp pose: answer close = true"
    )
    assert gates_of(refused) == [("grasp_plan", False)]  # never closed: no sigma_3


def test_a_pad_that_misses_fails_sigma3_and_the_grasp_is_tried_again(world) -> None:
    world.script("grasp", one_pad_misses())
    result = build(world)
    assert_built(world, result)
    refused, accepted = calls(result, "grasp")
    assert failed_checks(refused) == {"normal_force_n": 0.0}
    # f_min: the force per pad whose friction (pads 1.2 x brick 0.5) carries the brick.
    f_min = TOL.f_min_n(world.mass_kg * GRAVITY_MPS2 / (2 * 1.2 * world.friction))
    assert refused.feedback.startswith(
        f"sigma3_grasp failed: normal_force_n = 0, needs >= {f_min:.4g}; "
    )
    assert "pad_forces_n=(40, 0)" in refused.feedback
    measured = checked(accepted, "sigma3_grasp")
    assert measured["normal_force_n"] == 40.0 and measured["pose_error_m"] < 1e-9


def test_a_grip_off_the_bricks_centre_is_corrected_by_the_feedback(world) -> None:
    """sigma_3's correction: closed 5 mm off the brick's centre and turned 2 deg, the grip is
    refused; the next close is shifted and turned by the refusal's errors, and passes."""
    world.script("grasp", closes_off((-0.005, 0.002), turn_deg=2.0))
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    refused, accepted = calls(result, "grasp")
    assert set(failed_checks(refused)) == {"pose_error_m", "pose_error_deg"}
    assert failed_checks(refused)["pose_error_m"] == pytest.approx(math.hypot(0.005, 0.002))
    assert failed_checks(refused)["pose_error_deg"] == pytest.approx(2.0)
    again = reasoner.asked("grasp")[1]
    (refusal,) = again.memory.refusals
    miss = refusal.measured
    assert (miss.e_x_m, miss.e_y_m, miss.e_theta_deg) == pytest.approx((-0.005, 0.002, 2.0))
    # Opened again where it closed; the corrected close is that pose, shifted and turned.
    tool = again.view.robot.tool_pose
    x, y, _ = tool.position_m
    assert xy(accepted) == pytest.approx((x + miss.e_x_m, y + miss.e_y_m), abs=1e-9)
    turn = turned_deg(yaw_deg(accepted), math.degrees(quat_yaw(tool.quat_xyzw)))
    assert turn == pytest.approx(miss.e_theta_deg, abs=1e-9)
    assert gates_of(accepted) == [("grasp_plan", True), ("sigma3_grasp", True)]
    grip = checked(accepted, "sigma3_grasp")
    assert grip["pose_error_m"] < 1e-9 and grip["pose_error_deg"] < 1e-9
    (close_again,) = [m for m in world.moves if m.stage == "grasp"]
    assert close_again.waypoint.path == "linear"


def test_a_grip_off_centre_every_time_ends_the_trial_as_grasp_failed(world) -> None:
    world.script("grasp", closes_off((0.005, 0.0)), times=math.inf)
    result = build(world)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("grasp_failed", "grasp")
    grasps = calls(result, "grasp")
    assert len(grasps) == 3
    assert all(failed_checks(c).keys() == {"pose_error_m"} for c in grasps)
    assert world.held is None and world.width == GRIPPER_GAP_M[1]  # let go after each


def test_a_grip_high_on_the_brick_is_refused_and_closed_again_at_its_centre(world) -> None:
    # The descent stops 1 cm short: the pads close 1 cm above the brick's centre.
    world.script("descent", stalls(0.01))
    result = build(world)
    assert_built(world, result)
    (descent,) = [m for m in world.moves if m.stage == "descent"]
    assert not descent.motion.converged
    assert descent.motion.position_error_m == pytest.approx(0.01)
    refused, accepted = calls(result, "grasp")
    assert failed_checks(refused).keys() == {"pose_error_m"}
    assert failed_checks(refused)["pose_error_m"] == pytest.approx(0.01)
    miss = result.transcript[refused.call].gates[-1]
    assert miss.gate == "sigma3_grasp" and not miss.passed
    # The retry closes at the tool pose shifted down by the measured e_z_m: at the centre.
    tool_z = descent.waypoint.position_m[2] + 0.01
    assert accepted.answer["waypoint"]["position_m"][2] == pytest.approx(tool_z - 0.01)
    assert accepted.outcome == "accepted"


# --- Ag4 lift: the lift plan, reach and sigma_4 -------------------------------------------
def test_a_lift_that_drags_the_brick_is_refused_before_it_moves(world) -> None:
    """10 cm sideways over the lift's rise drags the brick 3.7 mm over its support."""
    result = build(world, Scripted({"lift": [with_waypoint(lambda w: moved(w, dx=0.1))]}))
    assert_built(world, result)
    refused, accepted = calls(result, "lift")
    assert gates_of(refused) == [("lift_plan", False)]
    grasp = [m for m in world.moves if m.stage == "descent"][-1].waypoint
    rise = accepted.answer["waypoint"]["position_m"][2] - grasp.position_m[2]
    drag = 0.1 * LIFT_SUPPORT_M / rise
    assert failed_checks(refused)["drag_m"] == pytest.approx(drag)
    assert f"drag_m = {drag:.4g}, needs <= {TOL.lift_drag_m:.4g}" in refused.feedback
    assert gates_of(accepted) == [("lift_plan", True), ("sigma4_lift", True)]
    lifts = [m for m in world.moves if m.stage == "lift"]
    assert len(lifts) == 1 and lifts[0].waypoint.position_m == tuple(
        accepted.answer["waypoint"]["position_m"]
    )


def test_a_lift_faster_than_v_lift_is_refused_before_it_moves(world) -> None:
    no_duration = with_waypoint(lambda w: w.model_copy(update={"duration_s": None}))
    result = build(world, Scripted({"lift": [no_duration]}))
    assert_built(world, result)
    refused, accepted = calls(result, "lift")
    assert gates_of(refused) == [("lift_plan", False)]
    assert failed_checks(refused) == {"speed_mps": math.inf}  # as fast as the arm goes
    assert f"speed_mps = inf, needs <= {TOL.v_lift_mps:.4g}" in refused.feedback
    assert speed_of_lift(accepted) == pytest.approx(TOL.v_lift_mps)
    assert [m.stage for m in world.moves].count("lift") == 1


def test_a_lift_out_of_reach_is_asked_again(world) -> None:
    world.script("lift", out_of_reach())
    result = build(world)
    assert_built(world, result)
    refused, _ = calls(result, "lift")
    # Planned fine; the arm did not get there, which the controller's verdict records.
    assert gates_of(refused) == [("lift_plan", True), ("controller", False)]
    assert failed_checks(refused) == {"reachable": 0.0}
    assert refused.feedback.startswith(
        "controller failed: reachable = 0, needs >= 1; unreachable: pose ("
    )


def test_a_lift_never_in_reach_ends_the_trial_unreachable(world) -> None:
    world.script("lift", out_of_reach(), times=3)
    result = build(world)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("unreachable", "lift")
    assert world.held == 0  # still in the hand where it was grasped


def test_a_slip_in_the_lift_sets_the_brick_aside_and_grasps_it_again(world) -> None:
    world.script("lift", slips(speed_mps=0.02))
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    slipped, lifted = calls(result, "lift")
    assert slipped.outcome == "regrasp"
    assert failed_checks(slipped) == {"relative_speed_mps": 0.02}
    # Still sliding after the lift, it was held still for SETTLE_S before it was judged.
    hold = [m for m in world.moves if m.stage == "lift"][1]
    assert hold.waypoint.duration_s == SETTLE_S
    assert hold.waypoint.position_m == tuple(slipped.answer["waypoint"]["position_m"])
    again = result.transcript[result.transcript.index(slipped) + 1]
    assert (again.agent, again.answer["brick_id"]) == ("pre_grasp", 0)
    second = reasoner.asked("pre_grasp")[1]
    assert second.memory.regrasps == 1
    assert second.memory.last_feedback.startswith("sigma4_lift failed: relative_speed_mps = 0.02")
    # Set down flat on the nearest free ground: here, where it was grasped.
    back = second.state.brick(0)
    assert back.status == "in_pick_area"
    assert_set_aside(back, [*BRICKS[1:], world.goal.targets[0].pose])
    assert math.dist(back.pose.position_m, BRICKS[0].position_m) < 1e-3
    assert lifted.outcome == "accepted"


def test_a_slip_sets_the_brick_aside_clear_of_a_neighbour_not_where_it_was_grasped(
    kinematics, one_brick
) -> None:
    """Where it was grasped is too near another brick to set it down: it goes on the nearest
    free ground, not back where it was."""
    neighbour = beside(BRICKS[0], 0.05)
    world = FakeWorld(one_brick, [*BRICKS, neighbour], *kinematics)
    world.script("lift", slips())
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    assert [c.outcome for c in calls(result, "lift")] == ["regrasp", "accepted"]
    aside = reasoner.asked("pre_grasp")[1].state.brick(0)
    assert_set_aside(aside, [*BRICKS[1:], neighbour, one_brick.targets[0].pose])
    grasped_at = BRICKS[0].position_m
    assert 0.01 < math.dist(aside.pose.position_m, grasped_at) < 0.1  # moved, but near by
    assert [c.answer["brick_id"] for c in calls(result, "pre_grasp")] == [0, 0]


def test_a_slip_is_corrected_by_a_lift_at_half_the_speed(world) -> None:
    """sigma_4's correction: the refusal measured a slip and the lift's speed; the next lift
    of the brick is half as fast."""
    world.script("lift", slips(speed_mps=0.02))
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    slipped, lifted = calls(result, "lift")
    first = speed_of_lift(slipped)
    assert first == pytest.approx(TOL.v_lift_mps)
    (refusal,) = reasoner.asked("lift")[1].memory.refusals
    assert refusal.gate == "sigma4_lift"
    assert refusal.measured.slip_speed_mps == 0.02
    assert refusal.measured.move_speed_mps == pytest.approx(first)
    assert [c.name for c in refusal.failed] == ["relative_speed_mps"]
    assert speed_of_lift(lifted) == pytest.approx(first / 2)
    durations = [c.answer["waypoint"]["duration_s"] for c in (slipped, lifted)]
    assert durations[1] == pytest.approx(2 * durations[0])


def test_a_brick_still_swinging_after_the_lift_is_held_still_and_then_judged(world) -> None:
    world.script("lift", slips(speed_mps=0.02, settles=True))
    result = build(world)
    assert_built(world, result)
    (lifted,) = calls(result, "lift")
    assert gates_of(lifted) == [("lift_plan", True), ("sigma4_lift", True)]
    assert checked(lifted, "sigma4_lift")["relative_speed_mps"] == 0.0  # judged at rest
    lift, hold = [m for m in world.moves if m.stage == "lift"]
    assert hold.waypoint.position_m == lift.waypoint.position_m
    assert hold.waypoint.duration_s == SETTLE_S


def test_agents_shown_no_poses_get_a_brick_set_aside_where_the_top_down_picture_shows_it(
    kinematics, one_brick
) -> None:
    """A brick held at the top-down picture's far edge (y 0.60 m; the picture ends at
    0.625 m at a brick's top): blind to the pictures, the nearest free ground is where it
    is, half out of the picture; in sight, a spot whose footprint keeps SET_ASIDE_SLACK_M
    inside it, so that a landing off by that much still lies in the picture."""
    edge = Pose(position_m=(0.05, 0.60, 0.03), quat_xyzw=yaw_quat(0.3))
    world = FakeWorld(one_brick, [edge, *BRICKS[1:]], *kinematics)
    world.go(Pose(position_m=edge.position_m, quat_xyzw=top_down_quat(0.3)))
    world.ideal_grip(None)
    world.go(Pose(position_m=(0.05, 0.60, 0.2), quat_xyzw=top_down_quat(0.3)))
    state = world.observe(Progress(current_brick=0, step="lift"))
    calls = AgentCaller(world, BuiltinReasoner(), TOL, BuildResult())
    picture = Polygon(TOP_DOWN.view_at_height(SPEC.brick_size_m[2]))

    def footprint(spot: Pose) -> Polygon:
        return Box(spot.position_m, spot.quat_xyzw, SPEC.brick_size_m).footprint

    blind = PutDown(world, calls).free_spot(state, 0, 0, set(), 0.2)
    assert blind is not None and math.dist(blind.position_m[:2], edge.position_m[:2]) < 0.03
    assert not picture.contains(footprint(blind))
    seen = PutDown(world, calls, in_sight=True).free_spot(state, 0, 0, set(), 0.2)
    assert seen is not None
    assert picture.buffer(-SET_ASIDE_SLACK_M).contains(footprint(seen))


def test_slips_past_the_regrasp_budget_end_the_trial_as_grasp_slip(world) -> None:
    world.script("lift", slips(), times=math.inf)
    result = build(world, budgets=Budgets(regrasps=1))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("grasp_slip", "lift")
    lifts = calls(result, "lift")
    assert [c.outcome for c in lifts] == ["regrasp", "regrasp"]
    assert speed_of_lift(lifts[1]) == pytest.approx(speed_of_lift(lifts[0]) / 2)
    assert result.placements == {} and world.held is None


# --- Ag5 placement: the slot plan, re-grasp and sigma_5 raise-and-retry -------------------
def test_a_brick_rolled_in_the_hand_is_set_down_level_by_tilting_the_tool(world) -> None:
    world.script("placement", rolls(30.0))  # on the carry over the slot
    result = build(world)
    assert_built(world, result)  # level and exactly on its slot
    assert [c.outcome for c in calls(result, "placement")] == ["accepted", "accepted"]
    (set_down,) = [m for m in world.moves if m.stop_on_contact is not None]
    assert tilt_deg(set_down.waypoint.quat_xyzw) == pytest.approx(30.0)  # the tool tilted by it


@pytest.mark.parametrize("tier", list(ToolTier))
def test_a_brick_creeping_in_the_hand_is_set_down_for_its_roll_at_touch_down(
    world, tier: ToolTier
) -> None:
    """The brick rolls 3 deg/s about the pads' axis whenever the arm moves it: over the slot
    it is watched for ROLL_WATCH_S (memory.roll_watch: 0.75 deg more), and the set-down
    tilts the tool for the roll it will have at touch-down, 2 x duration_s later, which
    seats it exactly (sigma_5 measures nothing off)."""
    world.script("placement", creeps(3.0), times=math.inf)
    reasoner = Scripted()
    result = build(world, reasoner, tier=tier)
    assert_built(world, result)
    carry, set_down = reasoner.asked("placement")
    assert carry.memory.roll_watch is None
    watch = set_down.memory.roll_watch
    assert watch is not None
    assert watch.now_s - watch.before_s == pytest.approx(ROLL_WATCH_S)
    assert watch.now_deg - watch.before_deg == pytest.approx(3.0 * ROLL_WATCH_S, abs=0.01)
    assert "roll_watch" in set_down.prompt
    (down,) = [m for m in world.moves if m.stop_on_contact is not None]
    at_touch_down = watch.now_deg + 3.0 * 2 * down.waypoint.duration_s
    assert tilt_deg(down.waypoint.quat_xyzw) == pytest.approx(abs(at_touch_down), abs=0.02)
    (placed,) = [c for c in calls(result, "placement") if c.outcome == "accepted"][-1:]
    seat = checked(placed, "sigma5_placement")
    assert seat["e_xy_m"] < 1e-4 and seat["tilt_deg"] < 0.05


def test_a_brick_dragged_off_its_target_at_release_is_withdrawn_and_set_right(world) -> None:
    """The release leaves the brick 3 cm off its target (outside the success rule's 2 cm):
    sigma_6 judges it at rest after the return, withdraws it, and the next cycle picks that
    brick first and sets it right."""
    world.script("release", lets_go_off((0.03, 0.0)))
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    first, again = calls(result, "release")
    at_rest = checked(first, "sigma6_at_rest")
    assert at_rest["offset_m"] == pytest.approx(0.03)
    assert ("sigma6_at_rest", False) in gates_of(first)
    assert checked(again, "sigma6_at_rest")["offset_m"] < 1e-6
    dragged = result.placements[0]
    picks = [c.answer["brick_id"] for c in calls(result, "pre_grasp")]
    assert picks == [dragged, dragged]  # the withdrawn brick picked first
    (note,) = [r for r in reasoner.asked("pre_grasp")[1].memory.refusals]
    assert note.gate == "sigma6_at_rest" and "repair 1 of 2" in note.note


def test_a_brick_off_its_target_is_left_once_the_repairs_are_spent(world) -> None:
    world.script("release", lets_go_off((0.03, 0.0)), times=math.inf)
    result = build(world, budgets=Budgets(repairs=1))
    assert result.failure is None  # built, the brick left off: the success rule judges it
    assert [("sigma6_at_rest", False) in gates_of(c) for c in calls(result, "release")] == [
        True,
        True,
    ]


def test_a_placed_brick_knocked_off_is_found_by_sigma1_and_set_right(kinematics, wall) -> None:
    """Lifting the second brick knocks the first 3 cm off target 0: the third brick's
    sigma_1 re-measures the placed bricks, refuses Ag1's answer naming the knocked brick,
    which is picked again and set right before the top brick is built on it."""
    world = FakeWorld(wall, BRICKS, *kinematics)
    target = wall.targets[0].pose.position_m

    def on_target(world: FakeWorld) -> int | None:
        near = [
            i for i, b in enumerate(world.bricks) if math.dist(b.pose.position_m, target) < 1e-3
        ]
        return next((i for i in near if i != world.held), None)

    def knocks(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        knocked = on_target(world)
        assert knocked is not None
        world.push(knocked, (0.03, 0.0, 0.0))
        return world.ideal_move(waypoint, stop)

    world.script("lift", Deviation("move", knocks, only=lambda w, *_: on_target(w) is not None))
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    refused = [c for c in calls(result, "pre_grasp") if c.outcome == "refused"]
    assert len(refused) == 1
    assert checked(refused[0], "sigma1_placed")["offset_m"] == pytest.approx(0.03)
    assert "repair 1 of 2" in refused[0].feedback
    picks = [(c.answer["brick_id"], c.answer["target_index"]) for c in calls(result, "pre_grasp")]
    knocked = picks[0][0]  # the brick built first, on target 0
    # The third answer (target 2, on top) refused; then the knocked brick back on target 0.
    assert [target for _, target in picks] == [0, 1, 2, 0, 2]
    assert picks[3] == (knocked, 0)


def test_a_brick_fallen_flat_onto_the_build_is_picked_off_it_and_built(kinematics, wall) -> None:
    """When the second brick is let go, the last loose brick falls flat onto the first
    course, 3 cm off the top target: it is free (dropped, lying flat), so the next cycle
    picks it off the build and sets it on that target."""
    world = FakeWorld(wall, BRICKS, *kinematics)
    top = wall.targets[2].pose

    def loose(world: FakeWorld) -> int:
        """The brick furthest from every target."""
        return max(
            range(len(world.bricks)),
            key=lambda i: min(
                math.dist(world.bricks[i].pose.position_m, t.pose.position_m) for t in wall.targets
            ),
        )

    def falls_onto_the_build(world: FakeWorld, opening_m: float | None) -> None:
        world.ideal_grip(opening_m)
        x, y, z = top.position_m
        world.bricks[loose(world)].pose = Pose(position_m=(x + 0.03, y, z), quat_xyzw=top.quat_xyzw)

    released = []

    def second_release(world: FakeWorld, *_: object) -> bool:
        released.append(world.held)
        return len(released) == 2

    world.script("release", Deviation("open", falls_onto_the_build, only=second_release))
    result = build(world)
    assert_built(world, result)
    fallen = result.placements[2]
    assert calls(result, "pre_grasp")[-1].answer["brick_id"] == fallen


def test_a_brick_slid_so_far_its_slot_is_underground_is_grasped_again(world) -> None:
    """On the carry the brick slides 12 cm up the pads: the slot that would set it on its
    target puts the tool below the ground, so Ag5 asks for a re-grasp rather than
    answering a pose outside the workspace; grasped again, it is built."""

    def slides_up(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        done = world.ideal_move(waypoint, stop)
        world.turn_in_hand(Rotation.identity(), (0.0, 0.0, -0.12))
        return done

    world.script("placement", Deviation("move", slides_up, only=lambda w, *_: w.held is not None))
    result = build(world)
    assert_built(world, result)
    asked = [c for c in calls(result, "placement") if c.outcome == "regrasp"]
    assert len(asked) == 1 and "outside the workspace" in asked[0].answer["rationale"]
    assert not [c for c in result.transcript if c.outcome == "refused"]


def test_the_check_tiers_grasp_checks_leave_the_brick_out_as_sigma1_does(world, one_brick) -> None:
    """Agent 1's checks in the check tier measure what grasp_options and sigma_1 measure:
    the brick to be grasped is no obstacle to the approach or to the way down."""
    result = build(world, Scripted(), tier=ToolTier.CHECK)
    assert_built(world, result)
    pick = calls(result, "pre_grasp")[0]
    approach, descent, place = pick.tool_calls
    assert (approach.name, descent.name, place.name) == (
        "collision_check",
        "collision_check",
        "reachability",
    )
    brick = pick.answer["brick_id"]
    assert approach.arguments["ignore_brick_id"] == descent.arguments["ignore_brick_id"] == brick


@pytest.mark.parametrize("tier", [ToolTier.CHECK, ToolTier.NONE])
def test_without_placement_pose_the_plans_refusal_of_the_way_asks_for_the_regrasp(
    world, one_brick, tier: ToolTier
) -> None:
    """In the check and none tiers Ag5 composes the slot itself: the placement plan refuses
    its way, and the next answer asks for the re-grasp; then the brick is built."""
    world.script("placement", rolls(85.0))
    reasoner = Scripted()
    result = build(world, reasoner, tier=tier)
    assert_built(world, result)
    placement = calls(result, "placement")
    refused = next(c for c in placement if c.outcome == "refused")
    assert refused.feedback.startswith("placement_plan") and "way_" in refused.feedback
    (asked,) = [c for c in result.transcript if c.outcome == "regrasp"]
    assert asked.answer["regrasp"] is True and asked.call > refused.call


def test_a_brick_rolled_too_far_to_set_down_is_set_aside_and_grasped_again(
    world, one_brick
) -> None:
    """In the solve tier placement_pose finds no clear way: Ag5 asks for a re-grasp."""
    world.script("placement", rolls(85.0))  # on the carry over the slot
    reasoner = Scripted()
    result = build(world, reasoner, tier=ToolTier.SOLVE)
    assert_built(world, result)
    (asked,) = [c for c in result.transcript if c.outcome == "regrasp"]
    assert asked.agent == "placement" and asked.answer["regrasp"] is True
    assert asked.feedback.startswith("placement_regrasp; placement asked for a re-grasp: ")
    assert "rolled 85.0 deg" in asked.feedback and "tilt_deg=+85" in asked.feedback
    second = reasoner.asked("pre_grasp")[1]
    assert second.memory.regrasps == 1 and second.memory.last_feedback == asked.feedback
    (refusal,) = second.memory.refusals
    assert (refusal.gate, refusal.measured.tilt_deg) == ("placement_regrasp", pytest.approx(85.0))
    # Set down level on free ground near by, clear of the target, and grasped from there.
    aside = second.state.brick(0)
    assert aside.status == "dropped"
    assert_set_aside(aside, [*BRICKS[1:], one_brick.targets[0].pose])
    assert calls(result, "pre_grasp")[1].answer["brick_id"] == 0


def test_a_misaligned_set_down_is_raised_and_placed_again(world) -> None:
    world.script("placement", lands_off((0.012, 0.0, 0.0)), times=math.inf)
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    carry, raised, corrected = calls(result, "placement")
    assert [carry.outcome, raised.outcome, corrected.outcome] == ["accepted", "raised", "accepted"]
    assert failed_checks(raised) == {"e_xy_m": pytest.approx(0.012)}
    assert raised.feedback.startswith(
        f"sigma5_placement failed: e_xy_m = 0.012, needs <= {TOL.eps_xy_m:.4g}; "
    )
    assert reasoner.asked("placement")[2].memory.last_feedback == raised.feedback
    # Raised straight up by delta_h from where it touched down, still held.
    guarded = next(i for i, m in enumerate(world.moves) if m.stop_on_contact is not None)
    touched, up = world.moves[guarded].waypoint, world.moves[guarded + 1].waypoint
    assert up.path == "linear"
    assert up.position_m[2] - touched.position_m[2] == pytest.approx(TOL.delta_h_m)
    assert "the set-down stopped on contact with the tool at z = " in raised.feedback


def test_a_set_down_that_lands_off_is_corrected_by_the_feedback(world, one_brick) -> None:
    """sigma_5's correction: every set-down slides the brick 12 mm and turns it 3.5 deg as it
    touches down (past eps_xy and eps_theta, seated); the next slot is shifted and turned
    by the measured miss, and the brick lands on its target."""
    world.script("placement", lands_off((0.008, -0.009, 0.0), turn_deg=3.5), times=math.inf)
    reasoner = Scripted()
    result = build(world, reasoner)
    assert_built(world, result)
    carry, raised, corrected = calls(result, "placement")
    assert [c.outcome for c in (carry, raised, corrected)] == ["accepted", "raised", "accepted"]
    assert set(failed_checks(raised)) == {"e_xy_m", "e_theta_deg"}
    asked = reasoner.asked("placement")[2]
    (refusal,) = asked.memory.refusals
    miss = refusal.measured
    assert refusal.gate == "sigma5_placement"
    assert (miss.e_x_m, miss.e_y_m, miss.e_theta_deg) == pytest.approx((-0.008, 0.009, -3.5))
    assert abs(miss.d_perp_m) <= TOL.eps_perp_m and miss.tilt_deg <= TOL.eps_tilt_deg  # seated
    # The corrected slot sets the brick, as it sits in the hand, off its target by the miss:
    # the slide at touch-down then carries it on to the target.
    slot = corrected.answer["waypoint"]
    tool = Pose(position_m=tuple(slot["position_m"]), quat_xyzw=tuple(slot["quat_xyzw"]))
    target = one_brick.targets[0]
    held = formulas.in_hand(asked.state.robot.ee_pose, asked.state.brick(0).pose)
    predicted = alignment_of(formulas.carried(tool, *held), one_brick.brick_size_m, target)
    assert predicted.e_xy_m == pytest.approx((-miss.e_x_m, -miss.e_y_m), abs=1e-9)
    assert predicted.e_theta_deg == pytest.approx(-miss.e_theta_deg, abs=1e-9)
    assert checked(corrected, "sigma5_placement")["e_xy_m"] < 1e-9


def test_a_set_down_that_met_no_support_says_so(world) -> None:
    landed = lands_off((0.012, 0.0, 0.0))

    def no_touch(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        return replace(landed.apply(world, waypoint, stop), stopped_on_contact=False)

    world.script("placement", Deviation("move", no_touch, only=landed.only), times=math.inf)
    result = build(world, Scripted())
    assert_built(world, result)
    raised = calls(result, "placement")[1]
    assert raised.outcome == "raised"
    assert "the set-down ran all the way to the slot" in raised.feedback
    assert "stopped on contact" not in raised.feedback


def test_set_downs_that_never_seat_end_the_trial_misaligned(world) -> None:
    world.script("placement", lands_off((0.0, 0.0, 0.0), tilt_deg=4.0), times=math.inf)
    result = build(world)
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("placement_misaligned", "placement")
    assert f"tilt_deg = 4, needs <= {TOL.eps_tilt_deg:.4g}" in result.failure.detail
    placements = calls(result, "placement")
    assert [c.outcome for c in placements] == ["accepted"] + [
        "raised"
    ] * Budgets().placement_attempts
    # A miss that did not seat is no offset to correct by: every slot is the same.
    slots = {tuple(c.answer["waypoint"]["position_m"]) for c in placements[1:]}
    assert len(slots) == 1


# --- the plans checked before a move: a refusal's errors point to the answer that passes --
#: (agent, change of its first answer, the plan gate, its failed checks, the refusal's
#: e_x_m, e_y_m, e_theta_deg)
PLANS = {
    # Off the brick's centre by 5 mm, which the descent corrects; turned 3 deg, which a
    # descent that keeps the orientation would grip with.
    "approach off the brick and turned": (
        "pre_grasp",
        shifted(0.005, -0.003, turn_deg=3.0),
        "pre_grasp_plan",
        {"grip_yaw_deg"},
        (-0.005, 0.003, -3.0),
    ),
    "descent off along the brick": (
        "descent",
        along_brick(0.004),
        "descent_plan",
        {"grip_offset_m"},
        along_error(-0.004),
    ),
    "lift that drifts": (
        "lift",
        shifted(0.1, 0.0),
        "lift_plan",
        {"drag_m", "speed_mps"},  # the drift makes the move longer, hence faster
        (-0.1, 0.0, None),
    ),
    "slot off its target": (
        "placement",
        shifted(0.03, 0.0),
        "placement_plan",
        {"predicted_offset_m"},
        (-0.03, 0.0, 0.0),
    ),
    "slot turned off its target": (
        "placement",
        shifted(0.0, 0.0, turn_deg=6.0),
        "placement_plan",
        {"predicted_rotation_deg"},
        (0.0, 0.0, -6.0),
    ),
}


@pytest.mark.parametrize("case", sorted(PLANS))
def test_a_plan_refused_before_it_moves_points_to_the_answer_that_passes(world, case) -> None:
    agent, change, gate, checks, errors = PLANS[case]
    reasoner = Scripted({agent: [change]})
    result = build(world, reasoner)
    assert_built(world, result)
    refused, accepted = calls(result, agent)[:2]
    assert refused.outcome == "refused" and accepted.outcome == "accepted"
    assert refused.gates[-1].gate == gate and set(failed_checks(refused)) == checks
    assert all(g.passed for g in accepted.gates)
    (refusal,) = reasoner.asked(agent)[1].memory.refusals
    assert (refusal.agent, refusal.gate) == (agent, gate)
    assert refusal.text() == refused.feedback
    e_x, e_y, e_theta = errors
    miss = refusal.measured
    assert (miss.e_x_m, miss.e_y_m) == pytest.approx((e_x, e_y), abs=1e-9)
    assert miss.e_theta_deg == (None if e_theta is None else pytest.approx(e_theta, abs=1e-9))
    # The next answer is the refused one moved by the refusal's errors ...
    moved_by = (xy(accepted)[0] - xy(refused)[0], xy(accepted)[1] - xy(refused)[1])
    assert moved_by == pytest.approx((e_x, e_y), abs=1e-9)
    turn = turned_deg(yaw_deg(accepted), yaw_deg(refused))
    assert turn == pytest.approx(e_theta or 0.0, abs=1e-9)
    # ... and the refused one never moved the arm.
    refused_pose = (xy(refused), refused.answer["waypoint"]["quat_xyzw"])
    assert all(
        (m.waypoint.position_m[:2], list(m.waypoint.quat_xyzw))
        != (pytest.approx(refused_pose[0]), pytest.approx(refused_pose[1]))
        for m in world.moves
    )


# --- Ag6 release: the release plan and sigma_6 --------------------------------------------
INTO_GROUND = with_waypoint(lambda w: w.model_copy(update={"position_m": (0.6, -0.2, 0.005)}))
WIDE_OPEN = lambda answer: answer.model_copy(update={"gripper_opening_m": GRIPPER_GAP_M[1]})  # noqa: E731
NARROW = lambda a: a.model_copy(update={"gripper_opening_m": SPEC.brick_size_m[1] - 0.005})  # noqa: E731
#: (change of the release, the verdicts of the refused answer, its first failed check)
BAD_RELEASES = {
    "a return into the ground": (
        INTO_GROUND,
        [("release_plan", True), ("sigma6_return", False)],
        "return_clearance_m",
    ),
    "an opening narrower than the brick": (NARROW, [("release_plan", False)], "opening_m"),
}


@pytest.mark.parametrize("case", sorted(BAD_RELEASES))
def test_a_bad_release_is_refused_before_the_gripper_opens(world, case: str) -> None:
    change, verdicts, check = BAD_RELEASES[case]
    result = build(world, Scripted({"release": [change]}))
    assert_built(world, result)
    refused, accepted = calls(result, "release")
    assert gates_of(refused) == verdicts
    assert check in failed_checks(refused)
    assert f"failed: {check} = " in refused.feedback
    assert gates_of(accepted) == [
        ("release_plan", True),
        ("sigma6_return", True),
        ("sigma6_at_rest", True),
    ]
    assert [m.stage for m in world.moves].count("release") == 2  # the accepted one's


def test_a_release_refused_every_time_keeps_the_brick_in_the_hand(world) -> None:
    result = build(world, Scripted({"release": [NARROW] * 3}))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("invalid_output", "release")
    assert world.held == 0 and result.placements == {}


@pytest.fixture
def crowded(kinematics, one_brick) -> FakeWorld:
    """The one-brick world with another brick lying 3 cm beside the target, across its width:
    a gripper opened wide puts a finger in it on the way up."""
    return FakeWorld(one_brick, [*BRICKS, beside(one_brick.targets[0].pose, 0.03)], *kinematics)


def test_a_release_opened_into_a_neighbour_is_refused_by_sigma6_and_asked_again(crowded) -> None:
    result = build(crowded, Scripted({"release": [WIDE_OPEN]}))
    assert_built(crowded, result)
    refused, accepted = calls(result, "release")
    assert gates_of(refused) == [("release_plan", True), ("sigma6_return", False)]
    assert failed_checks(refused).keys() == {"retreat_clearance_m"}
    assert failed_checks(refused)["retreat_clearance_m"] < 0.0
    assert "closest: gripper_finger_left vs brick 3" in refused.feedback
    assert "return_clearance_m" not in refused.feedback
    assert gates_of(accepted) == [
        ("release_plan", True),
        ("sigma6_return", True),
        ("sigma6_at_rest", True),
    ]


def test_a_return_refused_every_time_keeps_the_brick_in_the_hand(crowded) -> None:
    result = build(crowded, Scripted({"release": [WIDE_OPEN] * 3}))
    assert result.failure is not None
    assert (result.failure.reason, result.failure.agent) == ("collision", "release")
    assert crowded.held == 0 and result.placements == {}
    assert all(failed_checks(c).keys() == {"retreat_clearance_m"} for c in calls(result, "release"))


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


# --- every agent: an answer that leaves a decision field out ----------------------------
#: An in-process answer that leaves out what its decision needs, and the refusal it gets:
#: the words the schema refuses a model's answer with (test_validation.py).
INCOMPLETE = {
    "descent": (
        DescentAnswer(gripper_opening_m=0.13),
        "the answer needs gripper_opening_m, waypoint; missing: waypoint",
    ),
    "lift": (LiftAnswer(), "the answer needs waypoint; missing: waypoint"),
    "placement": (PlacementAnswer(), "the answer needs waypoint; missing: waypoint"),
    "release": (
        ReleaseAnswer(waypoint=READY),
        "the answer needs gripper_opening_m, waypoint; missing: gripper_opening_m",
    ),
}


@pytest.mark.parametrize("agent", sorted(INCOMPLETE))
def test_an_incomplete_answer_is_refused_before_it_acts_and_asked_again(
    kinematics, one_brick, agent: str
) -> None:
    answer, message = INCOMPLETE[agent]
    clean = FakeWorld(one_brick, BRICKS, *kinematics)
    assert_built(clean, build(clean))
    world = FakeWorld(one_brick, BRICKS, *kinematics)
    result = build(world, Scripted({agent: [answer]}))
    assert_built(world, result)
    refused, accepted = calls(result, agent)[:2]
    assert (refused.outcome, accepted.outcome) == ("refused", "accepted")
    assert refused.caught_by == f"{agent}_answer:answer_complete"
    assert refused.category == "schema"
    assert refused.feedback == f"{agent}_answer failed: answer_complete = 0, needs >= 1; {message}"
    assert gates_of(refused) == [(f"{agent}_answer", False)]
    # Nothing moved for the refused answer: the arm made the moves of a build without it.
    assert [(m.stage, m.waypoint) for m in world.moves] == [
        (m.stage, m.waypoint) for m in clean.moves
    ]


def test_a_brick_rolled_past_its_end_is_set_aside_level_by_tilting_the_tool(
    world, one_brick
) -> None:
    """Rolled 76 deg, past atan(length / height) = 73 deg, a full brick pressed down would tip
    onto its end: it is laid level instead, the tool tilted by its roll, down until it
    touches, and grasped again from where it lies flat."""
    world.script("placement", rolls(76.0))  # on the carry over the slot
    result = build(world, Scripted(), tier=ToolTier.SOLVE)
    assert_built(world, result)
    assert [c.outcome for c in calls(result, "placement")][:2] == ["accepted", "regrasp"]
    guarded = [m for m in world.moves if m.stage == "placement" and m.stop_on_contact == 0]
    laid, set_down = guarded  # the set-aside, then the set-down of the brick grasped again
    assert tilt_deg(set_down.waypoint.quat_xyzw) < 0.1
    assert tilt_deg(laid.waypoint.quat_xyzw) == pytest.approx(76.0, abs=0.5)
    assert laid.motion.stopped_on_contact
    again = calls(result, "pre_grasp")[1].answer["waypoint"]["position_m"]
    assert math.dist(again[:2], laid.waypoint.position_m[:2]) < SET_ASIDE_SLACK_M


#: A tool tilted 36 deg for a rolled brick over the far end of a four-course wall's top
#: course: the arm reaches it up to z = 0.34 m there, not at the carry height of 0.36 m.
FAR_TILTED = (0.8702481588564857, -0.37245897211367085, 0.24242924210386194, 0.2125335706938361)
#: The same tool tilted 21 deg, as it was carried there (reached at 0.36 m).
CARRIED_TILTED = (
    -0.8941737038487976,
    0.4078285492445622,
    -0.14082004539942924,
    -0.1195783282208835,
)


def test_a_set_down_hover_out_of_reach_at_the_carry_height_steps_down_to_where_it_reaches(
    world,
) -> None:
    """The tool carried at 0.36 m over a slot it can only reach tilted lower down: the set-down
    starts HOVER_STEP_M steps lower, at the highest height the arm reaches."""
    world.go(Pose(position_m=(0.2025, 0.659, 0.36), quat_xyzw=CARRIED_TILTED))
    orchestrator = Orchestrator(world, Scripted())
    state = world.observe(Progress(current_brick=0, step="placement"))
    slot = WaypointProposal(position_m=(0.2014, 0.6642, 0.2374), quat_xyzw=FAR_TILTED)
    above, way = orchestrator._hover(state, slot, path="linear")
    x, y, z = above.position_m
    assert way.reachable and (x, y) == (0.2014, 0.6642)
    assert 0.2374 < z < 0.36 and z == pytest.approx(
        0.36 - HOVER_STEP_M * round((0.36 - z) / HOVER_STEP_M)
    )
    higher = above.model_copy(update={"position_m": (x, y, z + HOVER_STEP_M)})
    assert not orchestrator._clearance(state, higher, start=state.robot.ee_pose).reachable


def test_a_brick_that_falls_out_at_the_set_down_is_grasped_again_where_it_lies(
    world, one_brick
) -> None:
    """sigma_5 raises the tool without the brick: Ag5 is not asked again for a brick the
    pads no longer hold; it is left where it fell and grasped again from there."""
    world.script("placement", falls_out((0.03, 0.0, 0.0)))
    reasoner = Scripted()
    result = build(world, reasoner, tier=ToolTier.CHECK)
    assert_built(world, result)
    raised = [c for c in calls(result, "placement") if c.outcome == "raised"]
    assert len(raised) == 1 and raised[0].feedback.startswith("sigma5_placement failed")
    second = reasoner.asked("pre_grasp")[1]
    assert second.memory.regrasps == 1
    assert second.memory.refusals[-1].gate == "placement_regrasp"
    assert "left the hand on the set-down" in second.memory.refusals[-1].note
    assert second.state.brick(0).status == "dropped"
    assert calls(result, "pre_grasp")[1].answer["brick_id"] == 0
