"""The built-in reasoner: a deterministic policy that answers every agent like an LLM would.

It reads only what a prompt shows (a :class:`Briefing`: the agent's state view, memory and
thresholds) and learns more only through the agent's own tools; its answers go through the
same schemas, verification and gates. The prompt-only reference model runs this same
policy on a briefing parsed from the prompt's text. It is the offline default.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, replace
from itertools import islice, takewhile
from typing import Any, Literal

import numpy as np
from scipy.spatial.transform import Rotation

from actionreasoning.agents.feedback import since_put_down
from actionreasoning.agents.memory import PlacementPhase, TaskMemory
from actionreasoning.agents.outputs import (
    AgentAnswer,
    DescentDecision,
    GraspAnswer,
    LiftDecision,
    PlacementDecision,
    PreGraspDecision,
    PreGraspSeenDecision,
    RegraspRequest,
    ReleaseDecision,
    SingleAgentAnswer,
    WaypointProposal,
)
from actionreasoning.agents.reasoner import AgentReply, AgentRequest, Briefing
from actionreasoning.agents.spec import SINGLE_AGENT, AgentKey
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.agents.view import BrickView, TargetView
from actionreasoning.reasoners.sight import corrected, ends_swapped, is_seen, seen_view
from actionreasoning.tools import formulas
from actionreasoning.tools.collision import COLLISION, CollisionQuery
from actionreasoning.tools.grasp_plan import (
    GRASP_OPTIONS,
    PLACE_CHECK_ABOVE_M,
    GraspOption,
    GraspOptionsQuery,
)
from actionreasoning.tools.placement import PLACEMENT_POSE, PlacementQuery
from actionreasoning.tools.reach import REACHABILITY, ReachQuery
from actionreasoning.world.geometry import axis_angle_deg, quat_yaw, top_down_quat, wrap_angle
from actionreasoning.world.models import Pose
from actionreasoning.world.motion import CARRY_SPEED_MPS, MAX_MOVE_S
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, WORKSPACE
from actionreasoning.world.stages import Stage

LIFT_CLEARANCE_M = 0.12
MIN_LIFT_M = 0.30
RELEASE_SIDE_M = 0.005
#: The descent opens this much wider than the brick (two centimetres a side), at most the
#: gripper's full opening: room for the pads past the side walls beyond what sigma_2 needs.
DESCENT_SLACK_M = 0.04
#: Checks of sigma_4 that fail when the brick slips in the grip.
SLIP_CHECKS = ("relative_speed_mps", "friction_margin_n", "normal_force_n")


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
            tier=request.spec.tier,
            observation=request.spec.observation,
            pictures=request.pictures,
        )
        return AgentReply(answer=answer(briefing))


def answer(briefing: Briefing) -> AgentAnswer:
    """The policy's answer to one agent's briefing; in the image tier, on the bricks its
    pictures show (``sight.py``), agent 1 naming its brick by where it lies."""
    if briefing.observation.poses:
        return POLICIES[briefing.agent](briefing)
    seen = seen_view(briefing.view, briefing.memory, briefing.pictures)
    decided = POLICIES[briefing.agent](replace(briefing, view=seen))
    if not isinstance(decided, PreGraspDecision):
        return decided
    # The gate's refusals of approaches over the brick chosen measured where it lies.
    better = corrected(seen, decided.brick_id, briefing.memory)
    if better is not None:
        decided = _pre_grasp(replace(briefing, view=better))
    return PreGraspSeenDecision(**decided.model_dump(exclude={"brick_id"}))


@dataclass(frozen=True)
class _Grasp:
    """One top-down grasp of a brick: the tool's yaw and the approach pose above it."""

    brick: BrickView
    yaw_deg: float
    approach: Pose
    option: GraspOption | None = None  # grasp_options' report of it (solve tier)


