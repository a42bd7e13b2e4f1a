"""The gated orchestrator: six agents per brick, each output verified and gated.

Per brick: Ag1 pre-grasp -> Ag2 descent & opening -> Ag3 grasp -> Ag4 safe lift ->
Ag5 placement -> Ag6 release & return. An answer is first verified (complete, known ids,
a target whose support is built, a reachable collision-free path); only then does the
world move, and the gate sigma_i judges what was measured afterwards. A failed check goes
back to the same agent as feedback, within a retry budget. sigma_4 = 0 puts the brick back
where it was grasped; Ag5 asking for a re-grasp sets it aside on free ground near by; either
way the cycle starts again at Ag1. sigma_5 = 0 in contact raises the brick by delta_h and
asks Ag5 again. A spent budget ends the trial with a typed failure.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import TypeVar

from actionreasoning.agents import gates
from actionreasoning.agents.calls import (
    BUILD_STOPPERS,
    A,
    AgentCaller,
    BuildResult,
    CallHook,
    StageHook,
    TrialStopped,
    failure_of,
)
from actionreasoning.agents.memory import EarlierAnswer, PlacedBrick, PlacementPhase, TaskMemory
from actionreasoning.agents.outputs import (
    DescentAnswer,
    GraspAnswer,
    LiftAnswer,
    PlacementAnswer,
    PreGraspAnswer,
    ReleaseAnswer,
    WaypointProposal,
    unit_waypoint,
)
from actionreasoning.agents.put_down import PutDown
from actionreasoning.agents.reasoner import Reasoner
from actionreasoning.agents.spec import agent_specs
from actionreasoning.agents.transcript import Outcome
from actionreasoning.agents.view import target_supports
from actionreasoning.agents.world import World
from actionreasoning.errors import UnreachableError
from actionreasoning.records import FailureCode
from actionreasoning.tools.collision import COLLISION, CollisionQuery, CollisionReport
from actionreasoning.tools.contact import FINGER_CONTACTS, SLIP
from actionreasoning.tools.geometry import ALIGNMENT, AlignmentQuery, BrickQuery
from actionreasoning.tools.placement import SEAT_CLEARANCE_M
from actionreasoning.world.geometry import quat_yaw, rotation_deg
from actionreasoning.world.models import GoalPattern, Pose, Progress, WorldState
from actionreasoning.world.motion import Motion
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, RETREAT_M
from actionreasoning.world.stages import Stage
from actionreasoning.world.tolerances import Tolerances

T = TypeVar("T")

#: The lift's path is checked from this far above the grasp: below it the brick still
#: touches its support.
LIFT_CHECK_FROM_M = 0.01
#: Where the carry ends: this far above the slot, so that the brick is measured in the
#: hand again just before the set-down (it may have crept or rolled on the way), with room
#: below for the ends of a brick rolled up to eps_tilt.
HOVER_M = 0.08


@dataclass(frozen=True)
class Budgets:
    """Retry budgets of a trial."""

    attempts_per_agent: int = 3
    regrasps: int = 4
    placement_attempts: int = 4


class _Refused(Exception):
    """An answer refused by verification or a gate; the message is the agent's feedback.

    ``reason`` is the failure code the trial ends with if the agent's budget runs out.
    """

    def __init__(self, feedback: str, reason: FailureCode = FailureCode.INVALID_OUTPUT) -> None:
        super().__init__(feedback)
        self.reason = reason


class _Regrasp(Exception):
    """sigma_4 = 0: the brick was put back; start again at Ag1 with this feedback."""


class Orchestrator:
    """Runs the six agents over a goal, brick by brick, against a :class:`World`."""

    def __init__(
        self,
        world: World,
        reasoner: Reasoner,
        tolerances: Tolerances = Tolerances(),
        budgets: Budgets = Budgets(),
        on_stage: StageHook | None = None,
        on_call: CallHook | None = None,
    ) -> None:
        self.world = world
        self.reasoner = reasoner
        self.tol = tolerances.under(world.sensing)
        self.budgets = budgets
        self.on_stage = on_stage
        self.specs = {spec.key: spec for spec in agent_specs()}
        self.result = BuildResult()
        self.calls = AgentCaller(world, reasoner, self.tol, self.result, on_call)
        self.put_down = PutDown(world, self.calls)
        self.memory = TaskMemory()

    # --- the pipeline -------------------------------------------------------------------
    def build(self, goal: GoalPattern) -> BuildResult:
        """Build every target of ``goal``; failures end up in ``result.failure``."""
        supports = target_supports(goal)
        try:
            while len(self.memory.placed) < len(goal.targets):
                self._place_one(supports)
        except BUILD_STOPPERS as error:
            self.result.failure = failure_of(error, self.memory.step)
        return self.result

    def _place_one(self, supports: Mapping[int, tuple[int, ...]]) -> None:
        feedback = ""
        for regrasps in range(self.budgets.regrasps + 1):
            self.memory = self.memory.model_copy(
                update={
                    "retries": {},
                    "last_feedback": feedback,
                    "regrasps": regrasps,
                    "this_brick": (),
                    "phase": None,
                }
            )
            self._check_bricks_left()
            brick, target = self._stage(
                Stage.PRE_GRASP, PreGraspAnswer, partial(self._pre_grasp, supports=supports)
            )
            grasp_pose = self._stage(
                Stage.DESCENT, DescentAnswer, partial(self._descent, brick=brick)
            )
            self._stage(
                Stage.GRASP, GraspAnswer, partial(self._grasp, brick=brick, pose=grasp_pose)
            )
            try:
                lifted = self._stage(
                    Stage.LIFT, LiftAnswer, partial(self._lift, brick=brick, grasp=grasp_pose)
                )
                self._placement(brick, target, grasp_pose, lifted)
                break
            except _Regrasp as regrasp:
                feedback = str(regrasp)
        else:
            raise TrialStopped(FailureCode.GRASP_SLIP, self.memory.step, "re-grasp budget spent")
        self._stage(Stage.RELEASE, ReleaseAnswer, partial(self._release, brick=brick))
        placed = (*self.memory.placed, PlacedBrick(brick_id=brick, target_index=target))
        self.memory = self.memory.model_copy(
            update={"placed": placed, "current_brick": None, "current_target": None}
        )
        self.result.placements[target] = brick

    def _check_bricks_left(self) -> None:
        """Stop the trial if no unused brick can be picked (each toppled or fell on others)."""
        used = tuple(p.brick_id for p in self.memory.placed)
        state = self.world.observe(Progress(placed_ids=used, step=Stage.PRE_GRASP))
        unused = [b for b in state.bricks if b.id not in used]
        if not any(b.pickable for b in unused):
            statuses = ", ".join(f"brick {b.id} {b.status}" for b in unused)
            raise TrialStopped(
                FailureCode.NO_BRICK_LEFT, Stage.PRE_GRASP, f"none can be picked: {statuses}"
            )

    def _stage(
        self,
        key: Stage,
        answers: type[A],
        act: Callable[[A, WorldState], T],
        label: Stage | None = None,
    ) -> T:
        """Ask agent ``key``, which ``answers`` with that model, until ``act`` accepts its
        answer, within the retry budget.

        ``label`` names the finished stage for the stage hook (default: ``key``).
        """
        self.memory = self.memory.model_copy(update={"step": key})
        reason = FailureCode.BUDGET_EXHAUSTED
        for attempt in range(1, self.budgets.attempts_per_agent + 1):
            answer, state = self.calls.ask(self.specs[key], self.memory, attempt, answers)
            try:
                outcome = act(answer, state)
            except _Refused as refusal:
                reason = refusal.reason
                self._remember(key, attempt, str(refusal))
                continue
            except UnreachableError as error:
                reason = FailureCode.UNREACHABLE
                self._remember(key, attempt, f"unreachable: {error}")
                continue
            except _Regrasp as regrasp:
                self.calls.conclude(Outcome.REGRASP, str(regrasp))
                raise
            self.calls.conclude(Outcome.ACCEPTED)
            earlier = (*self.memory.this_brick, EarlierAnswer.of(key, answer))
            self.memory = self.memory.model_copy(
                update={"last_feedback": "", "this_brick": earlier}
            )
            if self.on_stage is not None and self.memory.current_brick is not None:
                self.on_stage(self.memory.current_brick, label or key)
            return outcome
        raise TrialStopped(
            reason,
            key,
            f"{self.budgets.attempts_per_agent} answers refused; last: {self.memory.last_feedback}",
        )

    def _remember(self, key: Stage, attempt: int, feedback: str) -> None:
        self.calls.conclude(Outcome.REFUSED, feedback)
        retries = {**self.memory.retries, key: attempt}
        self.memory = self.memory.model_copy(update={"retries": retries, "last_feedback": feedback})

    def _gate(self, verdict: gates.GateVerdict, reason: FailureCode) -> None:
        """Record a verdict and refuse the answer (failure code ``reason``) if it failed."""
        if not self.calls.judge(verdict).passed:
            raise _Refused(verdict.feedback, reason)

    # --- the agents' acts ---------------------------------------------------------------
    def _pre_grasp(
        self, answer: PreGraspAnswer, state: WorldState, supports: Mapping[int, tuple[int, ...]]
    ) -> tuple[int, int]:
        if answer.brick_id is None or answer.target_index is None or answer.waypoint is None:
            raise _Refused("the answer needs brick_id, target_index and waypoint")
        built = {p.target_index for p in self.memory.placed}
        used = {p.brick_id for p in self.memory.placed}
        target, brick = answer.target_index, answer.brick_id
        if target >= len(state.goal.targets) or target in built:
            raise _Refused(
                f"target {target} does not exist or is already built", FailureCode.INVALID_CHOICE
            )
        missing = [t for t in supports[target] if t not in built]
        if missing:
            raise _Refused(
                f"target {target} rests on targets {missing}, not built yet",
                FailureCode.INVALID_CHOICE,
            )
        if brick in used or brick not in {b.id for b in state.bricks}:
            raise _Refused(
                f"brick {brick} does not exist or is already placed", FailureCode.INVALID_CHOICE
            )
        if not state.brick(brick).pickable:
            raise _Refused(
                f"brick {brick} is {state.brick(brick).status}, neither in the pick area nor "
                "lying on the ground",
                FailureCode.INVALID_CHOICE,
            )
        waypoint = _checked(answer.waypoint, path="joint")
        path = self._clearance(state, waypoint, ignore=brick)
        self._gate(gates.sigma1_pre_grasp(path, self.tol), FailureCode.COLLISION)
        self.memory = self.memory.model_copy(
            update={"current_brick": brick, "current_target": target}
        )
        self.world.move(waypoint)
        return brick, target

    def _descent(self, answer: DescentAnswer, state: WorldState, brick: int) -> WaypointProposal:
        if answer.gripper_opening_m is None or answer.waypoint is None:
            raise _Refused("the answer needs gripper_opening_m and waypoint")
        waypoint = _checked(answer.waypoint, path="linear")
        width = state.brick(brick).size_m[1]
        if answer.gripper_opening_m < width + self.tol.delta_m:
            raise _Refused(
                f"opening {answer.gripper_opening_m:.3f} m < brick width {width:.3f} + delta"
            )
        path = self._clearance(
            state,
            waypoint,
            start=state.robot.ee_pose,
            opening=answer.gripper_opening_m,
            ignore=brick,
        )
        if not self.tol.clear(path.clearance_m, path.reachable):
            raise _Refused(
                f"descent path collides: {path.closest} ({path.clearance_m:.3f} m)",
                FailureCode.COLLISION,
            )
        self.world.grip(answer.gripper_opening_m)
        self.world.move(waypoint)
        after = self.world.observe(Progress(current_brick=brick, step=Stage.DESCENT))
        pads = self.calls.measure(after, FINGER_CONTACTS, BrickQuery(brick_id=brick))
        shift = math.dist(
            after.brick(brick).pose.position_m[:2], state.brick(brick).pose.position_m[:2]
        )
        sigma2 = gates.sigma2_descent(after.robot.gripper_width_m, width, pads, shift, self.tol)
        self._gate(sigma2, FailureCode.DESCENT_BLOCKED)
        return waypoint

    def _grasp(
        self, answer: GraspAnswer, state: WorldState, brick: int, pose: WaypointProposal
    ) -> None:
        if not answer.close:
            raise _Refused("the gripper is at the grasp pose: answer close = true")
        self.world.grip(None)
        after = self.world.observe(Progress(current_brick=brick, step=Stage.GRASP))
        pads = self.calls.measure(after, FINGER_CONTACTS, BrickQuery(brick_id=brick))
        slip = self.calls.measure(after, SLIP, BrickQuery(brick_id=brick))
        offset = math.hypot(*slip.offset_in_gripper_m)
        turn = math.degrees(
            abs(
                _wrap_half_turn(
                    quat_yaw(after.robot.ee_pose.quat_xyzw)
                    - quat_yaw(after.brick(brick).pose.quat_xyzw)
                )
            )
        )
        verdict = self.calls.judge(gates.sigma3_grasp(pads, offset, turn, self.tol))
        if not verdict.passed:
            self.world.grip(GRIPPER_GAP_M[1])
            raise _Refused(verdict.feedback, FailureCode.GRASP_FAILED)

    def _lift(
        self, answer: LiftAnswer, state: WorldState, brick: int, grasp: WaypointProposal
    ) -> WaypointProposal:
        if answer.waypoint is None:
            raise _Refused("the answer needs a waypoint")
        waypoint = _checked(answer.waypoint, path="linear")
        self._gate(self._lift_plan(state, brick, waypoint), FailureCode.COLLISION)
        self.world.move(waypoint)
        after = self.world.observe(Progress(current_brick=brick, step=Stage.LIFT))
        slip = self.calls.measure(after, SLIP, BrickQuery(brick_id=brick))
        pads = self.calls.measure(after, FINGER_CONTACTS, BrickQuery(brick_id=brick))
        verdict = self.calls.judge(gates.sigma4_lift(slip, pads, self.tol))
        if not verdict.passed:
            self._put_back(brick, grasp, waypoint)
            raise _Regrasp(verdict.feedback)
        return waypoint

    def _lift_plan(
        self, state: WorldState, brick: int, lift: WaypointProposal
    ) -> gates.GateVerdict:
        """The lift's plan checked before it moves (see :func:`gates.lift_plan`)."""
        tool = state.robot.ee_pose
        x, y, z = tool.position_m
        rise = lift.position_m[2] - z
        start = WaypointProposal(position_m=(x, y, z + LIFT_CHECK_FROM_M), quat_xyzw=tool.quat_xyzw)
        held = state.brick(brick)
        others = [b.pose.position_m[2] + b.size_m[2] / 2 for b in state.bricks if b.id != brick]
        bottom = held.pose.position_m[2] - held.size_m[2] / 2 + rise
        return gates.lift_plan(
            sideways_m=math.hypot(lift.position_m[0] - x, lift.position_m[1] - y),
            turn_deg=rotation_deg(tool.quat_xyzw, lift.quat_xyzw),
            path=self._clearance(state, lift, start=start),
            bottom_clearance_m=bottom - max(others, default=0.0),
            tol=self.tol,
        )

    def _put_back(self, brick: int, spot: WaypointProposal, lifted: WaypointProposal) -> None:
        """Put the held brick back flat on ``spot``, where it was grasped (sigma_4 = 0)."""
        self.put_down.put_back(self._observer(brick), brick, _as_pose(spot), lifted.position_m[2])

    def _set_aside(self, brick: int, grasp: WaypointProposal, lifted: WaypointProposal) -> None:
        """Put the held brick down on the free ground nearest the tool (Ag5 asked for a
        re-grasp): a loose brick swings further on every move, so it is not carried back.
        Where no free ground near by is within reach, it goes back where it was grasped."""
        state = self.world.observe(Progress(current_brick=brick, step=self.memory.step))
        built = {p.target_index for p in self.memory.placed}
        height = lifted.position_m[2]
        spot = None
        if state.brick(brick).status == "grasped":
            spot = self.put_down.free_spot(state, brick, built, _as_pose(grasp), height)
        self.put_down.put_back(self._observer(brick), brick, spot or _as_pose(grasp), height)

    def _observer(self, brick: int) -> Callable[[], WorldState]:
        """Measures the world with ``brick`` as the current one, at the current step."""
        return partial(self.world.observe, Progress(current_brick=brick, step=self.memory.step))

    def _placement(
        self, brick: int, target: int, grasp: WaypointProposal, lifted: WaypointProposal
    ) -> None:
        """Ag5 twice: carry the brick over its slot, then, re-measured there, set it down.

        Either call may answer ``regrasp``: the brick is set aside on free ground near by and
        the cycle starts again at Ag1 (a brick that rolled in the hand is grasped level).
        """
        back = partial(self._set_aside, brick, grasp, lifted)
        self._placement_phase(PlacementPhase.CARRY)
        self._stage(
            Stage.PLACEMENT,
            PlacementAnswer,
            partial(self._carry_over_slot, brick=brick, back=back),
            label=Stage.TRANSFER,
        )
        self._placement_phase(PlacementPhase.SET_DOWN)
        failed = ""  # the last sigma_5 verdict's failed checks: the failure's detail
        for _ in range(self.budgets.placement_attempts):
            slot, motion = self._stage(
                Stage.PLACEMENT, PlacementAnswer, partial(self._set_down, brick=brick, back=back)
            )
            state = self.world.observe(Progress(current_brick=brick, step=Stage.PLACEMENT))
            errors = self.calls.measure(
                state, ALIGNMENT, AlignmentQuery(brick_id=brick, target_index=target)
            )
            verdict = self.calls.judge(gates.sigma5_placement(errors, self.tol))
            if verdict.passed:
                self._placement_phase(None)
                return
            failed = verdict.feedback
            feedback = f"{failed}; {_touch_down(motion, state, slot)}"
            self.calls.conclude(Outcome.RAISED, feedback)
            # Misaligned in contact: raise by delta_h and ask Ag5 again.
            x, y, z = state.robot.ee_pose.position_m
            up = WaypointProposal(
                position_m=(x, y, z + self.tol.delta_h_m), quat_xyzw=slot.quat_xyzw, path="linear"
            )
            self.world.move(up)
            self.memory = self.memory.model_copy(update={"last_feedback": feedback})
        raise TrialStopped(FailureCode.PLACEMENT_MISALIGNED, Stage.PLACEMENT, failed)

    def _placement_phase(self, phase: PlacementPhase | None) -> None:
        """Tell Ag5 which of its calls comes next (None: it is done with this brick)."""
        self.memory = self.memory.model_copy(update={"phase": phase})

    def _carry_over_slot(
        self, answer: PlacementAnswer, state: WorldState, brick: int, back: Callable[[], None]
    ) -> None:
        """Carry the brick over the proposed slot, once the way there and down is clear, and
        lower it to HOVER_M above the slot."""
        self._regrasp_if_asked(answer, state, brick, back)
        slot = self._slot(answer)
        above = _above(slot, state)
        transfer = self._clearance(state, above)
        self._check_descent(state, slot, start=above, path=transfer)
        self.world.move(above)
        x, y, z = slot.position_m
        if above.position_m[2] > z + HOVER_M:
            self.world.move(
                WaypointProposal(
                    position_m=(x, y, z + HOVER_M), quat_xyzw=slot.quat_xyzw, path="linear"
                )
            )

    def _regrasp_if_asked(
        self, answer: PlacementAnswer, state: WorldState, brick: int, back: Callable[[], None]
    ) -> None:
        """Ag5 asked for a re-grasp: put the brick back and start again at Ag1."""
        if not answer.regrasp:
            return
        tilt = self.calls.measure(state, SLIP, BrickQuery(brick_id=brick)).tilt_in_hand_deg
        back()
        raise _Regrasp(
            f"placement asked for a re-grasp; the brick had rolled {tilt:.1f} deg in the hand"
        )

    def _set_down(
        self, answer: PlacementAnswer, state: WorldState, brick: int, back: Callable[[], None]
    ) -> tuple[WaypointProposal, Motion]:
        """Set the brick down on the (re-measured) slot: over it, then straight down onto it.
        Returns the slot and what the way down did."""
        self._regrasp_if_asked(answer, state, brick, back)
        slot = self._slot(answer)
        above = _above(slot, state, path="linear")
        shift = self._clearance(state, above, start=state.robot.ee_pose)
        self._check_descent(state, slot, start=above, path=shift)
        self.world.move(above)
        # Onto the slot itself, pressed flat by the position controller; the guard stops the
        # move early if the brick meets its support above the slot.
        down = self.world.move(slot.model_copy(update={"path": "linear"}), stop_on_contact=brick)
        return slot, down

    @staticmethod
    def _slot(answer: PlacementAnswer) -> WaypointProposal:
        if answer.waypoint is None:
            raise _Refused("the answer needs a waypoint")
        return _checked(answer.waypoint)

    def _check_descent(
        self,
        state: WorldState,
        slot: WaypointProposal,
        start: WaypointProposal,
        path: CollisionReport | None = None,
    ) -> None:
        """Refuse a slot whose way down (and ``path`` to its start, if given) collides.

        The set-down ends in contact by design: the check goes to just above the seat.
        """
        x, y, z = slot.position_m
        near = WaypointProposal(position_m=(x, y, z + SEAT_CLEARANCE_M), quat_xyzw=slot.quat_xyzw)
        descent = self._clearance(state, near, start=start)
        for report in (path, descent):
            if report is not None and not self.tol.clear(report.clearance_m, report.reachable):
                raise _Refused(
                    f"path to the slot collides: {report.closest}", FailureCode.COLLISION
                )

    def _clearance(
        self,
        state: WorldState,
        to: WaypointProposal,
        start: WaypointProposal | Pose | None = None,
        opening: float | None = None,
        ignore: int | None = None,
        joint: bool = False,
    ) -> CollisionReport:
        """Clearance on the way to ``to``: straight from ``start`` if given (a joint move from
        it if ``joint``), else a joint move from where the arm is; at ``opening`` (default: the
        gripper's now), the held brick carried, brick ``ignore`` left out."""
        query = CollisionQuery(
            pose=_as_pose(to),
            start_pose=None if start is None else _as_pose(start),
            path="joint" if joint or start is None else "linear",
            gripper_opening_m=state.robot.gripper_width_m if opening is None else opening,
            ignore_brick_id=ignore,
        )
        return self.calls.measure(state, COLLISION, query)

    def _release(self, answer: ReleaseAnswer, state: WorldState, brick: int) -> None:
        if answer.gripper_opening_m is None or answer.waypoint is None:
            raise _Refused("the answer needs gripper_opening_m and waypoint")
        ready = _checked(answer.waypoint)
        x, y, z = state.robot.ee_pose.position_m
        retreat = WaypointProposal(
            position_m=(x, y, z + RETREAT_M), quat_xyzw=state.robot.ee_pose.quat_xyzw, path="linear"
        )
        way_up = self._clearance(
            state,
            retreat,
            start=state.robot.ee_pose,
            opening=answer.gripper_opening_m,
            ignore=brick,
        )
        onward = self._clearance(
            state,
            ready,
            start=retreat,
            opening=answer.gripper_opening_m,
            ignore=brick,
            joint=True,
        )
        self._gate(gates.sigma6_return(way_up, onward, self.tol), FailureCode.COLLISION)
        self.world.grip(answer.gripper_opening_m)
        self.world.move(retreat)
        self.world.move(ready)


