"""The gated orchestrator with the built-in reasoner, in the real simulator."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
from scipy.spatial.transform import Rotation

from actionreasoning.agents.memory import PlacementPhase
from actionreasoning.agents.orchestrator import Orchestrator
from actionreasoning.agents.outputs import PlacementAnswer, PreGraspAnswer
from actionreasoning.agents.put_down import SET_ASIDE_MARGIN_M, SET_ASIDE_RANGE_M, levelled_offset
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.agents.view import target_supports
from actionreasoning.control.waypoint import WaypointController
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.metrics import center_offset_cm
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.trial.sim_world import SimWorld
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import top_down_quat
from actionreasoning.world.models import READY_POSE, Pose
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scene_spec import ReachBand, SceneSpec
from actionreasoning.world.tolerances import Tolerances


@pytest.fixture
def small_goal(small_pattern: Path):
    return load_pattern(small_pattern, SceneSpec())


@dataclass
class Scripted:
    """Answers pre-grasp with scripted answers first, then like the built-in reasoner."""

    pre_grasp: list[PreGraspAnswer]
    name: str = "scripted"
    builtin: BuiltinReasoner = field(default_factory=lambda: BuiltinReasoner())
    requests: list[AgentRequest] = field(default_factory=list)

    def decide(self, request: AgentRequest) -> AgentReply:
        self.requests.append(request)
        if request.spec.key == "pre_grasp" and self.pre_grasp:
            return AgentReply(answer=self.pre_grasp.pop(0))
        return self.builtin.decide(request)


def build(goal, reasoner, world=SimWorld, before=None):
    # Precise physics: the paths under test (refusal, re-grasp, raise) are caused on purpose,
    # in a world where nothing else slips.
    spec = TrialSpec(
        method=Method.AGENTS,
        pattern_name="small",
        goal=goal,
        run_seed=4,
        trial=0,
        config=TrialConfig(physics=PRECISE),
    )
    with trial_world(spec) as made:
        scene = made.scene
        controller = WaypointController(scene, made.arm)
        if before is not None:
            before(scene)
        result = Orchestrator(world(controller, goal, made.sensor), reasoner).build(goal)
        scene.step(scene.ticks_for(1.0))
        final = [scene.brick_pose(i)[0] for i in range(len(scene.bricks))]
    return result, final


def test_supports_of_the_goal() -> None:
    goal = load_pattern("pyramid", SceneSpec())
    assert target_supports(goal) == {0: (), 1: (), 2: (), 3: (0, 1), 4: (1, 2), 5: (3, 4)}


@pytest.mark.slow
def test_a_refused_target_gets_feedback_and_the_wall_is_built(small_goal) -> None:
    too_early = PreGraspAnswer(brick_id=0, target_index=2, waypoint=READY_POSE.model_dump())
    reasoner = Scripted(pre_grasp=[too_early])
    result, final = build(small_goal, reasoner)
    assert result.failure is None
    assert sorted(result.placements) == [0, 1, 2]
    assert result.decisions == 3 * 7 + 1  # Ag5 twice per brick, one refused pre-grasp
    refused = result.transcript[0]
    assert [(g.gate, g.passed) for g in refused.gates] == [("pre_grasp_choice", False)]
    retried = [r for r in reasoner.requests if r.spec.key == "pre_grasp"][1]
    assert retried.memory.last_feedback == (
        "pre_grasp_choice failed: target_buildable = 0, needs >= 1; "
        "target 2 rests on targets [0, 1], not built yet"
    )
    assert [r.gate for r in retried.memory.refusals] == ["pre_grasp_choice"]
    for target, brick in result.placements.items():
        assert center_offset_cm(final[brick], small_goal.targets[target].pose.position_m) < 0.1


@pytest.mark.slow
def test_a_spent_budget_is_a_typed_failure(small_goal) -> None:
    unbuilt = PreGraspAnswer(brick_id=0, target_index=2, waypoint=READY_POSE.model_dump())
    reasoner = Scripted(pre_grasp=[unbuilt] * 3)
    result, _ = build(small_goal, reasoner)
    assert result.failure is not None
    assert result.failure.reason == "invalid_choice"
    assert result.failure.agent == "pre_grasp"
    assert "target 2 rests on targets [0, 1], not built yet" in result.failure.detail
    assert result.placements == {}


SNAG_MASS_KG = 40.0


class SnaggedFirstLift(SimWorld):
    """The first brick grasped weighs 40 kg until the gripper lets go of it: it must slip."""

    snagged: int | None = None
    done = False

    def grip(self, opening_m: float | None) -> None:
        scene = self.controller.scene
        if opening_m is None and self.snagged is None:
            tcp = scene.tcp_pose()[0]
            self.snagged = min(
                range(len(scene.bricks)), key=lambda i: math.dist(scene.brick_pose(i)[0], tcp)
            )
            self._set_mass(SNAG_MASS_KG)
        elif opening_m is not None and self.snagged is not None and not self.done:
            self._set_mass(scene.spec.brick_mass_kg)
            self.done = True
        super().grip(opening_m)

    def _set_mass(self, mass_kg: float) -> None:
        scene = self.controller.scene
        brick = scene.bricks[self.snagged]
        p.changeDynamics(brick, -1, mass=mass_kg, physicsClientId=scene.client)


@pytest.mark.slow
def test_a_slip_in_the_lift_sets_the_brick_down_and_grasps_it_again_lifting_slower(
    small_goal,
) -> None:
    reasoner = Scripted(pre_grasp=[])
    result, final = build(small_goal, reasoner, world=SnaggedFirstLift)
    assert result.failure is None, result.failure
    lifts = [call for call in result.transcript if call.agent == "lift"]
    slipped, *others = lifts
    assert slipped.outcome == "regrasp"
    plan, sigma4 = slipped.gates
    assert (plan.gate, plan.passed, sigma4.gate) == ("lift_plan", True, "sigma4_lift")
    failed = {check.name: check.value for check in sigma4.checks if not check.passed}
    assert failed  # a 40 kg brick is not held: too little pad force for it, or it slides
    assert all(call.outcome == "accepted" for call in others)
    # The re-grasp starts at Ag1 with sigma_4's feedback, and the same brick is picked up.
    again = result.transcript[result.transcript.index(slipped) + 1]
    assert again.agent == "pre_grasp"
    assert again.answer["brick_id"] == slipped.brick
    pre_grasps = [r for r in reasoner.requests if r.spec.key == "pre_grasp"]
    assert pre_grasps[1].memory.last_feedback.startswith("sigma4_lift failed: ")
    assert any(name in pre_grasps[1].memory.last_feedback for name in failed)
    # Set down on free ground near the tool, where it can be grasped again.
    aside = pre_grasps[1].state.brick(slipped.brick)
    band = ReachBand()
    assert aside.pickable
    assert band.min_radius_m <= math.hypot(*aside.pose.position_m[:2]) <= band.max_radius_m
    # The refusal measured a slip and the lift's speed: the next lift of the brick is half
    # as fast.
    (refusal,) = pre_grasps[1].memory.refusals
    assert refusal.measured.move_speed_mps == pytest.approx(_lift_speed(slipped))
    relifted = next(c for c in others if c.brick == slipped.brick)
    # (its duration is rounded up to whole 10 ms, hence rel)
    assert _lift_speed(relifted) == pytest.approx(_lift_speed(slipped) / 2, rel=1e-3)
    for target, brick in result.placements.items():
        assert center_offset_cm(final[brick], small_goal.targets[target].pose.position_m) < 0.1


def _lift_speed(call) -> float:
    """The mean speed of a lift answer, as the lift's plan measured it."""
    (plan,) = [g for g in call.gates if g.gate == "lift_plan"]
    return next(c.value for c in plan.checks if c.name == "speed_mps")


