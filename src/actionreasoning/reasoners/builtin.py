"""The built-in reasoner: a deterministic policy that answers every agent like an LLM would.

It reads only what a prompt shows (a :class:`Briefing`: the agent's state view, memory and
thresholds) and learns more only through the agent's own tools; its answers go through the
same schemas, verification and gates. The prompt-only reference model runs this same
policy on a briefing parsed from the prompt's text. It is the offline default.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from itertools import islice, pairwise, takewhile
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from actionreasoning.agents.memory import PlacementPhase, TaskMemory
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
from actionreasoning.agents.reasoner import AgentReply, AgentRequest, Briefing
from actionreasoning.agents.spec import SINGLE_AGENT, SINGLE_AGENT_START, AgentKey
from actionreasoning.agents.view import BrickView
from actionreasoning.tools.grasp_plan import GRASP_OPTIONS, GraspOption, GraspOptionsQuery
from actionreasoning.tools.placement import PLACEMENT_POSE, PlacementPose, PlacementQuery
from actionreasoning.world.geometry import quat_yaw, top_down_quat
from actionreasoning.world.models import Pose
from actionreasoning.world.motion import MAX_MOVE_S
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, RETREAT_M
from actionreasoning.world.stages import Stage

LIFT_CLEARANCE_M = 0.12
MIN_LIFT_M = 0.30
RELEASE_SIDE_M = 0.005
#: The descent opens this much wider than the brick (two centimetres a side), at most the
#: gripper's full opening: room for the pads past the side walls beyond what sigma_2 needs.
DESCENT_SLACK_M = 0.04
#: Mean speed of a carry with a brick in the hand: a brick creeps and rolls in the hand with
#: time, so a faster carry rolls it less (``bench/lift_roll.py``: carries at 5, 10, 20 and
#: 40 cm/s rolled 16 bricks more than 10 deg 7, 3, 1 and 1 times).
CARRY_SPEED_MPS = 0.20
#: Gates whose refusal put the brick down to be grasped again.
PUT_DOWN_GATES = ("sigma4_lift", "placement_regrasp")
#: Checks of sigma_4 that fail when the brick slips in the grip.
SLIP_CHECKS = ("relative_speed_mps", "friction_margin_n", "normal_force_n")

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

    measured: dict[int, list[GraspOption]] = {}

    def grasps(brick: BrickView) -> list[GraspOption]:
        """Both grasps of ``brick``, the least wrist turn first (measured once)."""
        if brick.id not in measured:
            query = GraspOptionsQuery(
                brick_id=brick.id,
                target_index=target.index,
                descent_opening_m=_descent_opening(brick),
            )
            options = briefing.use(GRASP_OPTIONS, query).options
            measured[brick.id] = sorted(
                options, key=lambda o: o.wrist_deg if o.reachable else math.inf
            )
        return measured[brick.id]

    def usable(option: GraspOption) -> bool:
        return (
            option.reachable
            and option.approach_clearance_m >= tol.c_min_m
            and tol.clear(option.descent_clearance_m)
        )

    # The brick the last refusal found in the way first, then by id.
    in_the_way = _in_the_way(memory)
    free.sort(key=lambda b: b.id != in_the_way)

    def candidates() -> Iterator[tuple[BrickView, GraspOption]]:
        """Each brick's least-wrist grasp where usable, then the other side's."""
        for side in (0, 1):
            for brick in free:
                if usable(option := grasps(brick)[side]):
                    yield brick, option

    # The first free brick with a grasp reachable at pick and place and a clear way down
    # to it (a dropped brick may lie where none is, or beside another). A way that sigma_1
    # found out of reach or not clear is not answered again: after k such refusals in a
    # row, the (k+1)-th grasp. With none left, the first brick's, for the gates to refuse.
    refused = _refused_in_a_row(memory, "sigma1_pre_grasp")
    brick, best = next(islice(candidates(), refused, None), (free[0], grasps(free[0])[0]))
    return PreGraspAnswer(
        brick_id=brick.id,
        target_index=target.index,
        waypoint=_proposal(best.approach_pose),
        rationale=f"target {target.index} next; brick {brick.id} free; grasp yaw "
        f"{best.gripper_yaw_deg:.1f} turns the wrist least"
        + (f" of the grasps sigma_1 has not refused ({refused} refused)" if refused else ""),
    )


def _refused_in_a_row(memory: TaskMemory, gate: str) -> int:
    """How many answers ``gate`` refused last, one after another."""
    tail = takewhile(lambda r: r.gate == gate, reversed(memory.refusals))
    return sum(1 for _ in tail)


def _in_the_way(memory: TaskMemory) -> int | None:
    """The brick the last refusal found in the way (``closest``: "... vs brick N"), if any:
    it is picked first, so that it is in the way no longer."""
    if not memory.refusals or not memory.refusals[-1].measured.closest:
        return None
    found = re.search(r"vs brick (\d+)$", memory.refusals[-1].measured.closest)
    return int(found.group(1)) if found else None


def _descent(briefing: Briefing) -> AgentAnswer:
    view = briefing.view
    brick = view.brick(_current(briefing.memory))
    grasp = _grasp_pose(brick, top_down_quat(quat_yaw(view.robot.tool_pose.quat_xyzw)))
    return DescentAnswer(
        gripper_opening_m=_descent_opening(brick),
        waypoint=_proposal(grasp, path="linear"),
        rationale="open 4 cm past the brick's width, straight down to its centre",
    )


def _grasp(briefing: Briefing) -> AgentAnswer:
    refusals = briefing.memory.refusals
    if not refusals or refusals[-1].gate != "sigma3_grasp":
        return GraspAnswer(close=True, rationale="at the grasp pose: close")
    miss = refusals[-1].measured
    dx, dy, dz = miss.e_x_m or 0.0, miss.e_y_m or 0.0, miss.e_z_m or 0.0
    turn = miss.e_theta_deg or 0.0
    tool = briefing.view.robot.tool_pose
    x, y, z = tool.position_m
    spin = Rotation.from_euler("z", turn, degrees=True) * Rotation.from_quat(tool.quat_xyzw)
    at = Pose(
        position_m=(x + dx, y + dy, z + dz),
        quat_xyzw=tuple(float(q) for q in spin.as_quat()),  # type: ignore[arg-type]
    )
    return GraspAnswer(
        close=True,
        waypoint=_proposal(at, path="linear"),
        rationale=f"the last grasp missed by ({1000 * dx:+.1f}, {1000 * dy:+.1f}, "
        f"{1000 * dz:+.1f}) mm and "
        f"{turn:+.2f} deg: close again there, shifted and turned by it",
    )


def _lift(briefing: Briefing) -> AgentAnswer:
    view, tol = briefing.view, briefing.tolerances
    tool = view.robot.tool_pose
    x, y, _ = tool.position_m
    z = max(MIN_LIFT_M, max(b.top_m for b in view.bricks) + LIFT_CLEARANCE_M)
    lift = Pose(position_m=(x, y, z), quat_xyzw=tool.quat_xyzw)
    slips = sum(
        1
        for refusal in briefing.memory.refusals
        if refusal.gate == "sigma4_lift" and any(c.name in SLIP_CHECKS for c in refusal.failed)
    )
    rise = z - tool.position_m[2]
    speed = max(tol.v_lift_mps / 2**slips, rise / MAX_MOVE_S)
    return LiftAnswer(
        waypoint=_proposal(lift, path="linear", duration_s=_seconds(rise / speed)),
        rationale=f"straight up over every brick at {100 * speed:.2g} cm/s, at most v_lift"
        + (f", halved for each of {slips} slips" if slips else ""),
    )


def _placement(briefing: Briefing) -> AgentAnswer:
    phase, tol = briefing.memory.phase, briefing.tolerances
    if phase is None:
        raise ValueError("memory shows no placement phase")
    placement = _placement_pose(briefing, "linear" if phase == PlacementPhase.SET_DOWN else "joint")
    tilt = placement.tilt_in_hand_deg
    if not tol.clear(placement.way_clearance_m, placement.reachable):
        return PlacementAnswer(
            regrasp=True,
            rationale=f"set level as it sits in the hand (rolled {tilt:.1f} deg), the brick's "
            f"way to the slot collides or is out of reach ({placement.closest}): grasp it again",
        )
    dx, dy, turn, misses = _misses(briefing)
    if math.hypot(dx, dy) > tol.max_offset_m or abs(turn) > tol.max_rotation_deg:
        return PlacementAnswer(
            regrasp=True,
            rationale=f"the set-downs missed by ({1000 * dx:+.1f}, {1000 * dy:+.1f}) mm and "
            f"{turn:+.2f} deg in all: more than a correction within the success rule: grasp "
            "it again",
        )
    slot = _corrected(briefing, placement.slot_pose, dx, dy, turn)
    note = (
        f"; shifted by ({1000 * dx:+.1f}, {1000 * dy:+.1f}) mm and turned by {turn:+.2f} deg: "
        f"the sum of the {misses} seated misses sigma_5 measured"
        if misses
        else ""
    )
    return PlacementAnswer(
        waypoint=_slot(briefing, slot),
        rationale=f"the slot pose for the brick as it sits in the hand, rolled {tilt:.1f} deg "
        "and set level by tilting the tool" + note,
    )


def _misses(briefing: Briefing) -> tuple[float, float, float, int]:
    """The summed offset (x, y) and yaw error of the set-downs sigma_5 refused since the
    brick was last grasped that seated the brick (within eps_perp and eps_tilt: a brick
    that did not seat missed for that reason, not by an offset), and how many."""
    tol, refusals = briefing.tolerances, briefing.memory.refusals
    put_down = [i for i, r in enumerate(refusals) if r.gate in PUT_DOWN_GATES]
    seated = [
        r.measured
        for r in refusals[put_down[-1] + 1 if put_down else 0 :]
        if r.gate == "sigma5_placement"
        and abs(r.measured.d_perp_m or 0.0) <= tol.eps_perp_m
        and (r.measured.tilt_deg or 0.0) <= tol.eps_tilt_deg
    ]
    return (
        sum(m.e_x_m or 0.0 for m in seated),
        sum(m.e_y_m or 0.0 for m in seated),
        sum(m.e_theta_deg or 0.0 for m in seated),
        len(seated),
    )


def _corrected(briefing: Briefing, slot: Pose, dx: float, dy: float, turn: float) -> Pose:
    """``slot`` turned about the vertical axis through the target's centre by ``turn``
    degrees, then shifted by (``dx``, ``dy``)."""
    target = briefing.view.targets[0].pose.position_m
    spin = Rotation.from_euler("z", turn, degrees=True)
    x, y, z = spin.apply(np.subtract(slot.position_m, target)) + np.asarray(target)
    return Pose(
        position_m=(float(x + dx), float(y + dy), float(z)),
        quat_xyzw=tuple(float(q) for q in (spin * Rotation.from_quat(slot.quat_xyzw)).as_quat()),  # type: ignore[arg-type]
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
        opening = _descent_opening(view.brick(pick.brick_id))
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


def _descent_opening(brick: BrickView) -> float:
    return min(brick.size_m[1] + DESCENT_SLACK_M, GRIPPER_GAP_M[1])


def _ready(briefing: Briefing) -> Pose:
    if briefing.view.robot.ready_pose is None:
        raise ValueError("the state shows no ready pose")
    return briefing.view.robot.ready_pose


def _current(memory: TaskMemory) -> int:
    if memory.current_brick is None:
        raise ValueError("no current brick in memory")
    return memory.current_brick


def _seconds(duration_s: float) -> float:
    """A move's duration rounded up to 0.01 s (so that its speed stays within a limit the
    duration was computed from), at most MAX_MOVE_S."""
    return min(math.ceil(duration_s * 100.0) / 100.0, MAX_MOVE_S)


def _proposal(pose: Pose, path: str = "joint", duration_s: float | None = None) -> WaypointProposal:
    return WaypointProposal(
        position_m=pose.position_m,
        quat_xyzw=pose.quat_xyzw,
        path=path,  # type: ignore[arg-type]
        duration_s=duration_s,
    )
