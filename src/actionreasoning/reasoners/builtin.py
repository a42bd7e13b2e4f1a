"""The built-in reasoner: a deterministic policy that answers every agent like an LLM would.

It reads only what a prompt shows (a :class:`Briefing`: the agent's state view, memory and
thresholds) and learns more only through the agent's own tools; its answers go through the
same schemas, verification and gates. The prompt-only reference model runs this same
policy on a briefing parsed from the prompt's text. It is the offline default.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from itertools import pairwise
from typing import Literal

from actionreasoning.agents.memory import PlacementPhase, TaskMemory
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
from actionreasoning.agents.reasoner import AgentReply, AgentRequest, Briefing
from actionreasoning.agents.spec import SINGLE_AGENT, SINGLE_AGENT_START, AgentKey
from actionreasoning.agents.view import BrickView
from actionreasoning.tools.grasp_plan import GRASP_OPTIONS, GraspOption, GraspOptionsQuery
from actionreasoning.tools.placement import PLACEMENT_POSE, PlacementPose, PlacementQuery
from actionreasoning.world.models import Pose
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, RETREAT_M
from actionreasoning.world.stages import Stage
from actionreasoning.world.tolerances import Tolerances

LIFT_CLEARANCE_M = 0.12
MIN_LIFT_M = 0.30
RELEASE_SIDE_M = 0.005
DESCENT_EXTRA_M = 0.01
#: Mean speeds of the moves with a brick in the hand. A lift breaks the brick away from
#: its support slowly, so that an edge still touching does not roll it in the grip; the
#: carry is slow enough that the grip is not loaded much beyond the brick's weight.
#: Whether a lift rolls the brick turns on how it breaks away, which no measurement here
#: predicts: a brick grasped again after a roll is lifted at the next speed of the cycle.
LIFT_SPEEDS_MPS = (0.02, 0.01, 0.03, 0.015, 0.025)
CARRY_SPEED_MPS = 0.10

#: The single agent's cycle: the step that follows the one executed last.
NEXT_STEP: dict[str, Stage] = {
    SINGLE_AGENT_START: Stage.PRE_GRASP,
    **dict(pairwise((*Stage, Stage.PRE_GRASP))),
}


class BuiltinReasoner:
    """Answers each of the six agents from its tools; no model, no network."""

    name = "builtin"

    def decide(self, request: AgentRequest) -> AgentReply:
        """The answer of agent ``request.spec``."""
        briefing = Briefing(
            agent=request.spec.key,
            view=request.view,
            memory=request.memory,
            tolerances=request.tolerances,
            call_tool=request.call_tool,
        )
        return AgentReply(answer=answer(briefing))


def answer(briefing: Briefing) -> AgentAnswer:
    """The policy's answer to one agent's briefing."""
    return POLICIES[briefing.agent](briefing)


def _pre_grasp(briefing: Briefing) -> AgentAnswer:
    view, memory = briefing.view, briefing.memory
    built = {p.target_index for p in memory.placed}
    used = {p.brick_id for p in memory.placed}
    target = next(t for t in view.targets if t.index not in built and set(t.rests_on) <= built)
    free = [b for b in view.bricks if b.id not in used and b.pickable]
    if not free:
        raise ValueError("no unused brick can be picked")
    tol = briefing.tolerances

    def best_grasp(brick: BrickView) -> GraspOption:
        query = GraspOptionsQuery(
            brick_id=brick.id,
            target_index=target.index,
            descent_opening_m=_descent_opening(brick, tol),
        )
        options = briefing.use(GRASP_OPTIONS, query).options
        return min(options, key=lambda o: o.wrist_deg if o.reachable else math.inf)

    def usable(option: GraspOption) -> bool:
        return (
            option.reachable
            and option.approach_clearance_m >= tol.c_min_m
            and tol.clear(option.descent_clearance_m)
        )

    # The first free brick with a grasp reachable at pick and place and a clear way down
    # to it (a dropped brick may lie where none is, or beside another); else the first,
    # for the gates to refuse with feedback.
    seen: list[tuple[BrickView, GraspOption]] = []
    for brick in free:
        seen.append((brick, best_grasp(brick)))
        if usable(seen[-1][1]):
            break
    brick, best = next((pair for pair in seen if usable(pair[1])), seen[0])
    return PreGraspAnswer(
        brick_id=brick.id,
        target_index=target.index,
        waypoint=_proposal(best.approach_pose),
        rationale=f"target {target.index} next; brick {brick.id} free; grasp yaw "
        f"{best.gripper_yaw_deg:.1f} turns the wrist least",
    )


def _descent(briefing: Briefing) -> AgentAnswer:
    view = briefing.view
    brick = view.brick(_current(briefing.memory))
    grasp = _grasp_pose(brick, view.robot.tool_pose.quat_xyzw)
    return DescentAnswer(
        gripper_opening_m=_descent_opening(brick, briefing.tolerances),
        waypoint=_proposal(grasp, path="linear"),
        rationale="open to width + delta + 1 cm, straight down to the brick's centre",
    )


def _grasp(briefing: Briefing) -> AgentAnswer:
    return GraspAnswer(close=True, rationale="at the grasp pose: close")


def _lift(briefing: Briefing) -> AgentAnswer:
    view = briefing.view
    tool = view.robot.tool_pose
    x, y, _ = tool.position_m
    z = max(MIN_LIFT_M, max(b.top_m for b in view.bricks) + LIFT_CLEARANCE_M)
    lift = Pose(position_m=(x, y, z), quat_xyzw=tool.quat_xyzw)
    speed = LIFT_SPEEDS_MPS[briefing.memory.regrasps % len(LIFT_SPEEDS_MPS)]
    duration = min((z - tool.position_m[2]) / speed, MAX_MOVE_S)
    return LiftAnswer(
        waypoint=_proposal(lift, path="linear", duration_s=duration),
        rationale=f"straight up over every brick at {100 * speed:g} cm/s, so it leaves level",
    )


def _placement(briefing: Briefing) -> AgentAnswer:
    phase = briefing.memory.phase
    if phase is None:
        raise ValueError("memory shows no placement phase")
    placement = _placement_pose(briefing, "linear" if phase == PlacementPhase.SET_DOWN else "joint")
    tilt, limit = placement.tilt_in_hand_deg, briefing.tolerances.eps_tilt_deg
    if tilt > limit:
        return PlacementAnswer(
            regrasp=True,
            rationale=f"the brick rolled {tilt:.1f} deg in the hand, more than the {limit:g} "
            "deg the tool may tilt to set it level: grasp it again",
        )
    if not briefing.tolerances.clear(placement.way_clearance_m, placement.reachable):
        return PlacementAnswer(
            regrasp=True,
            rationale=f"with the brick where it sits in the hand (rolled {tilt:.1f} deg), the "
            "way to the slot collides or is out of reach: grasp it again",
        )
    return PlacementAnswer(
        waypoint=_slot(briefing, placement.slot_pose),
        rationale="the slot pose for the brick as it sits in the hand",
    )


def _placement_pose(briefing: Briefing, approach: Literal["joint", "linear"]) -> PlacementPose:
    """The placement_pose tool's report for the held brick and its target."""
    memory = briefing.memory
    query = PlacementQuery(
        brick_id=_current(memory), target_index=memory.current_target or 0, approach=approach
    )
    return briefing.use(PLACEMENT_POSE, query)