#: How far off its slot every set-down of the first brick is answered: past eps_xy, within
#: the success rule (the slot's plan passes it).
MISPLACED_M = 0.014


@dataclass
class MisplacesFirstBrick(Scripted):
    """Answers every set-down of the first brick MISPLACED_M off (along x) the built-in
    reasoner's slot: a bias the built-in's correction by sigma_5's miss must take out."""

    def decide(self, request: AgentRequest) -> AgentReply:
        reply = super().decide(request)
        first_brick = not request.memory.placed
        if first_brick and request.memory.phase == PlacementPhase.SET_DOWN:
            x, y, z = reply.answer.waypoint.position_m
            moved = (x + MISPLACED_M, y, z)
            waypoint = reply.answer.waypoint.model_copy(update={"position_m": moved})
            return AgentReply(answer=reply.answer.model_copy(update={"waypoint": waypoint}))
        return reply


@pytest.mark.slow
def test_a_misaligned_set_down_is_raised_and_placed_again(small_goal) -> None:
    reasoner = MisplacesFirstBrick(pre_grasp=[])
    result, final = build(small_goal, reasoner)
    assert result.failure is None, result.failure
    placements = [call for call in result.transcript if call.agent == "placement"]
    carry, misplaced, corrected = placements[:3]
    assert [carry.outcome, misplaced.outcome, corrected.outcome] == [
        "accepted",
        "raised",
        "accepted",
    ]
    plan, sigma5 = misplaced.gates
    assert (plan.gate, plan.passed, sigma5.gate, sigma5.passed) == (
        "placement_plan",
        True,
        "sigma5_placement",
        False,
    )
    measured = {check.name: check.value for check in sigma5.checks}
    tol = Tolerances().for_goal(small_goal)
    assert tol.eps_xy_m < measured["e_xy_m"] < MISPLACED_M + 0.002
    assert f"e_xy_m = {measured['e_xy_m']:.4g}, needs <= {tol.eps_xy_m:.4g}" in misplaced.feedback
    # Off its slot, the brick comes down on the ground beside its seat: nothing stops it.
    assert (
        "; the set-down ran all the way to the slot: the brick met no support that stopped it"
        in misplaced.feedback
    )
    requests = [r for r in reasoner.requests if r.spec.key == "placement"]
    assert requests[2].memory.last_feedback == misplaced.feedback
    # The next slot is shifted by the miss sigma_5 measured (wanted minus measured): with the
    # same bias on it, the brick lands on its target.
    (miss,) = [r.measured for r in requests[2].memory.refusals]
    assert miss.e_x_m == pytest.approx(-MISPLACED_M, abs=0.002)
    first, second = (c.answer["waypoint"]["position_m"] for c in (misplaced, corrected))
    assert second[0] - first[0] == pytest.approx(miss.e_x_m, abs=0.002)
    assert corrected.gates[-1].gate == "sigma5_placement" and corrected.gates[-1].passed
    for target, brick in result.placements.items():
        assert center_offset_cm(final[brick], small_goal.targets[target].pose.position_m) < 0.1


