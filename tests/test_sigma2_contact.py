"""Gate sigma_2 in a real trial scene: a descent beside the grasp pose, one pad catching the
brick's top edge and pressing its side wall, is refused; a centred descent passes."""

from __future__ import annotations

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
from actionreasoning.reasoners.builtin import DESCENT_SLACK_M, BuiltinReasoner
from actionreasoning.sim.scene import GRASP_CONTACT_N
from actionreasoning.tools.contact import ContactForces
from actionreasoning.tools.registry import call_tool
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.trial.sim_world import SimWorld
from actionreasoning.world.geometry import QuatXYZW, Vec3, quat_yaw, top_down_quat
from actionreasoning.world.models import GoalPattern, Progress, WorldState
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scenarios import NOISE
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import Tolerances

PYRAMID = load_pattern("pyramid", SceneSpec())
TOL = Tolerances()
#: Sideways miss of the grasp pose, across the pads: the opening (the built-in reasoner's,
#: DESCENT_SLACK_M past the width) leaves 2 cm each side, so one pad comes down on the
#: brick's top edge, pushes it aside and ends pressing its wall.
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
        config=TrialConfig(noise=NOISE[noise]),
    )
    with trial_world(spec) as made:
        yield SimWorld(WaypointController(made.scene, made.arm), goal, made.sensor)


def _descend(
    offset_m: float, noise: str
) -> tuple[WorldState, ContactForces, gates.GateVerdict, tuple[float, float]]:
    """Open over brick 0, go straight down to its centre shifted ``offset_m`` across the
    pads, and measure the pads and sigma_2 as the orchestrator does; also how far the brick
    truly moved (x, y)."""
    with _trial(noise) as world:
        centre, quat = world.controller.scene.brick_pose(0)
        tool_quat = top_down_quat(quat_yaw(quat))
        before = world.observe(Progress()).brick(0)
        width = before.size_m[1]
        world.move(WaypointProposal(position_m=(*centre[:2], 0.15), quat_xyzw=tool_quat))
        world.grip(width + DESCENT_SLACK_M)
        grasp = _beside(centre, tool_quat, offset_m)
        world.move(WaypointProposal(position_m=grasp, quat_xyzw=tool_quat, path="linear"))
        state = world.observe(Progress(current_brick=0, step="descent"))
        pads = call_tool("finger_contacts", {"brick_id": 0}, world.tools(state))
        after, _ = world.controller.scene.brick_pose(0)
    (bx, by, _), (ax, ay, _) = before.pose.position_m, state.brick(0).pose.position_m
    shift = (ax - bx, ay - by)
    tol = TOL.under(world.sensing)
    verdict = gates.sigma2_descent(state.robot.gripper_width_m, width, pads, shift, tol)
    return state, pads, verdict, (after[0] - centre[0], after[1] - centre[1])


def _checked(verdict: gates.GateVerdict) -> dict[str, float]:
    return {check.name: check.value for check in verdict.checks}


@pytest.mark.parametrize("noise", ["none", "medium"])
def test_a_centred_descent_touches_nothing_and_passes(noise: str) -> None:
    state, pads, verdict, _ = _descend(0.0, noise)
    assert state.robot.pad_contacts == ()
    assert pads.normal_n == (0.0, 0.0)
    assert verdict.passed, verdict.feedback


def _one_pad_seen(state: WorldState, pads: ContactForces, pad: int) -> None:
    """One pad, ``pad``, presses on the brick (its side wall), the other touches nothing,
    and nothing is held."""
    assert state.brick(0).status != "grasped" and not pads.held
    assert state.robot.finger_forces_n == (0.0, 0.0)  # no brick held
    assert pads.normal_n[pad] > GRASP_CONTACT_N
    assert pads.normal_n[1 - pad] == 0.0
    assert pads.tangential_n[pad] > 0.0


@pytest.mark.parametrize(
    ("offset_m", "pad", "noise"),
    [
        (OFFSET_M, 1, "none"),
        (-OFFSET_M, 0, "none"),
        (OFFSET_M, 1, "medium"),
        (-OFFSET_M, 0, "medium"),
    ],
)
def test_a_pad_on_one_side_of_the_brick_is_seen_and_refused(
    offset_m: float, pad: int, noise: str
) -> None:
    state, pads, verdict, _ = _descend(offset_m, noise)
    _one_pad_seen(state, pads, pad)
    # More than slides the lightest, least grippy brick the noise allows, read through it.
    threshold = TOL.under(state.sensing).sidewall_contact_n
    assert pads.normal_n[pad] > threshold
    assert not verdict.passed
    assert _checked(verdict)["sidewall_force_n"] == pads.normal_n[pad]
    assert verdict.measured.pad_forces_n == pads.normal_n
    assert verdict.feedback.startswith(
        f"sigma2_descent failed: sidewall_force_n = {pads.normal_n[pad]:.4g}, "
        f"needs <= {threshold:.4g}"
    )