def _pre_grasp(briefing: Briefing) -> PreGraspDecision:
    view, memory = briefing.view, briefing.memory
    built = {p.target_index for p in memory.placed}
    used = {p.brick_id for p in memory.placed}
    unused = [b for b in view.bricks if b.id not in used and b.pickable]
    buildable = [t for t in view.targets if t.index not in built and set(t.rests_on) <= built]
    # The first target buildable now that an unused brick fits (all fit, of one brick size).
    target, free = next(
        (
            (t, fitting)
            for t in buildable
            if (fitting := [b for b in unused if view.fits(b, t.index)])
        ),
        (buildable[0], []),
    )
    if not free:
        raise ValueError("no unused brick can be picked")
    # The brick the last refusal found in the way first, then by id.
    in_the_way = _in_the_way(memory)
    free.sort(key=lambda b: b.id != in_the_way)
    usable = _USABLE[briefing.tier]
    measured: dict[int, list[_Grasp]] = {}

    def grasps(brick: BrickView) -> list[_Grasp]:
        """Both grasps of ``brick`` (measured once)."""
        if brick.id not in measured:
            measured[brick.id] = _grasps(briefing, target, brick)
        return measured[brick.id]

    ordered = (grasps(brick)[side] for side in (0, 1) for brick in free)
    # Each brick's grasp of the smaller wrist turn where usable, then the other side's. A
    # way that sigma_1 found out of reach or not clear is not answered again: after k such
    # refusals in a row, the (k+1)-th grasp. With none left, the first, for the gates to
    # refuse.
    refused = _refused_in_a_row(memory, "sigma1_pre_grasp")
    candidates = (grasp for grasp in ordered if usable(briefing, target, grasp))
    best = next(islice(candidates, refused, None), grasps(free[0])[0])
    return PreGraspDecision(
        brick_id=best.brick.id,
        target_index=target.index,
        waypoint=_proposal(best.approach),
        rationale=f"target {target.index} next; {_named(best.brick)} free; grasp yaw "
        f"{best.yaw_deg:.1f} turns the wrist least"
        + (f" of the grasps sigma_1 has not refused ({refused} refused)" if refused else ""),
    )


def _grasps(briefing: Briefing, target: TargetView, brick: BrickView) -> list[_Grasp]:
    """A brick's two grasps, the one that turns the wrist less first: in the solve tier as
    grasp_options measures the wrist (an unreachable grasp last), else by the formula."""
    if briefing.tier is ToolTier.SOLVE:
        options = sorted(
            _grasp_options(briefing, target, brick),
            key=lambda o: o.wrist_deg if o.reachable and o.wrist_deg is not None else math.inf,
        )
        return [_Grasp(brick, o.gripper_yaw_deg, o.approach_pose, o) for o in options]
    yaws = sorted(
        formulas.grasp_yaws_deg(brick.pose.quat_xyzw),
        key=lambda yaw: formulas.wrist_turn_deg(brick.pose, target.pose, yaw),
    )
    return [
        _Grasp(
            brick,
            yaw,
            formulas.approach_pose(
                formulas.grasp_pose(brick.pose, brick.size_m, top_down_quat(math.radians(yaw)))
            ),
        )
        for yaw in yaws
    ]


def _grasp_options(briefing: Briefing, target: TargetView, brick: BrickView) -> list[GraspOption]:
    """grasp_options' report for ``brick`` and ``target``."""
    query = GraspOptionsQuery(
        brick_id=brick.id, target_index=target.index, descent_opening_m=_descent_opening(brick)
    )
    return list(briefing.use(GRASP_OPTIONS, query).options)


def _usable_solved(briefing: Briefing, target: TargetView, grasp: _Grasp) -> bool:
    """Reachable at pick and place, a clear joint move to the approach and a clear way down,
    as grasp_options reports them."""
    tol, option = briefing.tolerances, grasp.option
    assert option is not None
    return (
        option.reachable
        and option.approach_clearance_m >= tol.c_min_m
        and tol.clear(option.descent_clearance_m)
    )


def _usable_checked(briefing: Briefing, target: TargetView, grasp: _Grasp) -> bool:
    """The same, measured by three checks in one turn: the joint move to the approach, the
    way down to the grasp pose, and the arm's reach of the place pose over the target."""
    tol, brick = briefing.tolerances, grasp.brick
    approach = grasp.approach
    down = formulas.grasp_pose(brick.pose, brick.size_m, approach.quat_xyzw)
    place_yaw = formulas.place_yaw_deg(grasp.yaw_deg, brick.pose.quat_xyzw, target.pose.quat_xyzw)
    x, y, z = target.pose.position_m
    place = Pose(
        position_m=(x, y, z + PLACE_CHECK_ABOVE_M),
        quat_xyzw=top_down_quat(math.radians(place_yaw)),
    )
    to_approach, descent, reach = briefing.use_all(
        (
            COLLISION,
            CollisionQuery(
                pose=approach,
                path="joint",
                gripper_opening_m=briefing.view.robot.gripper_width_m,
                **_left_out(brick),
            ),
        ),
        (
            COLLISION,
            CollisionQuery(
                pose=down,
                start_pose=approach,
                path="linear",
                gripper_opening_m=_descent_opening(brick),
                **_left_out(brick),
            ),
        ),
        (REACHABILITY, ReachQuery(pose=place)),
    )
    return (
        to_approach.reachable
        and descent.reachable
        and reach.reachable
        and to_approach.clearance_m >= tol.c_min_m
        and tol.clear(descent.clearance_m)
    )