@dataclass
class RegraspsAtFirstSetDown(Scripted):
    """Asks for a re-grasp at the first set-down, then answers like the built-in reasoner."""

    asked: bool = False

    def decide(self, request: AgentRequest) -> AgentReply:
        first_set_down = request.memory.phase == PlacementPhase.SET_DOWN
        if first_set_down and not self.asked:
            self.asked = True
            self.requests.append(request)
            return AgentReply(answer=PlacementAnswer(regrasp=True, rationale="rolled in the hand"))
        return super().decide(request)


@pytest.mark.slow
def test_placement_can_ask_for_a_regrasp_and_the_brick_is_grasped_again(small_goal) -> None:
    reasoner = RegraspsAtFirstSetDown(pre_grasp=[])
    result, final = build(small_goal, reasoner)
    assert result.failure is None, result.failure
    (asked,) = [call for call in result.transcript if call.outcome == "regrasp"]
    assert asked.agent == "placement"
    assert asked.feedback.startswith("placement_regrasp; placement asked for a re-grasp: ")
    # Set aside on the ground near its slot, clear of the other bricks and targets (outside
    # the pick area, hence "dropped"): Ag1 picks the same brick again from there.
    again = result.transcript[result.transcript.index(asked) + 1]
    assert again.agent == "pre_grasp"
    assert again.answer["brick_id"] == asked.brick
    pre_grasps = [r for r in reasoner.requests if r.spec.key == "pre_grasp"]
    assert pre_grasps[1].memory.last_feedback == asked.feedback
    # The agents know this is a re-grasp; nothing slipped, so the built-in one lifts at
    # v_lift again (it halves the speed for a slip only).
    assert [r.memory.regrasps for r in pre_grasps[:2]] == [0, 1]
    assert [r.gate for r in pre_grasps[1].memory.refusals] == ["placement_regrasp"]
    lifts = [c for c in result.transcript if c.agent == "lift" and c.target == asked.target]
    speeds = [_lift_speed(c) for c in lifts[:2]]
    # (durations are rounded up to whole 10 ms, hence rel)
    assert speeds == pytest.approx([Tolerances().v_lift_mps] * 2, rel=1e-3)
    aside = pre_grasps[1].state.brick(asked.brick)
    assert aside.status == "dropped" and aside.pickable
    slot = small_goal.targets[asked.target].pose.position_m
    assert center_offset_cm(aside.pose.position_m, slot) < 100 * (SET_ASIDE_RANGE_M + 0.05)
    footprint = Box(aside.pose.position_m, aside.pose.quat_xyzw, aside.size_m).footprint
    for target in small_goal.targets:
        taken = Box(target.pose.position_m, target.pose.quat_xyzw, target.size_m).footprint
        assert footprint.distance(taken) > SET_ASIDE_MARGIN_M / 2
    for target, brick in result.placements.items():
        assert center_offset_cm(final[brick], small_goal.targets[target].pose.position_m) < 0.1