def _slot(briefing: Briefing, slot: Pose) -> WaypointProposal:
    """The slot pose as a waypoint, carried at CARRY_SPEED_MPS."""
    tool = briefing.view.robot.tool_pose
    carry = min(math.dist(slot.position_m, tool.position_m) / CARRY_SPEED_MPS, MAX_MOVE_S)
    return _proposal(slot, duration_s=carry)


def _release(briefing: Briefing) -> AgentAnswer:
    brick = briefing.view.brick(_current(briefing.memory))
    return ReleaseAnswer(
        gripper_opening_m=brick.size_m[1] + 2 * RELEASE_SIDE_M,
        waypoint=_proposal(_ready(briefing)),
        rationale="open 1 cm past the brick's width, then to the ready pose",
    )


def _single_agent(briefing: Briefing) -> AgentAnswer:
    """The merged agent: the same policies, one waypoint of the cycle per call."""
    memory, view = briefing.memory, briefing.view
    step = NEXT_STEP[memory.step]
    used = {p.brick_id for p in memory.placed}
    left = [b for b in view.bricks if b.id not in used and b.pickable]
    ready = _ready(briefing)
    if step == Stage.PRE_GRASP and (not view.targets or not left):
        return SingleAgentAnswer(
            step="done", waypoint=_proposal(ready), rationale="nothing left to build"
        )
    here = view.robot.tool_pose
    if step == Stage.PRE_GRASP:
        pick = _pre_grasp(briefing)
        assert isinstance(pick, PreGraspAnswer) and pick.brick_id is not None
        opening = _descent_opening(view.brick(pick.brick_id), briefing.tolerances)
        return SingleAgentAnswer(
            step=step,
            brick_id=pick.brick_id,
            target_index=pick.target_index,
            waypoint=pick.waypoint,
            gripper="open",
            gripper_opening_m=opening,
            rationale=pick.rationale,
        )
    if step in (Stage.DESCENT, Stage.LIFT):
        moved = _descent(briefing) if step == Stage.DESCENT else _lift(briefing)
        assert isinstance(moved, DescentAnswer | LiftAnswer)
        return SingleAgentAnswer(step=step, waypoint=moved.waypoint, rationale=moved.rationale)
    if step == Stage.GRASP:
        return SingleAgentAnswer(step=step, gripper="close", rationale="close on the brick")
    if step in (Stage.TRANSFER, Stage.PLACEMENT):
        slot = _slot(briefing, _placement_pose(briefing, "joint").slot_pose)
        x, y, z = slot.position_m
        if step == Stage.TRANSFER:
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
    if step == Stage.RELEASE:
        release = _release(briefing)
        assert isinstance(release, ReleaseAnswer)
        return SingleAgentAnswer(
            step=step,
            gripper="open",
            gripper_opening_m=release.gripper_opening_m,
            rationale=release.rationale,
        )
    x, y, z = here.position_m
    # Up to the ready height at least: the next joint move to a brick sags mid-way, and
    # unlike the six agents the single agent checks no clearance on the way.
    up = Pose(position_m=(x, y, max(z + RETREAT_M, ready.position_m[2])), quat_xyzw=here.quat_xyzw)
    return SingleAgentAnswer(
        step=step, waypoint=_proposal(up, path="linear"), rationale="straight up"
    )