def _left_out(brick: BrickView) -> dict[str, Any]:
    """The collision check's argument that leaves ``brick`` out: its id, or, for a brick
    found in the pictures, whose id the scene does not know, its centre."""
    if is_seen(brick.id):
        return {"ignore_brick_at_m": brick.pose.position_m[:2]}
    return {"ignore_brick_id": brick.id}


def _usable_unchecked(briefing: Briefing, target: TargetView, grasp: _Grasp) -> bool:
    """Without tools every grasp is answered in order; sigma_1 refuses what is not clear."""
    return True


_USABLE: dict[ToolTier, Callable[[Briefing, TargetView, _Grasp], bool]] = {
    ToolTier.SOLVE: _usable_solved,
    ToolTier.CHECK: _usable_checked,
    ToolTier.NONE: _usable_unchecked,
}


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


def _descent(briefing: Briefing) -> DescentDecision:
    view = briefing.view
    brick = view.brick(_current(briefing.memory))
    # At the tool's present yaw, or turned to the brick's grasp yaw if that is further off
    # than eps_g_deg (the approach is then no grasp sigma_3 would accept).
    yaw = quat_yaw(view.robot.tool_pose.quat_xyzw)
    off = wrap_angle(2.0 * (quat_yaw(brick.pose.quat_xyzw) - yaw)) / 2.0
    if abs(math.degrees(off)) > briefing.tolerances.eps_g_deg:
        yaw += off
    grasp = formulas.grasp_pose(brick.pose, brick.size_m, top_down_quat(yaw))
    return DescentDecision(
        gripper_opening_m=_descent_opening(brick),
        waypoint=_proposal(grasp, path="linear"),
        rationale="open 4 cm past the brick's width, straight down to its centre",
    )


def _grasp(briefing: Briefing) -> GraspAnswer:
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
        quat_xyzw=tuple(float(q) for q in spin.as_quat()),
    )
    return GraspAnswer(
        close=True,
        waypoint=_proposal(at, path="linear"),
        rationale=f"the last grasp missed by ({1000 * dx:+.1f}, {1000 * dy:+.1f}, "
        f"{1000 * dz:+.1f}) mm and "
        f"{turn:+.2f} deg: close again there, shifted and turned by it",
    )


def _lift(briefing: Briefing) -> LiftDecision:
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
    return LiftDecision(
        waypoint=_proposal(lift, path="linear", duration_s=_seconds(rise / speed)),
        rationale=f"straight up over every brick at {speed:.3g} m/s, at most v_lift_mps"
        + (f", halved for each of {slips} slips" if slips else ""),
    )


def _placement(briefing: Briefing) -> PlacementDecision | RegraspRequest:
    phase, tol = briefing.memory.phase, briefing.tolerances
    if phase is None:
        raise ValueError("memory shows no placement phase")
    plan = _slot_plan(briefing, "linear" if phase == PlacementPhase.SET_DOWN else "joint")
    if not WORKSPACE.contains(plan.pose.position_m):
        x, y, z = plan.pose.position_m
        return RegraspRequest(
            regrasp=True,
            rationale=f"the brick sits so far along the pads (rolled {plan.tilt_deg:.1f} deg) "
            f"that its slot pose, ({x:.3f}, {y:.3f}, {z:.3f}) m, is outside the workspace: "
            "grasp it again",
        )
    if not plan.clear:
        return RegraspRequest(
            regrasp=True,
            rationale=f"set level as it sits in the hand (rolled {plan.tilt_deg:.1f} deg), the "
            f"brick's way to the slot collides or is out of reach ({plan.closest}): grasp it "
            "again",
        )
    dx, dy, turn, misses = _misses(briefing)
    if math.hypot(dx, dy) > tol.max_offset_m or abs(turn) > tol.max_rotation_deg:
        return RegraspRequest(
            regrasp=True,
            rationale=f"the set-downs missed by ({1000 * dx:+.1f}, {1000 * dy:+.1f}) mm and "
            f"{turn:+.2f} deg in all: more than a correction within the success rule: grasp "
            "it again",
        )
    slot = _corrected(briefing, plan.pose, dx, dy, turn)
    if not briefing.observation.poses:
        slot = _plan_corrected(briefing, slot)
    note = (
        f"; shifted by ({1000 * dx:+.1f}, {1000 * dy:+.1f}) mm and turned by {turn:+.2f} deg: "
        f"the sum of the {misses} seated misses sigma_5 measured"
        if misses
        else ""
    )
    return PlacementDecision(
        waypoint=_slot(briefing, slot),
        rationale=f"the slot pose for the brick as it sits in the hand, rolled "
        f"{plan.tilt_deg:.1f} deg and set level by tilting the tool" + note,
    )


