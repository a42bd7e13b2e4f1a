"""The paper's single-agent ablation: one merged prompt per waypoint, no stage gating.

One agent holds all six roles, tools and thinking chains and answers the next waypoint of
the cycle with a gripper command. Its answers are validated as any model answer is
(``agents/validation.py``: schema, workspace box, unit quaternion, known brick and target,
a ``pre_grasp`` that names both) and the controller's limits still hold (an unreachable
pose is refused), but nothing is verified or gated: no collision check before a move, no
force check after the grasp, no slip or alignment check, no retries with feedback. An
answer refused by either ends the trial: its call fails with the error's category.
"""

from __future__ import annotations

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
from actionreasoning.agents.memory import PlacedBrick, TaskMemory
from actionreasoning.agents.outputs import (
    AgentAnswer,
    SingleAgentPick,
    SingleAgentStep,
    single_agent_decision,
)
from actionreasoning.agents.reasoner import Reasoner
from actionreasoning.agents.spec import SINGLE_AGENT_START, single_agent_spec
from actionreasoning.agents.tiers import DEFAULT_TIER, ToolTier
from actionreasoning.agents.transcript import Outcome
from actionreasoning.agents.validation import OutputError, check_answer, complete
from actionreasoning.agents.world import World
from actionreasoning.errors import UnreachableError
from actionreasoning.records import FailureCode
from actionreasoning.world.models import GoalPattern, WorldState
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, WORKSPACE
from actionreasoning.world.stages import Stage
from actionreasoning.world.tolerances import Tolerances

#: Waypoints the agent may spend per brick (a full cycle takes eight), plus one to finish.
WAYPOINTS_PER_BRICK = 12


class SingleAgent:
    """Runs the merged agent over a goal, one waypoint per call, against a :class:`World`."""

    def __init__(
        self,
        world: World,
        reasoner: Reasoner,
        tolerances: Tolerances = Tolerances(),
        on_stage: StageHook | None = None,
        on_call: CallHook | None = None,
        tier: ToolTier = DEFAULT_TIER,
    ) -> None:
        self.world = world
        self.spec = single_agent_spec(tier)
        self.on_stage = on_stage
        self.result = BuildResult()
        self.calls = AgentCaller(
            world, reasoner, tolerances.under(world.sensing), self.result, on_call
        )
        self.memory = TaskMemory(step=SINGLE_AGENT_START)

    def build(self, goal: GoalPattern) -> BuildResult:
        """Ask for waypoints and run them until the agent is done or the budget is spent."""
        budget = WAYPOINTS_PER_BRICK * len(goal.targets) + 1
        try:
            for call in range(budget):
                answer, state = self.calls.ask(self.spec, self.memory, call + 1)
                try:
                    step = self._execute(answer, state)
                except UnreachableError as error:
                    self.calls.conclude(Outcome.FAILED, str(error), ErrorCategory.UNREACHABLE)
                    raise
                self.calls.conclude(Outcome.EXECUTED)
                if step == "done":
                    return self.result
            raise TrialStopped(
                FailureCode.BUDGET_EXHAUSTED, self.spec.key, f"{budget} waypoints spent"
            )
        except BUILD_STOPPERS as error:
            self.result.failure = failure_of(error, self.spec.key)
        return self.result

    def _execute(self, answer: AgentAnswer, state: WorldState) -> SingleAgentStep:
        """Check the answer's data (as any model answer is checked) and that it is a complete
        decision, move, grip, and keep the memory of the cycle; returns the step done."""
        try:
            checked = check_answer(answer, self.spec, state, WORKSPACE)
            decision = complete(single_agent_decision, checked)
        except OutputError as error:
            raise self._refused(str(error), error.category) from None
        update: dict[str, object] = {"step": decision.step}
        if isinstance(decision, SingleAgentPick):
            update |= {"current_brick": decision.brick_id, "current_target": decision.target_index}
        if decision.waypoint is not None:
            self.world.move(decision.waypoint)
        if decision.gripper == "open":
            self.world.grip(decision.gripper_opening_m or GRIPPER_GAP_M[1])
        elif decision.gripper == "close":
            self.world.grip(None)
        self.memory = self.memory.model_copy(update=update)
        brick, target = self.memory.current_brick, self.memory.current_target
        if brick is None or target is None:
            return decision.step
        if decision.step == Stage.RELEASE:
            self.result.placements[target] = brick
            placed = (*self.memory.placed, PlacedBrick(brick_id=brick, target_index=target))
            self.memory = self.memory.model_copy(update={"placed": placed})
        if self.on_stage is not None:
            self.on_stage(brick, decision.step)
        return decision.step

    def _refused(self, detail: str, category: ErrorCategory) -> TrialStopped:
        """The error that ends the trial on an invalid answer, whose call fails with
        ``category``."""
        self.calls.conclude(Outcome.FAILED, detail, category)
        return TrialStopped(FailureCode.INVALID_OUTPUT, self.spec.key, detail)