def _lay(brick: int, position, euler_rad):
    """A scene hook that puts ``brick`` at rest at ``position``, turned by ``euler_rad``."""

    def lay(scene) -> None:
        quat = p.getQuaternionFromEuler(euler_rad)
        p.resetBasePositionAndOrientation(
            scene.bricks[brick], position, quat, physicsClientId=scene.client
        )
        scene.step(scene.ticks_for(0.5))

    return lay


@pytest.fixture
def one_brick_goal(small_goal):
    return small_goal.model_copy(update={"targets": small_goal.targets[:1]})


@pytest.mark.slow
def test_a_brick_dropped_flat_outside_the_pick_area_is_picked_from_there(one_brick_goal) -> None:
    reasoner = Scripted(pre_grasp=[])
    dropped = _lay(0, (0.55, 0.0, 0.03), (0.0, 0.0, 0.4))
    result, final = build(one_brick_goal, reasoner, before=dropped)
    assert result.failure is None, result.failure
    (first, *_) = [r for r in reasoner.requests if r.spec.key == "pre_grasp"]
    assert first.state.brick(0).status == "dropped"
    slot = one_brick_goal.targets[0].pose.position_m
    assert center_offset_cm(final[0], slot) < 0.1


@pytest.mark.slow
def test_a_toppled_last_brick_ends_the_trial_with_no_brick_left(one_brick_goal) -> None:
    on_its_side = _lay(0, (0.3, -0.45, 0.0475), (math.pi / 2, 0.0, 0.0))
    result, _ = build(one_brick_goal, Scripted(pre_grasp=[]), before=on_its_side)
    assert result.failure is not None
    assert result.failure.reason == "no_brick_left"
    assert "brick 0 toppled" in result.failure.detail
    assert result.transcript == []