def _above(slot: WaypointProposal, state: WorldState, path: str = "joint") -> WaypointProposal:
    """The tool over ``slot`` at the current height (or the slot's, if higher)."""
    x, y, z = slot.position_m
    height = max(state.robot.ee_pose.position_m[2], z)
    return slot.model_copy(update={"position_m": (x, y, height), "path": path})


def _touch_down(motion: Motion, after: WorldState, slot: WaypointProposal) -> str:
    """How the set-down ended, as measured: stopped on contact (where), or ran to the slot."""
    if not motion.stopped_on_contact:
        return "the set-down ran all the way to the slot: the brick met no support that stopped it"
    z = after.robot.ee_pose.position_m[2]
    return (
        f"the set-down stopped on contact with the tool at z = {z:.4f} m, "
        f"{(z - slot.position_m[2]) * 1000:.1f} mm above the slot"
    )


def _as_pose(waypoint: WaypointProposal | Pose) -> Pose:
    return Pose(position_m=waypoint.position_m, quat_xyzw=waypoint.quat_xyzw)


def _checked(waypoint: WaypointProposal, path: str | None = None) -> WaypointProposal:
    """A waypoint with a unit quaternion (normalised within tolerance, else refused)."""
    try:
        return unit_waypoint(waypoint, path)
    except ValueError as error:
        raise _Refused(str(error)) from None


def _wrap_half_turn(angle_rad: float) -> float:
    """An angle modulo pi, into [-pi/2, pi/2): a gripper turned 180 deg grips the same."""
    return (angle_rad + math.pi / 2.0) % math.pi - math.pi / 2.0
