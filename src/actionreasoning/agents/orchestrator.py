"""The gated orchestrator: six agents per brick, each output verified and gated.

Per brick: Ag1 pre-grasp -> Ag2 descent & opening -> Ag3 grasp -> Ag4 safe lift ->
Ag5 placement -> Ag6 release & return. An answer is first validated (schema, workspace,
unit quaternion, known ids) and verified before the world moves (its pre-move checks,
``plans.py``: a choice that can be built, a pose the next gate will accept, a clear and
reachable path, a speed within the measured limits); the gate sigma_i then judges what was
measured afterwards. A refusal goes back to the same agent as feedback (:class:`Refusal`:
the failed checks with the measured errors, signed, in the world frame), within a retry
budget. sigma_4 = 0, or Ag5 asking for a re-grasp, sets the brick aside on free ground near
by, where it can be grasped again, and the cycle starts again at Ag1. sigma_5 = 0 in
contact raises the brick by delta_h and asks Ag5 again. A spent budget ends the trial with
a typed failure.

The same loop runs the single-agent ablation (``single_agent=True``): one merged agent
answers every stage, with the same moves and controller primitives (the hover over the
slot, the guarded set-down, the retreat, the settle hold), the same validation and the
same retry budget. What refuses an answer is the rung of verification
(:class:`~actionreasoning.agents.verification.Verification`): a verdict the rung does not
enforce is measured and recorded, and its answer runs as given.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import NoReturn, TypeVar, get_args

from pydantic import NonNegativeInt, PositiveInt
from scipy.spatial.transform import Rotation

from actionreasoning.agents import gates, plans
from actionreasoning.agents.calls import (
    BUILD_STOPPERS,
    AgentCaller,
    BuildResult,
    CallHook,
    StageHook,
    TrialStopped,
    failure_of,
)
from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.feedback import Measured, Refusal
from actionreasoning.agents.gates import Check, GateVerdict
from actionreasoning.agents.memory import (
    PlacedBrick,
    PlacementPhase,
    RollWatch,
    StepDecision,
    TaskMemory,
)
from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
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
    SingleAgentStep,
    WaypointProposal,
    placement_decision,
    stage_answer,
    unit_waypoint,
)
from actionreasoning.agents.put_down import PutDown
from actionreasoning.agents.reasoner import Reasoner
from actionreasoning.agents.spec import AgentSpec, agent_specs, single_agent_spec
from actionreasoning.agents.tiers import DEFAULT_TIER, ToolTier
from actionreasoning.agents.transcript import Outcome, Perceived
from actionreasoning.agents.validation import OutputError, check_answer, complete
from actionreasoning.agents.verification import Verification
from actionreasoning.agents.view import target_supports
from actionreasoning.agents.world import World
from actionreasoning.errors import UnreachableError
from actionreasoning.records import FailureCode
from actionreasoning.tools import formulas
from actionreasoning.tools.collision import COLLISION, CollisionQuery, CollisionReport
from actionreasoning.tools.contact import FINGER_CONTACTS, SLIP
from actionreasoning.tools.geometry import (
    ALIGNMENT,
    AlignmentErrors,
    AlignmentQuery,
    BrickQuery,
    alignment_of,
)
from actionreasoning.tools.placement import PLACEMENT_POSE, SEAT_CLEARANCE_M, PlacementQuery
from actionreasoning.world.geometry import Vec3, quat_yaw, rotation_deg, round_floats, wrap_angle
from actionreasoning.world.models import (
    BrickState,
    BrickStatus,
    GoalPattern,
    Pose,
    Progress,
    WorldState,
    highest_under,
)
from actionreasoning.world.motion import CARRY_SPEED_MPS, Motion
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, RETREAT_M, WORKSPACE
from actionreasoning.world.stages import Stage
from actionreasoning.world.tolerances import LIFT_SUPPORT_M, Tolerances

T = TypeVar("T")
D = TypeVar("D", bound=AgentAnswer)

#: Decimals an earlier agent's decision is recalled to in memory: a millimetre, a
#: thousandth of a quaternion (the state shows what is measured to 0.01 mm).
MEMORY_DIGITS = 3
#: How long a brick still moving in the hand after the lift is held still before sigma_4
#: judges it: a swing of a brick hanging from a pad dies out within about half a second.
SETTLE_S = 0.5
#: How long the held brick is watched over the slot before each set-down, between the two
#: measurements of its roll that give its roll rate (Formulas: roll rate). The set-down
#: touches down about 2 s after its answer, and sigma_5 seats a brick tilted at most
#: eps_tilt_deg (2.5 deg), so the rate must be known to about 1 deg/s: 0.25 deg of roll over
#: the watch, far above what the roll is measured to (quaternions shown to 1e-5, perception
#: noise on yaw only). A longer watch costs cycle time and lets the brick roll further.
ROLL_WATCH_S = 0.25
#: How far a set-down's hover steps down where the arm cannot reach it at the carry height
#: (a brick rolled far in the hand needs the tool tilted far, which the arm's reach allows
#: only lower down): the reach changes smoothly with height, and a centimetre more descent
#: is 0.03 s at the carry speed, so a finer step buys nothing.
HOVER_STEP_M = 0.01


@dataclass(frozen=True)
class Budgets:
    """Retry budgets of a trial."""

    attempts_per_agent: PositiveInt = 3
    regrasps: NonNegativeInt = 4
    placement_attempts: PositiveInt = 4
    #: Bricks found off their targets (sigma_6 at rest, sigma_1 re-measuring the placed ones)
    #: withdrawn and built again, per trial: each costs a brick's cycle (about 31 s of the
    #: trial's simulated time), so two keep a six-brick trial within 1.4 times its length.
    repairs: NonNegativeInt = 2


class _Refused(Exception):
    """An answer refused by validation, verification or a gate, with what was measured.

    ``reason`` is the failure code the trial ends with if the agent's budget runs out;
    ``category`` the answer's error category where no recorded verdict tells it (None: the
    transcript takes it from the failed gate).
    """

    def __init__(
        self,
        refusal: Refusal,
        reason: FailureCode = FailureCode.INVALID_OUTPUT,
        category: ErrorCategory | None = None,
    ) -> None:
        super().__init__(refusal.text())
        self.refusal = refusal
        self.reason = reason
        self.category = category


class _Regrasp(Exception):
    """The brick was put down to be grasped again: start again at Ag1 with this refusal
    (``category`` as for :class:`_Refused`)."""

    def __init__(self, refusal: Refusal, category: ErrorCategory | None = None) -> None:
        super().__init__(refusal.text())
        self.refusal = refusal
        self.category = category


#: The six agents' stages, in the order of a brick's cycle: the single agent's steps.
AGENT_STAGES: tuple[Stage, ...] = get_args(SingleAgentStep)


class Orchestrator:
    """Runs the six agents (or, with ``single_agent``, the merged agent at every stage)
    over a goal, brick by brick, against a :class:`World`.

    ``tolerances`` are the design thresholds; a build runs under them as widened for the
    world's sensing noise and narrowed for the goal's joints (:class:`Tolerances`). ``tier``
    is the reasoning tier: which tools and formulas the agents get; ``verify`` the rung of
    verification: which verdicts refuse an answer; ``observation`` what the agents observe of
    the scene (the state's poses, the cameras' pictures or both)."""

    def __init__(
        self,
        world: World,
        reasoner: Reasoner,
        tolerances: Tolerances = Tolerances(),
        budgets: Budgets = Budgets(),
        on_stage: StageHook | None = None,
        on_call: CallHook | None = None,
        tier: ToolTier = DEFAULT_TIER,
        verify: Verification = Verification.FULL,
        single_agent: bool = False,
        observation: Observation = DEFAULT_OBSERVATION,
    ) -> None:
        self.world = world
        self.reasoner = reasoner
        self.design = tolerances
        self.tol = tolerances.under(world.sensing)
        self.budgets = budgets
        self.on_stage = on_stage
        self.verify = verify
        self.single_agent = single_agent
        self.specs: dict[Stage, AgentSpec] = (
            dict.fromkeys(AGENT_STAGES, single_agent_spec(tier, observation))
            if single_agent
            else {Stage(spec.key): spec for spec in agent_specs(tier, observation)}
        )
        self.result = BuildResult()
        self.calls = AgentCaller(world, reasoner, self.tol, self.result, on_call)
        self.put_down = PutDown(world, self.calls, in_sight=not observation.poses)
        self.memory = TaskMemory()
        #: When the held brick, creeping in the hand faster than v_th, would leave it (state
        #: time, s); None when it creeps no faster.
        self._held_until_s: float | None = None
        #: Bricks withdrawn to be built again so far (Budgets.repairs).
        self._repairs = 0

    # --- the pipeline -------------------------------------------------------------------
    def build(self, goal: GoalPattern) -> BuildResult:
        """Build every target of ``goal``; failures end up in ``result.failure``."""
        self.tol = self.calls.tol = self.design.for_goal(goal).under(self.world.sensing)
        supports = target_supports(goal)
        try:
            while len(self.memory.placed) < len(goal.targets):
                self._place_one(supports)
        except BUILD_STOPPERS as error:
            self.result.failure = failure_of(error, self.memory.step)
        return self.result

    def _place_one(self, supports: Mapping[int, tuple[int, ...]]) -> None:
        for regrasps in range(self.budgets.regrasps + 1):
            self.memory = self.memory.model_copy(
                update={
                    "retries": {},
                    "regrasps": regrasps,
                    "this_brick": (),
                    "phase": None,
                    "roll_watch": None,
                }
            )
            self._check_bricks_left(supports)
            seen = not self.specs[Stage.PRE_GRASP].observation.poses
            brick, target = self._stage(
                Stage.PRE_GRASP,
                PreGraspSeenDecision.of if seen else PreGraspDecision.of,
                partial(self._pre_grasp, supports=supports),
            )
            self._stage(Stage.DESCENT, DescentDecision.of, partial(self._descent, brick=brick))
            grasp_pose = self._stage(Stage.GRASP, GraspAnswer.of, partial(self._grasp, brick=brick))
            try:
                lifted = self._stage(
                    Stage.LIFT, LiftDecision.of, partial(self._lift, brick=brick, grasp=grasp_pose)
                )
                self._placement(brick, target, grasp_pose, lifted)
                break
            except _Regrasp as regrasp:
                self._note(regrasp.refusal)
        else:
            raise TrialStopped(FailureCode.GRASP_SLIP, self.memory.step, "re-grasp budget spent")
        self._stage(Stage.RELEASE, ReleaseDecision.of, partial(self._release, brick=brick))
        if self._withdrawn(brick, target):
            return
        placed = (*self.memory.placed, PlacedBrick(brick_id=brick, target_index=target))
        self.memory = self.memory.model_copy(
            update={
                "placed": placed,
                "current_brick": None,
                "current_target": None,
                "last_feedback": "",
                "refusals": (),
            }
        )
        self.result.placements[target] = brick

    def _withdrawn(self, brick: int, target: int) -> bool:
        """sigma_6 at rest: the released brick, once the arm has left it, as the success
        rule will judge it. One found off its target (or still moving) is repaired where it
        can be (:meth:`_repair`); returns whether it was withdrawn for that."""
        others = tuple(p.brick_id for p in self.memory.placed)
        state = self.world.observe(Progress(placed_ids=others, step=Stage.RELEASE))
        errors = self.calls.measure(
            state, ALIGNMENT, AlignmentQuery(brick_id=brick, target_index=target)
        )
        released = state.brick(brick)
        verdict = gates.sigma6_at_rest(
            errors,
            math.hypot(*released.linear_velocity_mps),
            math.hypot(*released.angular_velocity_radps),
            self.tol,
        )
        if not self._refuses(verdict):
            return False
        refusal = self._repair(brick, target, verdict.refusal(Stage.RELEASE), "after its release")
        if refusal is None:
            return False
        self.memory = self.memory.model_copy(
            update={"current_brick": None, "current_target": None, "last_feedback": ""}
        )
        self._note(refusal)
        return True

    def _check_placed(self, state: WorldState, supports: Mapping[int, tuple[int, ...]]) -> None:
        """sigma_1 re-measures the bricks already placed (in ``state``, Ag1's) before a new
        brick is picked: the one furthest off its target, against the success rule's offset
        and rotation. One found off that carries no placed brick is repaired where it can be
        (:meth:`_repair`), and Ag1's answer refused with the refusal naming it."""
        if not self.memory.placed:
            return

        def errors(placed: PlacedBrick) -> AlignmentErrors:
            query = AlignmentQuery(brick_id=placed.brick_id, target_index=placed.target_index)
            return self.calls.measure(state, ALIGNMENT, query)

        measured = [(placed, errors(placed)) for placed in self.memory.placed]
        placed, worst = max(
            measured,
            key=lambda pair: max(
                pair[1].offset_m / self.tol.max_offset_m,
                pair[1].rotation_deg / self.tol.max_rotation_deg,
            ),
        )
        verdict = gates.sigma1_placed(worst, self.tol).noted(
            f"brick {placed.brick_id} on target {placed.target_index}, the furthest off of the "
            "bricks placed"
        )
        carries = any(placed.target_index in supports[p.target_index] for p in self.memory.placed)
        if not self._refuses(verdict) or carries:
            return
        refusal = self._repair(
            placed.brick_id, placed.target_index, verdict.refusal(Stage.PRE_GRASP), "since"
        )
        if refusal is not None:
            raise _Refused(refusal, FailureCode.INVALID_CHOICE, ErrorCategory.WRONG_CHOICE)

    def _repair(self, brick: int, target: int, refusal: Refusal, when: str) -> Refusal | None:
        """Withdraw brick ``brick`` from target ``target`` to set it right, if it lies free on
        the ground (as measured without it placed) and the trial's repair budget is not
        spent: its target is built again, and the returned refusal names the brick in the
        way, so that it is picked first. None: it stays placed, for the success rule."""
        others = tuple(p.brick_id for p in self.memory.placed if p.brick_id != brick)
        state = self.world.observe(Progress(placed_ids=others, step=self.memory.step))
        if not state.brick(brick).pickable or self._repairs == self.budgets.repairs:
            return None
        self._repairs += 1
        self.memory = self.memory.model_copy(
            update={"placed": tuple(p for p in self.memory.placed if p.brick_id != brick)}
        )
        self.result.placements.pop(target, None)
        note = (
            f"brick {brick} lies off target {target} {when}: it is picked again to set it "
            f"right (repair {self._repairs} of {self.budgets.repairs})"
        )
        in_the_way = f"target {target} vs brick {brick}"
        measured = refusal.measured.model_copy(update={"closest": in_the_way})
        return refusal.model_copy(update={"measured": measured, "note": note})

    def _check_bricks_left(self, supports: Mapping[int, tuple[int, ...]]) -> None:
        """Stop the trial if no unused brick can be picked (each toppled or fell on others),
        or, in a pattern of several brick sizes, none that fits a target buildable now."""
        used = tuple(p.brick_id for p in self.memory.placed)
        state = self.world.observe(Progress(placed_ids=used, step=Stage.PRE_GRASP))
        unused = [b for b in state.bricks if b.id not in used]
        if not any(b.pickable for b in unused):
            statuses = ", ".join(f"brick {b.id} {b.status}" for b in unused)
            raise TrialStopped(
                FailureCode.NO_BRICK_LEFT, Stage.PRE_GRASP, f"none can be picked: {statuses}"
            )
        built = {p.target_index for p in self.memory.placed}
        buildable = [
            t.index
            for t in state.goal.targets
            if t.index not in built and set(supports[t.index]) <= built
        ]
        if not any(b.pickable and state.goal.fits(b.size_m, t) for b in unused for t in buildable):
            raise TrialStopped(
                FailureCode.NO_BRICK_LEFT,
                Stage.PRE_GRASP,
                f"none that can be picked fits targets {buildable}, buildable now",
            )

    def _stage(
        self,
        key: Stage,
        decide: Callable[[AgentAnswer], D],
        act: Callable[[D, WorldState], T],
        label: Stage | None = None,
    ) -> T:
        """Ask agent ``key`` until ``act`` accepts the decision ``decide`` makes of its
        answer, within the retry budget.

        ``label`` names the finished stage for the stage hook (default: ``key``).
        """
        self.memory = self.memory.model_copy(update={"step": key})
        reason = FailureCode.BUDGET_EXHAUSTED
        for attempt in range(1, self.budgets.attempts_per_agent + 1):
            answer, state = self.calls.ask(self.specs[key], self.memory, attempt)
            try:
                decision = self._validate(key, answer, state, decide)
                outcome = act(decision, state)
            except _Refused as refusal:
                reason = refusal.reason
                self._remember(key, attempt, refusal.refusal, refusal.category)
                continue
            except UnreachableError as error:
                reason = FailureCode.UNREACHABLE
                verdict = GateVerdict(
                    "controller", (Check("reachable", 0.0, 1.0, at_most=False),)
                ).noted(f"unreachable: {error}")
                self._remember(key, attempt, self.calls.judge(verdict).refusal(key))
                continue
            except _Regrasp as regrasp:
                self.calls.conclude(Outcome.REGRASP, regrasp.refusal.text(), regrasp.category)
                raise
            self.calls.conclude(Outcome.ACCEPTED)
            self._remember_decision(key, decision)
            if self.on_stage is not None and self.memory.current_brick is not None:
                self.on_stage(self.memory.current_brick, label or key)
            return outcome
        raise TrialStopped(
            reason,
            key,
            f"{self.budgets.attempts_per_agent} answers refused; last: {self.memory.last_feedback}",
        )

    def _remember_decision(self, key: Stage, decision: AgentAnswer) -> None:
        """Keep m_i, the accepted decision of ``key`` and its verdicts, for the agents after
        it in this brick's cycle."""
        failed = tuple(g.gate for g in self.result.transcript[-1].gates if not g.passed)
        decided = decision.model_dump(
            mode="json", exclude={"rationale", "tool_calls"}, exclude_defaults=True
        )
        m_i = StepDecision.model_validate(
            {
                **round_floats(decided, MEMORY_DIGITS),
                "agent": key,
                "phase": self.memory.phase,
                "passed": not failed,
                "failed": failed,
            }
        )
        self.memory = self.memory.model_copy(
            update={"last_feedback": "", "this_brick": (*self.memory.this_brick, m_i)}
        )

    def _judged_after_acceptance(self, verdict: GateVerdict) -> None:
        """A verdict that did not refuse, judged after its answer was accepted (sigma_5 on
        the set-down): the answer's outcome (executed, if it failed unenforced) and its m_i
        take it too."""
        self.calls.conclude(Outcome.ACCEPTED)
        last = self.memory.this_brick[-1]
        failed = (*last.failed, *(() if verdict.passed else (verdict.gate,)))
        m_i = last.model_copy(update={"passed": not failed, "failed": failed})
        self.memory = self.memory.model_copy(
            update={"this_brick": (*self.memory.this_brick[:-1], m_i)}
        )

    def _remember(
        self, key: Stage, attempt: int, refusal: Refusal, category: ErrorCategory | None = None
    ) -> None:
        self.calls.conclude(Outcome.REFUSED, refusal.text(), category)
        self.memory = self.memory.model_copy(
            update={"retries": {**self.memory.retries, key: attempt}}
        )
        self._note(refusal)

    def _note(self, refusal: Refusal) -> None:
        """Keep ``refusal`` in memory: the next answers read it."""
        self.memory = self.memory.model_copy(
            update={
                "last_feedback": refusal.text(),
                "refusals": (*self.memory.refusals, refusal),
            }
        )

    def _validate(
        self, key: Stage, answer: AgentAnswer, state: WorldState, decide: Callable[[AgentAnswer], D]
    ) -> D:
        """The answer's decision, once it is valid data (as an LLM's answer is checked: a
        waypoint inside the workspace, a unit quaternion, known ids and tools) and complete
        (``answer_complete``: no decision field left out, as a tool turn leaves them)."""
        try:
            check_answer(answer, self.specs[key], state, WORKSPACE, normalise=False)
            if isinstance(answer, SingleAgentAnswer):
                answer = self._stage_answer(key, answer)
        except OutputError as error:
            verdict = _failed(f"{key}_answer", "valid_answer", str(error))
            self._refuse(verdict, key, category=error.category)
        try:
            return complete(decide, answer)
        except OutputError as error:
            self._refuse(_failed(f"{key}_answer", "answer_complete", str(error)), key)

    def _stage_answer(self, key: Stage, answer: SingleAgentAnswer) -> AgentAnswer:
        """The merged agent's answer as the answer of stage ``key``: its step must be the
        one asked (memory.step); the fields other stages answer are not read."""
        if answer.step != key:
            given = "no step" if answer.step is None else f"step {str(answer.step)!r}"
            raise OutputError(
                f"{given} answered; memory.step asks for {str(key)!r}: answer step = {str(key)!r}",
                ErrorCategory.SCHEMA,
            )
        return stage_answer(key, answer)

    def _refuses(self, verdict: GateVerdict) -> bool:
        """Record a verdict; whether it refuses the answer: it failed, and this rung of
        verification enforces it (one it does not is recorded, and the answer runs)."""
        enforced = self.verify.enforces(verdict.gate)
        return not self.calls.judge(verdict, enforced).passed and enforced

    def _gate(
        self,
        verdict: GateVerdict,
        key: Stage,
        reason: FailureCode = FailureCode.INVALID_OUTPUT,
        category: ErrorCategory | None = None,
    ) -> None:
        """Record a verdict and refuse the answer of ``key`` (failure code ``reason``, error
        ``category`` if the verdict does not tell it) if it refuses it."""
        if self._refuses(verdict):
            raise _Refused(verdict.refusal(key), reason, category)

    def _refuse(
        self, verdict: GateVerdict, key: Stage, category: ErrorCategory | None = None
    ) -> NoReturn:
        """Record a failed verdict and refuse the answer of ``key`` (an invalid output)."""
        self.calls.judge(verdict)
        raise _Refused(verdict.refusal(key), category=category)

    # --- the agents' acts ---------------------------------------------------------------
    def _pre_grasp(
        self,
        answer: PreGraspDecision | PreGraspSeenDecision,
        state: WorldState,
        supports: Mapping[int, tuple[int, ...]],
    ) -> tuple[int, int]:
        key = Stage.PRE_GRASP
        self._check_placed(state, supports)
        if isinstance(answer, PreGraspSeenDecision):
            answer = self._named(answer, state)
        self._perceived(Stage.PRE_GRASP, answer.waypoint, state.brick(answer.brick_id))
        self._gate(
            self._choice(answer.brick_id, answer.target_index, state, supports),
            key,
            FailureCode.INVALID_CHOICE,
        )
        brick = state.brick(answer.brick_id)
        waypoint = _checked(key, answer.waypoint, path="joint")
        widest = GRIPPER_GAP_M[1]
        self._gate(plans.approach_plan(_as_pose(waypoint), brick, widest, self.tol), key)
        path = self._clearance(state, waypoint, ignore=brick.id)
        self._gate(gates.sigma1_pre_grasp(path, self.tol), key, FailureCode.COLLISION)
        self.memory = self.memory.model_copy(
            update={"current_brick": brick.id, "current_target": answer.target_index}
        )
        self.world.move(waypoint)
        return brick.id, answer.target_index

    def _named(self, answer: PreGraspSeenDecision, state: WorldState) -> PreGraspDecision:
        """The image tier's Ag1 answer with the brick it names by where it lies: the highest
        brick not yet placed whose measured footprint holds the approach pose's (x, y). An
        approach over no such brick names nothing and is refused, as a brick id that names
        nothing is, whatever the rung. The call is recorded as about that brick."""
        x, y = answer.waypoint.position_m[:2]
        used = {p.brick_id for p in self.memory.placed}
        free = [b for b in state.bricks if b.id not in used and b.status is not BrickStatus.QUEUED]
        brick = highest_under(free, x, y)
        if brick is None:
            verdict = GateVerdict(
                f"{Stage.PRE_GRASP}_choice",
                (Check("brick_under_approach", 0.0, 1.0, at_most=False),),
            ).noted(f"no brick but placed ones lies under the approach pose ({x:.3f}, {y:.3f}) m")
            self._refuse(verdict, Stage.PRE_GRASP)
        self.result.transcript[-1].brick = brick.id
        return PreGraspDecision(brick_id=brick.id, **dict(answer))

    def _perceived(self, key: Stage, waypoint: WaypointProposal, brick: BrickState) -> None:
        """With pictures, record how far the answer's pose of its brick (over its centre, at
        its yaw) was from the brick as measured."""
        if not self.specs[key].observation.pictures:
            return
        yaw = wrap_angle(2.0 * (quat_yaw(waypoint.quat_xyzw) - quat_yaw(brick.pose.quat_xyzw)))
        self.result.transcript[-1].perceived = Perceived(
            centre_offset_cm=100.0 * math.dist(waypoint.position_m[:2], brick.pose.position_m[:2]),
            yaw_error_deg=abs(math.degrees(yaw)) / 2.0,
        )

    def _choice(
        self, brick: int, target: int, state: WorldState, supports: Mapping[int, tuple[int, ...]]
    ) -> GateVerdict:
        """The target can be built now, the brick is free and, in a pattern of several
        brick sizes, of the target's size (Ag1's choice)."""
        built = {p.target_index for p in self.memory.placed}
        used = {p.brick_id for p in self.memory.placed}
        missing = [t for t in supports[target] if t not in built]
        free = brick not in used and state.brick(brick).pickable
        notes = []
        if target in built:
            notes.append(f"target {target} is already built")
        if missing:
            notes.append(f"target {target} rests on targets {missing}, not built yet")
        if not free:
            status = BrickStatus.PLACED if brick in used else state.brick(brick).status
            notes.append(f"brick {brick} is {status}, neither in the pick area nor on the ground")
        checks = [
            Check("target_buildable", float(target not in built and not missing), 1.0, False),
            Check("brick_free", float(free), 1.0, at_most=False),
        ]
        if len(state.goal.sizes) > 1:
            size = state.brick(brick).size_m
            fits = state.goal.fits(size, target)
            checks.append(Check("brick_fits_target", float(fits), 1.0, at_most=False))
            if not fits:
                wanted = state.goal.targets[target].size_m
                notes.append(
                    f"brick {brick} measures {_edges(size)} m; target {target} "
                    f"takes a brick of {_edges(wanted)} m"
                )
        return GateVerdict(f"{Stage.PRE_GRASP}_choice", tuple(checks)).noted("; ".join(notes))

    def _descent(self, answer: DescentDecision, state: WorldState, brick: int) -> None:
        key = Stage.DESCENT
        waypoint = _checked(key, answer.waypoint, path="linear")
        held = state.brick(brick)
        self._perceived(key, waypoint, held)
        tool = state.robot.ee_pose
        path = self._clearance(
            state, waypoint, start=tool, opening=answer.gripper_opening_m, ignore=brick
        )
        width = held.size_m[1]
        plan = plans.grip_plan(
            f"{key}_plan",
            tool,
            _as_pose(waypoint),
            held,
            answer.gripper_opening_m,
            path,
            self.tol,
            least_opening_m=width + self.tol.delta_m,
        )
        self._gate(plan, key, _failure_of(path, self.tol))
        self.world.grip(answer.gripper_opening_m)
        self.world.move(waypoint)
        after = self.world.observe(Progress(current_brick=brick, step=Stage.DESCENT))
        pads = self.calls.measure(after, FINGER_CONTACTS, BrickQuery(brick_id=brick))
        bx, by, _ = after.brick(brick).pose.position_m
        shift = (bx - held.pose.position_m[0], by - held.pose.position_m[1])
        sigma2 = gates.sigma2_descent(after.robot.gripper_width_m, width, pads, shift, self.tol)
        if self._refuses(sigma2):
            # Back up the way it came, so that the next descent starts above the brick again.
            self.world.move(
                WaypointProposal(
                    position_m=tool.position_m, quat_xyzw=tool.quat_xyzw, path="linear"
                )
            )
            raise _Refused(sigma2.refusal(key), FailureCode.DESCENT_BLOCKED)

    def _grasp(self, answer: GraspAnswer, state: WorldState, brick: int) -> WaypointProposal:
        """Close on the brick (at the answer's corrected pose, if any); returns where."""
        key = Stage.GRASP
        if not answer.close:
            note = "the gripper is at the grasp pose: answer close = true"
            self._gate(_failed(f"{key}_plan", "close", note), key)
        tool = state.robot.ee_pose
        at = WaypointProposal(position_m=tool.position_m, quat_xyzw=tool.quat_xyzw, path="linear")
        if answer.waypoint is not None:
            at = _checked(key, answer.waypoint, path="linear")
            path = self._clearance(state, at, start=tool, ignore=brick)
            opening = state.robot.gripper_width_m
            plan = plans.grip_plan(
                f"{key}_plan", tool, _as_pose(at), state.brick(brick), opening, path, self.tol
            )
            self._gate(plan, key)
            self.world.move(at)
        if answer.close:
            self.world.grip(None)
        after = self.world.observe(Progress(current_brick=brick, step=Stage.GRASP))
        pads = self.calls.measure(after, FINGER_CONTACTS, BrickQuery(brick_id=brick))
        slip = self.calls.measure(after, SLIP, BrickQuery(brick_id=brick))
        grip = Rotation.from_quat(after.robot.ee_pose.quat_xyzw)
        dx, dy, dz = grip.apply(slip.offset_in_gripper_m)
        turn = plans.Grip.of(after.robot.ee_pose, after.brick(brick)).yaw_deg
        verdict = gates.sigma3_grasp(pads, (dx, dy, dz), turn, self.tol)
        if self._refuses(verdict):
            self.world.grip(GRIPPER_GAP_M[1])
            raise _Refused(verdict.refusal(key), FailureCode.GRASP_FAILED)
        return at

    def _lift(
        self, answer: LiftDecision, state: WorldState, brick: int, grasp: WaypointProposal
    ) -> WaypointProposal:
        key = Stage.LIFT
        waypoint = _checked(key, answer.waypoint, path="linear")
        self._gate(self._lift_plan(state, brick, waypoint), key, FailureCode.COLLISION)
        self.world.move(waypoint)
        after = self.world.observe(Progress(current_brick=brick, step=Stage.LIFT))
        slip = self.calls.measure(after, SLIP, BrickQuery(brick_id=brick))
        if slip.relative_speed_mps > self.tol.v_th_mps:
            # Still swinging from the move's end: judge the brick once it is at rest in the
            # hand, so that v_th measures creep, not the swing.
            self.world.move(waypoint.model_copy(update={"duration_s": SETTLE_S}))
            after = self.world.observe(Progress(current_brick=brick, step=Stage.LIFT))
            slip = self.calls.measure(after, SLIP, BrickQuery(brick_id=brick))
        pads = self.calls.measure(after, FINGER_CONTACTS, BrickQuery(brick_id=brick))
        set_down = self.calls.measure(
            after,
            PLACEMENT_POSE,
            PlacementQuery(brick_id=brick, target_index=self.memory.current_target or 0),
        )
        speed = _speed(state.robot.ee_pose, waypoint)
        carry_s = _carry_s(after.robot.ee_pose, set_down.slot_pose)
        verdict = gates.sigma4_lift(slip, pads, set_down, speed, self.tol, carry_s=carry_s)
        if self._refuses(verdict):
            self._set_aside(brick, grasp, waypoint)
            raise _Regrasp(verdict.refusal(key))
        # A brick creeping faster than v_th is carried only until it would creep out.
        creep = slip.relative_speed_mps
        hold_m = gates.creep_hold_m(self.tol)
        self._held_until_s = after.time_s + hold_m / creep if creep > self.tol.v_th_mps else None
        return waypoint

    def _lift_plan(
        self, state: WorldState, brick: int, lift: WaypointProposal
    ) -> gates.GateVerdict:
        """The lift's plan checked before it moves (see :func:`plans.lift_plan`)."""
        tool = state.robot.ee_pose
        x, y, z = tool.position_m
        rise = lift.position_m[2] - z
        start = WaypointProposal(position_m=(x, y, z + LIFT_SUPPORT_M), quat_xyzw=tool.quat_xyzw)
        held = state.brick(brick)
        others = [b.pose.position_m[2] + b.size_m[2] / 2 for b in state.bricks if b.id != brick]
        bottom = held.pose.position_m[2] - held.size_m[2] / 2 + rise
        return plans.lift_plan(
            sideways_m=(lift.position_m[0] - x, lift.position_m[1] - y),
            rise_m=rise,
            turn_deg=rotation_deg(tool.quat_xyzw, lift.quat_xyzw),
            speed_mps=_speed(tool, lift),
            path=self._clearance(state, lift, start=start),
            bottom_clearance_m=bottom - max(others, default=0.0),
            tol=self.tol,
        )

    def _set_aside(self, brick: int, grasp: WaypointProposal, lifted: WaypointProposal) -> None:
        """Put the held brick down on the free ground nearest the tool, where it can be
        grasped again (sigma_4 = 0, or Ag5 asked for a re-grasp): a loose brick swings
        further on every move, so it is not carried far. Where no free ground near by is
        within reach, it goes back where it was grasped."""
        state = self.world.observe(Progress(current_brick=brick, step=self.memory.step))
        built = {p.target_index for p in self.memory.placed}
        height = lifted.position_m[2]
        spot = None
        if state.brick(brick).status == BrickStatus.GRASPED:
            target = self.memory.current_target or 0
            spot = self.put_down.free_spot(state, brick, target, built, height)
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
        carry = partial(self._carry_over_slot, brick=brick, target=target, back=back)
        self._placement_phase(PlacementPhase.CARRY)
        self._stage(Stage.PLACEMENT, placement_decision, carry, label=Stage.TRANSFER)
        self._placement_phase(PlacementPhase.SET_DOWN)
        set_down = partial(self._set_down, brick=brick, target=target, back=back)
        failed = ""  # the last sigma_5 verdict's failed checks: the failure's detail
        for _ in range(self.budgets.placement_attempts):
            self._watch_roll(brick)
            slot, motion = self._stage(Stage.PLACEMENT, placement_decision, set_down)
            state = self.world.observe(Progress(current_brick=brick, step=Stage.PLACEMENT))
            errors = self.calls.measure(
                state, ALIGNMENT, AlignmentQuery(brick_id=brick, target_index=target)
            )
            verdict = gates.sigma5_placement(errors, self.tol).noted(
                _touch_down(motion, state, slot)
            )
            if not self._refuses(verdict):
                self._judged_after_acceptance(verdict)
                self._placement_phase(None)
                return
            refusal = verdict.refusal(Stage.PLACEMENT)
            failed = refusal.text()
            self.calls.conclude(Outcome.RAISED, failed)
            # Misaligned in contact: raise by delta_h and ask Ag5 again.
            x, y, z = state.robot.ee_pose.position_m
            up = WaypointProposal(
                position_m=(x, y, z + self.tol.delta_h_m), quat_xyzw=slot.quat_xyzw, path="linear"
            )
            self.world.move(up)
            self._note(refusal)
            self._dropped_at_set_down(brick, back)
        raise TrialStopped(FailureCode.PLACEMENT_MISALIGNED, Stage.PLACEMENT, failed)

    def _dropped_at_set_down(self, brick: int, back: Callable[[], None]) -> None:
        """A brick that left the hand on a set-down (sigma_5 raised the tool without it) is
        no answer's to place: left where it lies, the cycle starts again at Ag1, which grasps
        it there if it lies flat (if not, the trial ends as no brick left, a physics
        failure, not as answers refused for a brick no longer held)."""
        state = self.world.observe(Progress(current_brick=brick, step=Stage.PLACEMENT))
        if state.brick(brick).status == BrickStatus.GRASPED:
            return
        back()
        raise _Regrasp(
            Refusal(
                agent=Stage.PLACEMENT,
                gate="placement_regrasp",
                note="the brick left the hand on the set-down: it is grasped again where it lies",
            ),
            ErrorCategory.GRASP,
        )

    def _placement_phase(self, phase: PlacementPhase | None) -> None:
        """Tell Ag5 which of its calls comes next (None: it is done with this brick)."""
        update = {"phase": phase} if phase is not None else {"phase": None, "roll_watch": None}
        self.memory = self.memory.model_copy(update=update)

    def _watch_roll(self, brick: int) -> None:
        """Measure the held brick's roll in the hand twice, ROLL_WATCH_S apart, with the tool
        held still where it is; memory keeps both measurements for the set-down (none if the
        brick is not in the hand)."""
        observe = self._observer(brick)
        before = observe()
        if before.brick(brick).status != BrickStatus.GRASPED:
            self.memory = self.memory.model_copy(update={"roll_watch": None})
            return
        tool = before.robot.ee_pose
        hold = WaypointProposal(
            position_m=tool.position_m,
            quat_xyzw=tool.quat_xyzw,
            path="linear",
            duration_s=ROLL_WATCH_S,
        )
        self.world.move(hold)
        now = observe()
        # Times to the millisecond, rolls to a hundredth of a degree, as the prompt shows them.
        watch = RollWatch(
            before_s=round(before.time_s, 3),
            before_deg=round(_roll(before, brick), 2),
            now_s=round(now.time_s, 3),
            now_deg=round(_roll(now, brick), 2),
        )
        self.memory = self.memory.model_copy(update={"roll_watch": watch})

    def _carry_over_slot(
        self,
        answer: PlacementDecision | RegraspRequest,
        state: WorldState,
        brick: int,
        target: int,
        back: Callable[[], None],
    ) -> None:
        """Carry the brick over the proposed slot, at the height it was carried at (lower where
        the arm cannot reach that), once the slot would set it within the success rule and the
        way there and down is clear."""
        slot = self._slot(answer, state, brick, back)
        above, transfer = self._hover(state, slot, path="joint")
        self._check_slot(state, brick, target, slot, above, transfer=transfer)
        self.world.move(above)

    def _set_down(
        self,
        answer: PlacementDecision | RegraspRequest,
        state: WorldState,
        brick: int,
        target: int,
        back: Callable[[], None],
    ) -> tuple[WaypointProposal, Motion]:
        """Set the brick down on the (re-measured) slot: over it, then straight down onto it.
        Returns the slot and what the way down did."""
        slot = self._slot(answer, state, brick, back)
        above, shift = self._hover(state, slot, path="linear")
        self._check_slot(state, brick, target, slot, above, transfer=shift, moves=2)
        self.world.move(above)
        # Onto the slot itself, pressed flat by the position controller; the guard stops the
        # move early if the brick meets its support above the slot.
        down = self.world.move(slot.model_copy(update={"path": "linear"}), stop_on_contact=brick)
        return slot, down

    def _hover(
        self, state: WorldState, slot: WaypointProposal, path: str
    ) -> tuple[WaypointProposal, CollisionReport]:
        """The tool over ``slot`` and the way there (a ``path`` move from where it is): at the
        carry height, or, where the arm cannot reach that, as high as it can, HOVER_STEP_M at
        a time down to the seat's clearance."""
        start = None if path == "joint" else state.robot.ee_pose
        above = _above(slot, state, path=path)
        way = self._clearance(state, above, start=start)
        x, y, z = above.position_m
        lowest = slot.position_m[2] + SEAT_CLEARANCE_M
        while not way.reachable and z > lowest:
            z = max(lowest, z - HOVER_STEP_M)
            above = above.model_copy(update={"position_m": (x, y, z)})
            way = self._clearance(state, above, start=start)
        return above, way

    def _slot(
        self,
        answer: PlacementDecision | RegraspRequest,
        state: WorldState,
        brick: int,
        back: Callable[[], None],
    ) -> WaypointProposal:
        """The answer's slot pose; a re-grasp, if that is what Ag5 asked for."""
        if isinstance(answer, RegraspRequest):
            tilt = self.calls.measure(state, SLIP, BrickQuery(brick_id=brick)).tilt_in_hand_deg
            back()
            raise _Regrasp(
                Refusal(
                    agent=Stage.PLACEMENT,
                    gate="placement_regrasp",
                    measured=Measured(tilt_deg=tilt),
                    note=f"placement asked for a re-grasp: {answer.rationale}",
                ),
                ErrorCategory.GRASP,
            )
        return _checked(Stage.PLACEMENT, answer.waypoint)

    def _check_slot(
        self,
        state: WorldState,
        brick: int,
        target: int,
        slot: WaypointProposal,
        above: WaypointProposal,
        transfer: CollisionReport,
        moves: int = 1,
    ) -> None:
        """Refuse a slot that would not set the brick, as it will sit in the hand at touch-down
        (a set-down, ``moves`` 2: rolled on at memory.roll_watch's rate), within the success
        rule, or whose way over it (``transfer``) or down collides. The way down ends in
        contact by design: it is checked to just above the seat."""
        goal = state.goal.targets[target]
        held = state.brick(brick)
        watch = self.memory.roll_watch
        turn = 0.0
        if moves == 2 and watch is not None:
            turn = watch.turn_by_touch_down_deg(slot.duration_s or 0.0)
        grip = formulas.rolled_in_hand(*formulas.in_hand(state.robot.ee_pose, held.pose), turn)
        landing = formulas.carried(_as_pose(slot), *grip)
        predicted = alignment_of(landing, held.size_m, goal)
        # The moves this slot asks for (over it; for a set-down, down too) must end while a
        # creeping brick is still held.
        hold = (
            ()
            if self._held_until_s is None
            else (
                Check(
                    "hold_margin_s",
                    self._held_until_s - state.time_s - moves * (slot.duration_s or 0.0),
                    0.0,
                    at_most=False,
                ),
            )
        )
        x, y, z = slot.position_m
        near = WaypointProposal(position_m=(x, y, z + SEAT_CLEARANCE_M), quat_xyzw=slot.quat_xyzw)
        descent = self._clearance(state, near, start=above, roll_turn_deg=turn)
        worst = min((transfer, descent), key=lambda r: r.clearance_m if r.reachable else -1e9)
        verdict = GateVerdict(
            f"{Stage.PLACEMENT}_plan",
            (
                Check("predicted_offset_m", predicted.offset_m, self.tol.max_offset_m, True),
                Check(
                    "predicted_rotation_deg",
                    predicted.rotation_deg,
                    self.tol.max_rotation_deg,
                    True,
                ),
                *plans.path_checks(worst, self.tol, "way_"),
                *hold,
            ),
            measured=gates.misalignment(predicted).model_copy(
                update={"clearance_m": worst.clearance_m, "closest": worst.closest}
            ),
        )
        crept = any(not check.passed for check in hold)
        self._gate(
            verdict,
            Stage.PLACEMENT,
            FailureCode.GRASP_SLIP if crept else _failure_of(worst, self.tol),
        )

    def _clearance(
        self,
        state: WorldState,
        to: WaypointProposal,
        start: WaypointProposal | Pose | None = None,
        opening: float | None = None,
        ignore: int | None = None,
        joint: bool = False,
        roll_turn_deg: float = 0.0,
    ) -> CollisionReport:
        """Clearance on the way to ``to``: straight from ``start`` if given (a joint move from
        it if ``joint``), else a joint move from where the arm is; at ``opening`` (default: the
        gripper's now), the held brick carried (turned ``roll_turn_deg`` further in the
        hand), brick ``ignore`` left out."""
        query = CollisionQuery(
            pose=_as_pose(to),
            start_pose=None if start is None else _as_pose(start),
            path="joint" if joint or start is None else "linear",
            gripper_opening_m=state.robot.gripper_width_m if opening is None else opening,
            ignore_brick_id=ignore,
            held_roll_turn_deg=roll_turn_deg,
        )
        return self.calls.measure(state, COLLISION, query)

    def _release(self, answer: ReleaseDecision, state: WorldState, brick: int) -> None:
        """Let go and return: the pads open to the answer's opening, the tool rises RETREAT_M
        straight up, then moves (joint) on to the answer's waypoint; sigma_6 checks both
        moves before the gripper opens."""
        key = Stage.RELEASE
        ready = _checked(key, answer.waypoint)
        width = state.brick(brick).size_m[1]
        self._gate(plans.release_plan(answer.gripper_opening_m, width), key)
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
        self._gate(gates.sigma6_return(way_up, onward, self.tol), key, FailureCode.COLLISION)
        self.world.grip(answer.gripper_opening_m)
        self.world.move(retreat)
        self.world.move(ready)


def _roll(state: WorldState, brick: int) -> float:
    """Brick ``brick``'s roll in the hand (deg) in ``state``."""
    quat = formulas.in_hand(state.robot.ee_pose, state.brick(brick).pose)[1]
    return formulas.roll_in_hand_deg(quat)


def _failed(gate: str, check: str, note: str) -> GateVerdict:
    """A verdict with the one failed yes/no check ``check``, saying why in ``note``."""
    return GateVerdict(gate, (Check(check, 0.0, 1.0, at_most=False),)).noted(note)


def _failure_of(path: CollisionReport, tol: Tolerances) -> FailureCode:
    """How a trial ends if a plan with this path keeps being refused: on a collision if the
    path is not clear, else on invalid answers."""
    clear = tol.clear(path.clearance_m, path.reachable)
    return FailureCode.INVALID_OUTPUT if clear else FailureCode.COLLISION


def _above(slot: WaypointProposal, state: WorldState, path: str = "joint") -> WaypointProposal:
    """The tool over ``slot`` at the current height (or the slot's, if higher)."""
    x, y, z = slot.position_m
    height = max(state.robot.ee_pose.position_m[2], z)
    return slot.model_copy(update={"position_m": (x, y, height), "path": path})


def _carry_s(tool: Pose, slot: Pose) -> float:
    """How long carrying the held brick over ``slot`` and setting it down take at the carry
    speed: across at the tool's height, then down."""
    across = math.dist(tool.position_m[:2], slot.position_m[:2])
    down = max(0.0, tool.position_m[2] - slot.position_m[2])
    return (across + down) / CARRY_SPEED_MPS


def _touch_down(motion: Motion, after: WorldState, slot: WaypointProposal) -> str:
    """How the set-down ended, as measured: stopped on contact (where), or ran to the slot."""
    if not motion.stopped_on_contact:
        return "the set-down ran all the way to the slot: the brick met no support that stopped it"
    z = after.robot.ee_pose.position_m[2]
    return (
        f"the set-down stopped on contact with the tool at z = {z:.4f} m, "
        f"{(z - slot.position_m[2]) * 1000:.1f} mm above the slot"
    )


def _speed(tool: Pose, waypoint: WaypointProposal) -> float:
    """Mean speed (m/s) of a move from ``tool`` to ``waypoint``: infinite without a duration
    (as fast as the controller's limits allow)."""
    length = math.dist(tool.position_m, waypoint.position_m)
    return length / waypoint.duration_s if waypoint.duration_s else math.inf


def _as_pose(waypoint: WaypointProposal | Pose) -> Pose:
    return Pose(position_m=waypoint.position_m, quat_xyzw=waypoint.quat_xyzw)


def _checked(key: Stage, waypoint: WaypointProposal, path: str | None = None) -> WaypointProposal:
    """A waypoint with a unit quaternion (normalised within tolerance, else refused)."""
    try:
        return unit_waypoint(waypoint, path)
    except ValueError as error:
        refusal = _failed(f"{key}_answer", "valid_answer", str(error)).refusal(key)
        raise _Refused(refusal, category=ErrorCategory.FRAME_UNITS) from None


def _edges(size: Vec3) -> str:
    return " x ".join(f"{edge:.3f}" for edge in size)
