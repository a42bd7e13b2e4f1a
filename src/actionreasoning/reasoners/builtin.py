"""The built-in reasoner: a deterministic policy that answers every agent like an LLM would.

It reads only what an LLM gets (the request's state, memory and tolerances) and learns
more only through the agent's own tools (``request.call_tool``); its answers go through
the same schemas, verification and gates. It is the offline default and the reference.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from actionreasoning.agents.orchestrator import target_supports
from actionreasoning.agents.outputs import (
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
from actionreasoning.world.models import Pose

LIFT_CLEARANCE_M = 0.12
MIN_LIFT_M = 0.30
RELEASE_SIDE_M = 0.005
DESCENT_EXTRA_M = 0.01
RETREAT_M = 0.08

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
        brick = next(b for b in state.bricks if b.id not in used and b.status == "in_pick_area")
        grasps = request.call_tool("grasp_candidates", {"brick_id": brick.id})
        turn = quat_yaw(target.pose.quat_xyzw) - quat_yaw(brick.pose.quat_xyzw)

        def wrist_load(candidate: Any) -> float:
            place_yaw = math.radians(candidate.gripper_yaw_deg) + turn
            x, y, z = target.pose.position_m
            place = Pose(position_m=(x, y, z + 0.1), quat_xyzw=top_down_quat(place_yaw))
            reports = [
                request.call_tool("reachability", {"pose": pose.model_dump()})
                for pose in (candidate.approach_pose, place)
            ]
            if not all(r.reachable for r in reports):
                return math.inf
            return max(abs(r.joints_rad[6]) for r in reports)

        best = min(grasps.candidates, key=wrist_load)
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
        opening = brick.size_m[1] + request.tolerances.delta_m + DESCENT_EXTRA_M
        grasp = Pose(position_m=brick.pose.position_m, quat_xyzw=state.robot.ee_pose.quat_xyzw)
        return DescentAnswer(
            gripper_opening_m=min(opening, 0.16),
            waypoint=_proposal(grasp, path="linear"),
            rationale="open to width + delta and go straight down to the brick centre",
        )

    def _grasp(self, request: AgentRequest) -> AgentAnswer:
        return GraspAnswer(close=True, rationale="at the grasp pose: close")

    def _lift(self, request: AgentRequest) -> AgentAnswer:
        state = request.state
        tops = [b.pose.position_m[2] + b.size_m[2] / 2 for b in state.bricks]
        x, y, _ = state.robot.ee_pose.position_m
        z = max(MIN_LIFT_M, max(tops) + LIFT_CLEARANCE_M)
        lift = Pose(position_m=(x, y, z), quat_xyzw=state.robot.ee_pose.quat_xyzw)
        return LiftAnswer(waypoint=_proposal(lift, path="linear"), rationale="straight up, clear")

    def _placement(self, request: AgentRequest) -> AgentAnswer:
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
        return PlacementAnswer(
            waypoint=_proposal(slot),
            rationale="tool pose that puts the brick, as measured in the hand, level on its target",
        )

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
        if step == "pre_grasp" and len(request.memory.placed) == len(state.goal.targets):
            return SingleAgentAnswer(
                step="done", waypoint=_proposal(self.ready), rationale="all built: go ready"
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
            slot = self._placement(request).waypoint
            assert slot is not None
            x, y, z = slot.position_m
            if step == "transfer":
                above = (x, y, max(z, here.position_m[2]))
                return SingleAgentAnswer(
                    step=step,
                    waypoint=WaypointProposal(position_m=above, quat_xyzw=slot.quat_xyzw),
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


def _with_brick(request: AgentRequest, brick: int | None) -> AgentRequest:
    """The request with ``brick`` as the current brick of its memory."""
    memory = request.memory.model_copy(update={"current_brick": brick})
    return dataclasses.replace(request, memory=memory)


def _current(request: AgentRequest) -> int:
    if request.memory.current_brick is None:
        raise ValueError("no current brick in memory")
    return request.memory.current_brick


def _proposal(pose: Pose, path: str = "joint") -> WaypointProposal:
    return WaypointProposal(position_m=pose.position_m, quat_xyzw=pose.quat_xyzw, path=path)  # type: ignore[arg-type]