@pytest.mark.parametrize("noise", ["none", "medium"])
def test_a_pad_that_shoves_the_brick_aside_is_refused_though_it_ends_touching_nothing(
    noise: str,
) -> None:
    _, pads, verdict, moved = _descend(0.05, noise)
    assert pads.normal_n == (0.0, 0.0)  # the pad slid off the top: nothing presses now
    assert not verdict.passed
    assert _checked(verdict)["brick_shift_m"] > 0.02
    assert "brick_shift_m = " in verdict.feedback and "sidewall" not in verdict.feedback
    # The feedback says where the brick went, signed, in the world frame: the grasp's
    # correction (measured through the sensor's noise, if any).
    noise_m = 3.0 * NOISE[noise].perception.position_std_m * 2**0.5
    assert verdict.measured.e_x_m == pytest.approx(moved[0], abs=noise_m + 1e-6)
    assert verdict.measured.e_y_m == pytest.approx(moved[1], abs=noise_m + 1e-6)


@dataclass
class OffsetFirstDescent:
    """The built-in reasoner, but its first descent aims OFFSET_M beside the grasp pose."""

    name: str = "offset-first-descent"
    builtin: BuiltinReasoner = field(default_factory=lambda: BuiltinReasoner())
    shifted: bool = False
    descents: list[AgentRequest] = field(default_factory=list)

    def decide(self, request: AgentRequest) -> AgentReply:
        reply = self.builtin.decide(request)
        if request.spec.key != "descent":
            return reply
        self.descents.append(request)
        if self.shifted:
            return reply
        self.shifted = True
        aim = reply.answer.waypoint
        moved = aim.model_copy(
            update={"position_m": _beside(aim.position_m, aim.quat_xyzw, OFFSET_M)}
        )
        return AgentReply(answer=reply.answer.model_copy(update={"waypoint": moved}))


@pytest.mark.slow
def test_the_orchestrator_refuses_an_offset_descent_before_it_moves_and_the_next_one_grasps() -> (
    None
):
    goal = PYRAMID.model_copy(update={"targets": PYRAMID.targets[:1]})
    reasoner = OffsetFirstDescent()
    with _trial(goal=goal) as world:
        result = Orchestrator(world, reasoner).build(goal)
    assert result.failure is None, result.failure
    assert list(result.placements) == [0]
    descents = [call for call in result.transcript if call.agent == "descent"]
    assert [call.outcome for call in descents] == ["refused", "accepted"]
    refused, accepted = descents
    # Refused by the descent's plan: its grasp pose 3 cm off the brick's centre across the
    # pads, so a pad would come down on the brick (the closing centres a brick only as far
    # as the open pads pass its side walls); sigma_2, which judges a descent once made,
    # never ran.
    (plan,) = refused.gates
    assert plan.gate == "descent_plan" and not plan.passed
    failed = {check.name: check for check in plan.checks if not check.passed}
    assert set(failed) == {"pad_room_m"}
    opening = refused.answer["gripper_opening_m"]
    room = opening / 2 - OFFSET_M - SceneSpec().brick_size_m[1] / 2
    assert failed["pad_room_m"].value == pytest.approx(room, abs=1e-4)
    assert failed["pad_room_m"].threshold == TOL.pad_room_m
    assert refused.feedback.startswith(f"descent_plan failed: pad_room_m = {room:.4g}")
    # The refusal says where the grasp pose should have been: back across the pads.
    first, second = reasoner.descents
    (refusal,) = second.memory.refusals
    aim = first.view.robot.tool_pose
    back = _beside((0.0, 0.0, 0.0), aim.quat_xyzw, -OFFSET_M)
    assert (refusal.measured.e_x_m, refusal.measured.e_y_m) == pytest.approx(back[:2], abs=1e-6)
    # Nothing moved: the tool is asked again from where it was, over the same brick.
    assert second.view.robot.tool_pose == first.view.robot.tool_pose
    assert second.state.brick(0).pose == first.state.brick(0).pose
    assert [(g.gate, g.passed) for g in accepted.gates] == [
        ("descent_plan", True),
        ("sigma2_descent", True),
    ]
