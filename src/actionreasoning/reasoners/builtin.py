"""The built-in reasoner: a deterministic policy that answers every agent like an LLM would.

It reads only what an LLM gets (the request's state, memory and tolerances) and learns
more only through the agent's own tools (``request.call_tool``); its answers go through
the same schemas, verification and gates. It is the offline default and the reference.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Iterator
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from actionreasoning.agents.orchestrator import SEAT_CLEARANCE_M, target_supports
from actionreasoning.agents.outputs import (
    MAX_MOVE_S,
    AgentAnswer,
    DescentAnswer,
    GraspAnswer,
    LiftAnswer,
    PlacementAnswer,
    PreGraspAnswer,
    ReleaseAnswer,
    SingleAgentAnswer,
    WaypointProposal,
)
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.agents.spec import SINGLE_AGENT_START
from actionreasoning.world.geometry import quat_yaw, top_down_quat
from actionreasoning.world.models import BrickState, Pose
from actionreasoning.world.tolerances import Tolerances

LIFT_CLEARANCE_M = 0.12
MIN_LIFT_M = 0.30
RELEASE_SIDE_M = 0.005
DESCENT_EXTRA_M = 0.01
RETREAT_M = 0.08
#: Mean speeds of the moves with a brick in the hand. A lift breaks the brick away from
#: its support slowly, so that an edge still touching does not roll it in the grip; the
#: carry is slow enough that the grip is not loaded much beyond the brick's weight.
#: Whether a lift rolls the brick turns on how it breaks away, which no measurement here
#: predicts: a brick grasped again after a roll is lifted at the next speed of the cycle.
LIFT_SPEEDS_MPS = (0.02, 0.01, 0.03, 0.015, 0.025)
CARRY_SPEED_MPS = 0.10

#: The single agent's cycle: the step that follows the one executed last.
NEXT_STEP = {
    SINGLE_AGENT_START: "pre_grasp",
    "pre_grasp": "descent",
    "descent": "grasp",
    "grasp": "lift",
    "lift": "transfer",
    "transfer": "placement",
    "placement": "release",
    "release": "retreat",
    "retreat": "pre_grasp",
}


class BuiltinReasoner:
    """Answers each of the six agents from its tools; no model, no network."""

    name = "builtin"

    def __init__(self, ready: Pose) -> None:
        self.ready = ready

    def decide(self, request: AgentRequest) -> AgentReply:
        """The answer of agent ``request.spec``."""
        policy = getattr(self, f"_{request.spec.key}")
        return AgentReply(answer=policy(request))

    def _pre_grasp(self, request: AgentRequest) -> AgentAnswer:
        state, memory = request.state, request.memory
        built = {p.target_index for p in memory.placed}
        used = {p.brick_id for p in memory.placed}
        supports = target_supports(state.goal)
        target = next(
            t
            for t in state.goal.targets
            if t.index not in built and set(supports[t.index]) <= built
        )
        free = [b for b in state.bricks if b.id not in used and b.pickable]
        if not free:
            raise ValueError("no unused brick can be picked")

        def wrist_load(brick: BrickState, candidate: Any) -> float:
            turn = quat_yaw(target.pose.quat_xyzw) - quat_yaw(brick.pose.quat_xyzw)
            place_yaw = math.radians(candidate.gripper_yaw_deg) + turn
            x, y, z = target.pose.position_m
            place = Pose(position_m=(x, y, z + 0.1), quat_xyzw=top_down_quat(place_yaw))
            reports = [
                request.call_tool("reachability", {"pose": pose.model_dump()})
                for pose in (candidate.approach_pose, candidate.grasp_pose, place)
            ]
            if not all(r.reachable for r in reports):
                return math.inf
            return max(abs(r.joints_rad[6]) for r in reports)

        def grasps() -> Iterator[tuple[float, BrickState, Any]]:
            for brick in free:
                candidates = request.call_tool("grasp_candidates", {"brick_id": brick.id})
                load, best = min(
                    ((wrist_load(brick, c), c) for c in candidates.candidates),
                    key=lambda pair: pair[0],
                )
                yield load, brick, best

        # The first free brick with a grasp reachable at pick and place and a clear way down
        # to it (a dropped brick may lie where none is, or beside another); else the first
        # reachable one, else the first, for the gates to refuse with feedback.
        options = grasps()
        first = next(options)
        choice = next(
            (
                (load, brick, best)
                for load, brick, best in itertools.chain([first], options)
                if math.isfinite(load) and _way_down_to_grasp_clear(request, brick, best)
            ),
            None,
        )
        _, brick, best = choice or first
        return PreGraspAnswer(
            brick_id=brick.id,
            target_index=target.index,
            waypoint=_proposal(best.approach_pose),
            rationale=f"target {target.index} is next with its support built; brick {brick.id} "
            f"is free; grasp yaw {best.gripper_yaw_deg:.1f} deg keeps the wrist small",
        )

    def _descent(self, request: AgentRequest) -> AgentAnswer:
        state = request.state
        brick = state.brick(_current(request))
        grasp = _grasp_pose(brick, state.robot.ee_pose.quat_xyzw)
        return DescentAnswer(
            gripper_opening_m=_descent_opening(brick, request.tolerances),
            waypoint=_proposal(grasp, path="linear"),
            rationale="open to width + delta and go straight down to the brick centre, half "
            "its height above the ground",
        )

    def _grasp(self, request: AgentRequest) -> AgentAnswer:
        return GraspAnswer(close=True, rationale="at the grasp pose: close")

    def _lift(self, request: AgentRequest) -> AgentAnswer:
        state = request.state
        tops = [b.pose.position_m[2] + b.size_m[2] / 2 for b in state.bricks]
        x, y, _ = state.robot.ee_pose.position_m
        z = max(MIN_LIFT_M, max(tops) + LIFT_CLEARANCE_M)
        lift = Pose(position_m=(x, y, z), quat_xyzw=state.robot.ee_pose.quat_xyzw)
        speed = LIFT_SPEEDS_MPS[request.memory.regrasps % len(LIFT_SPEEDS_MPS)]
        duration = min((z - state.robot.ee_pose.position_m[2]) / speed, MAX_MOVE_S)
        return LiftAnswer(
            waypoint=_proposal(lift, path="linear", duration_s=duration),
            rationale=f"straight up, clear of every brick, at {100 * speed:g} cm/s so the brick "
            "leaves its support level (another speed than the lifts before it that rolled it)",
        )

    def _placement(self, request: AgentRequest) -> AgentAnswer:
        brick = _current(request)
        slip = request.call_tool("slip_estimate", {"brick_id": brick})
        limit = request.tolerances.eps_tilt_deg
        if slip.tilt_in_hand_deg > limit:
            return PlacementAnswer(
                regrasp=True,
                rationale=f"the brick rolled {slip.tilt_in_hand_deg:.1f} deg in the hand, more "
                f"than the {limit:g} deg the tool may tilt to set it level: grasp it again",
            )
        slot = self._slot(request)
        if not _way_down_clear(request, slot):
            return PlacementAnswer(
                regrasp=True,
                rationale=f"with the brick where it sits in the hand (rolled "
                f"{slip.tilt_in_hand_deg:.1f} deg), the way to the slot collides or is out of "
                "reach: grasp it again",
            )
        return PlacementAnswer(
            waypoint=slot,
            rationale="tool pose that puts the brick, as measured in the hand, level on its target",
        )

    @staticmethod
    def _slot(request: AgentRequest) -> WaypointProposal:
        """The tool pose that sets the held brick, as measured in the hand, on its target."""
        state = request.state
        brick = state.brick(_current(request))
        target = state.goal.targets[request.memory.current_target or 0]
        tool = state.robot.ee_pose
        tool_rot = Rotation.from_quat(tool.quat_xyzw)
        in_hand = tool_rot.inv() * Rotation.from_quat(brick.pose.quat_xyzw)
        offset = tool_rot.inv().apply(np.subtract(brick.pose.position_m, tool.position_m))
        # The whole measured pose in the hand, tilt too: a brick that rolled in the hand is
        # set down level by tilting the tool, not pressed flat from a corner.
        slot_rot = Rotation.from_quat(target.pose.quat_xyzw) * in_hand.inv()
        position = np.asarray(target.pose.position_m) - slot_rot.apply(offset)
        slot = Pose(position_m=tuple(position), quat_xyzw=tuple(slot_rot.as_quat()))
        carry = min(math.dist(slot.position_m, tool.position_m) / CARRY_SPEED_MPS, MAX_MOVE_S)
        return _proposal(slot, duration_s=carry)

    def _release(self, request: AgentRequest) -> AgentAnswer:
        brick = request.state.brick(_current(request))
        return ReleaseAnswer(
            gripper_opening_m=brick.size_m[1] + 2 * RELEASE_SIDE_M,
            waypoint=_proposal(self.ready),
            rationale="open just past the brick's width so neighbours are not pushed; go ready",
        )

    def _single_agent(self, request: AgentRequest) -> AgentAnswer:
        """The merged agent: the same policies, one waypoint of the cycle per call."""
        step = NEXT_STEP[request.memory.step]
        state = request.state
        used = {p.brick_id for p in request.memory.placed}
        left = [b for b in state.bricks if b.id not in used and b.pickable]
        if step == "pre_grasp" and (len(used) == len(state.goal.targets) or not left):
            return SingleAgentAnswer(
                step="done", waypoint=_proposal(self.ready), rationale="nothing left to build"
            )
        here = state.robot.ee_pose
        if step == "pre_grasp":
            pick = self._pre_grasp(request)
            opening = self._descent(_with_brick(request, pick.brick_id)).gripper_opening_m
            return SingleAgentAnswer(
                step=step,
                brick_id=pick.brick_id,
                target_index=pick.target_index,
                waypoint=pick.waypoint,
                gripper="open",
                gripper_opening_m=opening,
                rationale=pick.rationale,
            )
        if step in ("descent", "lift"):
            answer = self._descent(request) if step == "descent" else self._lift(request)
            return SingleAgentAnswer(
                step=step, waypoint=answer.waypoint, rationale=answer.rationale
            )
        if step == "grasp":
            return SingleAgentAnswer(step=step, gripper="close", rationale="close on the brick")
        if step in ("transfer", "placement"):
            slot = self._slot(request)
            x, y, z = slot.position_m
            if step == "transfer":
                above = (x, y, max(z, here.position_m[2]))
                return SingleAgentAnswer(
                    step=step,
                    waypoint=slot.model_copy(update={"position_m": above}),
                    rationale="carry the brick above its slot",
                )
            return SingleAgentAnswer(
                step=step,
                waypoint=WaypointProposal(
                    position_m=slot.position_m, quat_xyzw=slot.quat_xyzw, path="linear"
                ),
                rationale="straight down onto the slot",
            )
        if step == "release":
            release = self._release(request)
            return SingleAgentAnswer(
                step=step,
                gripper="open",
                gripper_opening_m=release.gripper_opening_m,
                rationale=release.rationale,
            )
        x, y, z = here.position_m
        # Up to the ready height at least: the next joint move to a brick sags mid-way, and
        # unlike the six agents the single agent checks no clearance on the way.
        up = Pose(
            position_m=(x, y, max(z + RETREAT_M, self.ready.position_m[2])),
            quat_xyzw=here.quat_xyzw,
        )
        return SingleAgentAnswer(
            step=step, waypoint=_proposal(up, path="linear"), rationale="straight up"
        )


def _grasp_pose(brick: BrickState, quat_xyzw: tuple[float, ...]) -> Pose:
    """The tool at the brick's centre. A brick lying on the ground has its centre at half its
    height, whatever the noisy measurement of that height says."""
    x, y, _ = brick.pose.position_m
    return Pose(position_m=(x, y, brick.size_m[2] / 2.0), quat_xyzw=quat_xyzw)


def _descent_opening(brick: BrickState, tolerances: Tolerances) -> float:
    return min(brick.size_m[1] + tolerances.delta_m + DESCENT_EXTRA_M, 0.16)


def _way_down_to_grasp_clear(request: AgentRequest, brick: BrickState, grasp: Any) -> bool:
    """Whether sigma_1 will pass the way to the approach pose (clearance c_min) and the
    descent below it is clear, at the opening the descent will use."""
    tol = request.tolerances
    approach = grasp.approach_pose
    to_approach = request.call_tool(
        "collision_check",
        {
            "pose": approach.model_dump(),
            "path": "joint",
            "gripper_opening_m": request.state.robot.gripper_width_m,
            "ignore_brick_id": brick.id,
        },
    )
    descent = request.call_tool(
        "collision_check",
        {
            "pose": _grasp_pose(brick, approach.quat_xyzw).model_dump(),
            "start_pose": approach.model_dump(),
            "gripper_opening_m": _descent_opening(brick, tol),
            "ignore_brick_id": brick.id,
        },
    )
    return (
        to_approach.reachable
        and to_approach.clearance_m >= tol.c_min_m
        and tol.clear(descent.clearance_m, descent.reachable)
    )


def _way_down_clear(request: AgentRequest, slot: WaypointProposal) -> bool:
    """Whether the held brick's way over the slot (at the current height) and down onto it
    is free of collisions, as the orchestrator will check it."""
    tool = request.state.robot.ee_pose
    x, y, z = slot.position_m
    above = Pose(position_m=(x, y, max(z, tool.position_m[2])), quat_xyzw=slot.quat_xyzw)
    seat = Pose(position_m=(x, y, z + SEAT_CLEARANCE_M), quat_xyzw=slot.quat_xyzw)
    opening = request.state.robot.gripper_width_m
    setting_down = request.memory.flags.get("placement", False)
    over = (
        {"pose": above.model_dump(), "start_pose": tool.model_dump()}
        if setting_down
        else {"pose": above.model_dump(), "path": "joint"}
    )
    checks = (over, {"pose": seat.model_dump(), "start_pose": above.model_dump()})
    reports = [
        request.call_tool("collision_check", {**check, "gripper_opening_m": opening})
        for check in checks
    ]
    return all(request.tolerances.clear(r.clearance_m, r.reachable) for r in reports)


def _with_brick(request: AgentRequest, brick: int | None) -> AgentRequest:
    """The request with ``brick`` as the current brick of its memory."""
    memory = request.memory.model_copy(update={"current_brick": brick})
    return dataclasses.replace(request, memory=memory)


def _current(request: AgentRequest) -> int:
    if request.memory.current_brick is None:
        raise ValueError("no current brick in memory")
    return request.memory.current_brick


def _proposal(pose: Pose, path: str = "joint", duration_s: float | None = None) -> WaypointProposal:
    return WaypointProposal(
        position_m=pose.position_m,
        quat_xyzw=pose.quat_xyzw,
        path=path,  # type: ignore[arg-type]
        duration_s=duration_s,
    )