@dataclass(frozen=True)
class _SlotPlan:
    """The slot pose for the held brick, its roll in the hand, and whether its way is clear
    (and if not, the two things that close)."""

    pose: Pose
    tilt_deg: float
    clear: bool
    closest: str


def _slot_plan(briefing: Briefing, approach: Literal["joint", "linear"]) -> _SlotPlan:
    """The slot pose and its way: placement_pose's report in the solve tier; else the
    formulas' pose, its way clear unless the gate's last refusal found it not (a
    placement_plan refusal of the way of a slot that was right: the plan's check measures
    what a collision_check of the way would, so asking the tool first would only repeat
    it)."""
    tol, memory = briefing.tolerances, briefing.memory
    if briefing.tier is ToolTier.SOLVE:
        query = PlacementQuery(
            brick_id=_current(memory), target_index=memory.current_target or 0, approach=approach
        )
        report = briefing.use(PLACEMENT_POSE, query)
        turn = _roll_turn_deg(briefing, report.slot_pose)
        if turn:
            query = query.model_copy(update={"roll_turn_deg": turn})
            report = briefing.use(PLACEMENT_POSE, query)
        clear = tol.clear(report.way_clearance_m, report.reachable)
        return _SlotPlan(report.slot_pose, report.tilt_in_hand_deg, clear, report.closest)
    slot, tilt = _slot_by_formula(briefing)
    last = memory.refusals[-1] if memory.refusals else None
    if last is None or last.gate != f"{Stage.PLACEMENT}_plan":
        return _SlotPlan(slot, tilt, True, "")
    failed = {check.name for check in last.failed}
    # Refused for its way, the slot itself right (a wrong slot is answered again, right).
    way_refused = bool(failed & {"way_reachable", "way_clearance_m"}) and not any(
        name.startswith("predicted_") for name in failed
    )
    return _SlotPlan(slot, tilt, not way_refused, last.measured.closest or "")


def _slot_by_formula(briefing: Briefing) -> tuple[Pose, float]:
    """The slot pose that sets the held brick, as it will sit in the hand at touch-down, on
    its target (the knowledge base's formulas), and its roll in the hand now (deg)."""
    view, memory = briefing.view, briefing.memory
    brick, tool = view.brick(_current(memory)), view.robot.tool_pose
    target, grip = _target(briefing).pose, formulas.in_hand(tool, brick.pose)
    slot = formulas.slot_pose(target, *grip)
    turn = _roll_turn_deg(briefing, slot)
    if turn:
        slot = formulas.slot_pose(target, *formulas.rolled_in_hand(*grip, turn))
    return slot, axis_angle_deg(brick.pose.quat_xyzw, tool.quat_xyzw)


def _roll_turn_deg(briefing: Briefing, slot: Pose) -> float:
    """How much further the held brick rolls in the hand before a set-down to ``slot``
    touches down (deg): memory.roll_watch's roll rate times the touch-down time of the
    set-down's duration (Formulas: roll rate); 0 without a watch (the carry)."""
    watch = briefing.memory.roll_watch
    if watch is None:
        return 0.0
    return watch.turn_by_touch_down_deg(_carry_s(briefing, slot))