POLICIES: dict[AgentKey, Callable[[Briefing], AgentAnswer]] = {
    Stage.PRE_GRASP: _pre_grasp,
    Stage.DESCENT: _descent,
    Stage.GRASP: _grasp,
    Stage.LIFT: _lift,
    Stage.PLACEMENT: _placement,
    Stage.RELEASE: _release,
    SINGLE_AGENT: _single_agent,
}


def _grasp_pose(brick: BrickView, quat_xyzw: tuple[float, ...]) -> Pose:
    """The tool at the brick's centre. A brick lying on the ground has its centre at half its
    height, whatever the noisy measurement of that height says."""
    x, y, _ = brick.pose.position_m
    return Pose(position_m=(x, y, brick.size_m[2] / 2.0), quat_xyzw=quat_xyzw)


def _descent_opening(brick: BrickView, tolerances: Tolerances) -> float:
    return min(brick.size_m[1] + tolerances.delta_m + DESCENT_EXTRA_M, GRIPPER_GAP_M[1])


def _ready(briefing: Briefing) -> Pose:
    if briefing.view.robot.ready_pose is None:
        raise ValueError("the state shows no ready pose")
    return briefing.view.robot.ready_pose


def _current(memory: TaskMemory) -> int:
    if memory.current_brick is None:
        raise ValueError("no current brick in memory")
    return memory.current_brick


def _proposal(pose: Pose, path: str = "joint", duration_s: float | None = None) -> WaypointProposal:
    return WaypointProposal(
        position_m=pose.position_m,
        quat_xyzw=pose.quat_xyzw,
        path=path,  # type: ignore[arg-type]
        duration_s=duration_s,
    )
