"""Gate sigma_2 in a real trial scene: a descent beside the grasp pose, one pad catching the
brick's top edge and pressing its side wall, is refused; a centred descent passes."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from actionreasoning.agents import gates
from actionreasoning.agents.orchestrator import Orchestrator
from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.control.waypoint import WaypointController
from actionreasoning.eval.rules import Method
from actionreasoning.eval.sim_world import SimWorld
from actionreasoning.eval.trial import TrialSpec, trial_world
from actionreasoning.eval.trial_config import TrialConfig
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.sim.scene import GRASP_CONTACT_N
from actionreasoning.tools.contact import ContactForces
from actionreasoning.tools.registry import call_tool
from actionreasoning.world.geometry import QuatXYZW, Vec3, quat_yaw, top_down_quat
from actionreasoning.world.models import GoalPattern, Progress, WorldState
from actionreasoning.world.noise import LEVELS
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import Tolerances

PYRAMID = load_pattern("pyramid", SceneSpec())
TOL = Tolerances()
#: Sideways miss of the grasp pose, across the pads: the opening leaves 2 cm each side, so
#: one pad comes down on the brick's top edge, pushes it aside and ends pressing its wall.
OFFSET_M = 0.03


def _beside(position_m: Vec3, quat_xyzw: QuatXYZW, distance_m: float) -> Vec3:
    """``position_m`` moved ``distance_m`` along the tool's y axis, across the pads."""
    shift = Rotation.from_quat(quat_xyzw).apply((0.0, distance_m, 0.0))
    return tuple(float(v) for v in np.add(position_m, shift))  # type: ignore[return-value]


@contextmanager
def _trial(noise: str = "none", goal: GoalPattern = PYRAMID) -> Iterator[SimWorld]:
    """The first eval trial's scene (seed 0, paper physics) behind the orchestrator's world."""
    spec = TrialSpec(
        method=Method.AGENTS,
        pattern_name="pyramid",
        goal=goal,
        run_seed=0,
        trial=0,
        config=TrialConfig(noise=LEVELS[noise]),
    )
    with trial_world(spec) as made:
        yield SimWorld(WaypointController(made.scene, made.arm), goal, made.sensor)


def _descend(offset_m: float, noise: str) -> tuple[WorldState, ContactForces, gates.GateVerdict]:
    """Open over brick 0, go straight down to its centre shifted ``offset_m`` across the
    pads, and measure the pads and sigma_2 as the orchestrator does."""
    with _trial(noise) as world:
        centre, quat = world.controller.scene.brick_pose(0)
        tool_quat = top_down_quat(quat_yaw(quat))
        before = world.observe(Progress()).brick(0)
        width = before.size_m[1]
        world.move(WaypointProposal(position_m=(*centre[:2], 0.15), quat_xyzw=tool_quat))
        world.grip(width + TOL.delta_m + 0.01)
        grasp = _beside(centre, tool_quat, offset_m)
        world.move(WaypointProposal(position_m=grasp, quat_xyzw=tool_quat, path="linear"))
        state = world.observe(Progress(current_brick=0, step="descent"))
        pads = call_tool("finger_contacts", {"brick_id": 0}, world.tools(state))
    shift = math.dist(state.brick(0).pose.position_m[:2], before.pose.position_m[:2])
    tol = TOL.under(world.sensing)
    verdict = gates.sigma2_descent(state.robot.gripper_width_m, width, pads, shift, tol)
    return state, pads, verdict


@pytest.mark.parametrize("noise", ["none", "medium"])
def test_a_centred_descent_touches_nothing_and_passes(noise: str) -> None:
    state, pads, verdict = _descend(0.0, noise)
    assert state.robot.pad_contacts == ()
    assert pads.normal_n == (0.0, 0.0)
    assert verdict.passed, verdict.feedback


@pytest.mark.parametrize("noise", ["none", "medium"])
@pytest.mark.parametrize(("offset_m", "pad"), [(OFFSET_M, 1), (-OFFSET_M, 0)])
def test_a_pad_on_one_side_of_the_brick_is_seen_and_refused(
    offset_m: float, pad: int, noise: str
) -> None:
    state, pads, verdict = _descend(offset_m, noise)
    assert state.brick(0).status != "grasped" and not pads.held
    assert state.robot.finger_forces_n == (0.0, 0.0)  # no brick held
    assert pads.normal_n[pad] > GRASP_CONTACT_N
    assert pads.normal_n[1 - pad] == 0.0
    assert pads.tangential_n[pad] > 0.0
    assert not verdict.passed
    assert verdict.measured["sidewall_force_n"] == pads.normal_n[pad]
    assert verdict.feedback.startswith(
        f"sigma2_descent failed: sidewall_force_n = {pads.normal_n[pad]:.4g}, needs <= 1"
    )


@pytest.mark.parametrize("noise", ["none", "medium"])
def test_a_pad_that_shoves_the_brick_aside_is_refused_though_it_ends_touching_nothing(
    noise: str,
) -> None:
    _, pads, verdict = _descend(0.05, noise)
    assert pads.normal_n == (0.0, 0.0)  # the pad slid off the top: nothing presses now
    assert not verdict.passed
    assert verdict.measured["brick_shift_m"] > 0.02
    assert "brick_shift_m = " in verdict.feedback and "sidewall" not in verdict.feedback


@dataclass
class OffsetFirstDescent:
    """The built-in reasoner, but its first descent aims OFFSET_M beside the grasp pose."""

    name: str = "offset-first-descent"
    builtin: BuiltinReasoner = field(default_factory=lambda: BuiltinReasoner())
    shifted: bool = False

    def decide(self, request: AgentRequest) -> AgentReply:
        reply = self.builtin.decide(request)
        if request.spec.key != "descent" or self.shifted:
            return reply
        self.shifted = True
        aim = reply.answer.waypoint
        moved = aim.model_copy(
            update={"position_m": _beside(aim.position_m, aim.quat_xyzw, OFFSET_M)}
        )
        return AgentReply(answer=reply.answer.model_copy(update={"waypoint": moved}))


@pytest.mark.slow
def test_the_orchestrator_refuses_an_offset_descent_and_the_next_one_grasps() -> None:
    goal = PYRAMID.model_copy(update={"targets": PYRAMID.targets[:1]})
    with _trial(goal=goal) as world:
        result = Orchestrator(world, OffsetFirstDescent()).build(goal)
    assert result.failure is None, result.failure
    assert list(result.placements) == [0]
    descents = [call for call in result.transcript if call.agent == "descent"]
    assert [call.outcome for call in descents] == ["refused", "accepted"]
    refused, accepted = descents
    (sigma2,) = refused.gates
    assert sigma2.gate == "sigma2_descent" and not sigma2.passed
    opening, sidewall, _ = sigma2.checks
    assert opening.passed
    assert sidewall.name == "sidewall_force_n" and not sidewall.passed
    assert sidewall.value > GRASP_CONTACT_N and sidewall.threshold == TOL.sidewall_contact_n
    assert refused.feedback.startswith("sigma2_descent failed: sidewall_force_n = ")
    assert accepted.gates[0].passed