def _misses(briefing: Briefing) -> tuple[float, float, float, int]:
    """The summed offset (x, y) and yaw error of the set-downs sigma_5 refused since the
    brick was last grasped that seated the brick (within eps_perp and eps_tilt: a brick
    that did not seat missed for that reason, not by an offset), and how many."""
    tol = briefing.tolerances
    seated = [
        r.measured
        for r in since_put_down(briefing.memory.refusals)
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


def _plan_corrected(briefing: Briefing, slot: Pose) -> Pose:
    """In the image tier, where the held brick is seen, not measured: ``slot`` corrected by
    the placement plan's refusals in a row (the last ones). Each predicted the brick, as it
    truly sits in the hand, landing off its target by (e_x, e_y) (wanted minus landing),
    turned by e_theta and d_perp above it, from a slot corrected by those before it: their
    sum is what this slot needs. A landing turned more than a quarter turn is the brick's
    ends told apart (``sight.py``), not a miss."""
    misses = [
        r.measured
        for r in takewhile(
            lambda r: r.gate == f"{Stage.PLACEMENT}_plan", reversed(briefing.memory.refusals)
        )
        if not ends_swapped(r)
    ]
    if not misses:
        return slot
    dx, dy = sum(m.e_x_m or 0.0 for m in misses), sum(m.e_y_m or 0.0 for m in misses)
    turn = sum(m.e_theta_deg or 0.0 for m in misses)
    moved = _corrected(briefing, slot, dx, dy, turn)
    x, y, z = moved.position_m
    down = sum(m.d_perp_m or 0.0 for m in misses)
    return Pose(position_m=(x, y, z - down), quat_xyzw=moved.quat_xyzw)


def _corrected(briefing: Briefing, slot: Pose, dx: float, dy: float, turn: float) -> Pose:
    """``slot`` turned about the vertical axis through the target's centre by ``turn``
    degrees, then shifted by (``dx``, ``dy``)."""
    target = _target(briefing).pose.position_m
    spin = Rotation.from_euler("z", turn, degrees=True)
    x, y, z = spin.apply(np.subtract(slot.position_m, target)) + np.asarray(target)
    return Pose(
        position_m=(float(x + dx), float(y + dy), float(z)),
        quat_xyzw=tuple(float(q) for q in (spin * Rotation.from_quat(slot.quat_xyzw)).as_quat()),
    )


def _slot(briefing: Briefing, slot: Pose) -> WaypointProposal:
    """The slot pose as a waypoint, carried at CARRY_SPEED_MPS."""
    return _proposal(slot, duration_s=_carry_s(briefing, slot) or None)  # 0: already there


def _carry_s(briefing: Briefing, slot: Pose) -> float:
    """How long the move to ``slot`` takes at CARRY_SPEED_MPS (Formulas: duration)."""
    tool = briefing.view.robot.tool_pose
    return min(math.dist(slot.position_m, tool.position_m) / CARRY_SPEED_MPS, MAX_MOVE_S)


def _release(briefing: Briefing) -> ReleaseDecision:
    brick = briefing.view.brick(_current(briefing.memory))
    return ReleaseDecision(
        gripper_opening_m=brick.size_m[1] + 2 * RELEASE_SIDE_M,
        waypoint=_proposal(_ready(briefing)),
        rationale="open 1 cm past the brick's width, then to the ready pose",
    )


def _single_agent(briefing: Briefing) -> SingleAgentAnswer:
    """The merged agent: at the stage memory.step asks for, that stage's agent's policy,
    on what the merged prompt shows."""
    step = briefing.memory.step
    if step not in STAGE_POLICIES:
        raise ValueError(f"memory.step {step!r} is no stage the single agent answers")
    decision = STAGE_POLICIES[step](replace(briefing, agent=Stage(step)))
    return SingleAgentAnswer(step=Stage(step), **dict(decision))


STAGE_POLICIES: dict[str, Callable[[Briefing], AgentAnswer]] = {
    Stage.PRE_GRASP: _pre_grasp,
    Stage.DESCENT: _descent,
    Stage.GRASP: _grasp,
    Stage.LIFT: _lift,
    Stage.PLACEMENT: _placement,
    Stage.RELEASE: _release,
}
POLICIES: dict[AgentKey, Callable[[Briefing], AgentAnswer]] = {
    **{Stage(stage): policy for stage, policy in STAGE_POLICIES.items()},
    SINGLE_AGENT: _single_agent,
}


def _named(brick: BrickView) -> str:
    """How a rationale names ``brick``: by id, or, found in the pictures, by where it lies."""
    if is_seen(brick.id):
        x, y, _ = brick.pose.position_m
        return f"the brick at ({x:.3f}, {y:.3f}) m"
    return f"brick {brick.id}"


def _descent_opening(brick: BrickView) -> float:
    return min(brick.size_m[1] + DESCENT_SLACK_M, GRIPPER_GAP_M[1])


def _ready(briefing: Briefing) -> Pose:
    if briefing.view.robot.ready_pose is None:
        raise ValueError("the state shows no ready pose")
    return briefing.view.robot.ready_pose


def _target(briefing: Briefing) -> TargetView:
    """The current target, as the state shows it."""
    index = briefing.memory.current_target
    found = next((t for t in briefing.view.targets if t.index == index), None)
    if found is None:
        raise ValueError(f"the state shows no current target ({index})")
    return found


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
        path=path,
        duration_s=duration_s,
    )