def test_a_brick_rolled_about_the_pads_is_levelled_about_the_tool_centre_point() -> None:
    tool_rot = Rotation.from_quat(top_down_quat(0.3))
    tool = Pose(position_m=(0.5, -0.2, 0.3), quat_xyzw=tuple(tool_rot.as_quat()))
    flat_offset = np.array([0.02, -0.003, 0.012])  # where the brick sat in the hand, level
    flat_in_hand = tool_rot.inv() * Rotation.from_euler("z", 0.3)
    for roll_deg in (-60.0, 25.0, 89.0, 150.0):  # 150: flat again, on the other face
        roll = Rotation.from_euler("y", roll_deg, degrees=True)  # about the pad axis
        centre = tool_rot.apply(roll.apply(flat_offset)) + tool.position_m
        quat = (tool_rot * roll * flat_in_hand).as_quat()
        brick = Pose(position_m=tuple(centre), quat_xyzw=tuple(quat))
        # Past 90 deg it turns on to lie flat the other way up: half a turn from the start.
        half_turns = Rotation.from_euler("y", 180.0 if abs(roll_deg) > 90.0 else 0.0, degrees=True)
        expected = half_turns.apply(flat_offset)
        assert np.allclose(levelled_offset(tool, brick), expected, atol=1e-9)


@dataclass
class Skewed:
    """The built-in reasoner, but its first lift drifts 10 cm sideways and its first return
    ends with the fingers in the ground."""

    name: str = "skewed"
    builtin: BuiltinReasoner = field(default_factory=BuiltinReasoner)
    skewed: set[str] = field(default_factory=set)

    def decide(self, request: AgentRequest) -> AgentReply:
        reply = self.builtin.decide(request)
        key = request.spec.key
        if key not in ("lift", "release") or key in self.skewed:
            return reply
        self.skewed.add(key)
        waypoint = reply.answer.waypoint
        x, y, z = waypoint.position_m
        moved = (x + 0.1, y, z) if key == "lift" else (0.6, -0.2, 0.005)
        skewed = waypoint.model_copy(update={"position_m": moved})
        return AgentReply(answer=reply.answer.model_copy(update={"waypoint": skewed}))


@pytest.mark.slow
def test_a_dragging_lift_and_a_return_into_the_ground_are_refused_before_they_move(
    small_goal,
) -> None:
    one_brick = small_goal.model_copy(update={"targets": small_goal.targets[:1]})
    result, _ = build(one_brick, Skewed())
    assert result.failure is None and result.placements == {0: 0}
    outcomes = [(c.agent, c.outcome) for c in result.transcript if c.agent in ("lift", "release")]
    assert outcomes == [
        ("lift", "refused"),
        ("lift", "accepted"),
        ("release", "refused"),
        ("release", "accepted"),
    ]
    lift, release = (c for c in result.transcript if c.outcome == "refused")
    assert [g.gate for g in lift.gates] == ["lift_plan"]
    assert "drag_m = " in lift.feedback  # 10 cm over the rise drags the brick 3.7 mm
    assert "e_x_m=-0.1" in lift.feedback  # the way back to straight up
    # A return into the ground is refused before the gripper opens, by sigma_6's check of
    # the way there (any pose the way to is clear would do).
    assert [(g.gate, g.passed) for g in release.gates] == [
        ("release_plan", True),
        ("sigma6_return", False),
    ]
    assert release.feedback.startswith("sigma6_return failed: return_clearance_m = -")
    accepted = next(
        c for c in result.transcript if c.agent == "release" and c.outcome == "accepted"
    )
    assert [(g.gate, g.passed) for g in accepted.gates] == [
        ("release_plan", True),
        ("sigma6_return", True),
        ("sigma6_at_rest", True),
    ]
