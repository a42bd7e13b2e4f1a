"""Asking a reasoner on an agent's behalf, and the record of a build.

Shared by the gated orchestrator and the single-agent ablation: observe the world, render
the prompt, let the reasoner call the agent's whitelisted tools, and log every call in
the transcript of the :class:`BuildResult`.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any

from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.gates import GateVerdict
from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.outputs import AgentAnswer
from actionreasoning.agents.prompt import render_prompt
from actionreasoning.agents.reasoner import AgentRequest, Reasoner
from actionreasoning.agents.spec import AgentSpec
from actionreasoning.agents.transcript import (
    AgentCall,
    GateRecord,
    Outcome,
    PictureRecord,
    ToolRecord,
)
from actionreasoning.agents.view import StateView
from actionreasoning.agents.world import World
from actionreasoning.errors import (
    ActionReasoningError,
    LLMError,
    ToolError,
    TrialAborted,
    UnreachableError,
)
from actionreasoning.records import Failure, FailureCode, LLMUsage
from actionreasoning.tools.base import In, Out, Tool, ToolContext, ToolModel
from actionreasoning.tools.registry import call_tool, measurements
from actionreasoning.world.models import Progress, WorldState
from actionreasoning.world.tolerances import Tolerances

#: Called with (brick id, stage name) after each stage a build finished, for snapshots.
StageHook = Callable[[int, str], None]
#: Called with the call each time its record grows (answer, gate verdict, outcome): it must
#: only read.
CallHook = Callable[[AgentCall], None]


class TrialStopped(ActionReasoningError):
    """Raised inside a build when it cannot go on; carries the failure."""

    def __init__(self, reason: FailureCode, agent: str | None, detail: str) -> None:
        super().__init__(f"{reason} ({agent}): {detail}")
        self.failure = Failure(reason=reason, agent=agent, detail=detail)


#: The errors that end a build (rather than the program), and how to say so.
BUILD_STOPPERS = (TrialStopped, UnreachableError, ToolError, TrialAborted)


def failure_of(error: Exception, agent: str | None) -> Failure:
    """The failure record of an error in BUILD_STOPPERS raised while ``agent`` was acting."""
    if isinstance(error, TrialStopped):
        return error.failure
    if isinstance(error, TrialAborted):
        return Failure(reason=error.reason, agent=agent, detail=error.detail)
    reason = (
        FailureCode.UNREACHABLE if isinstance(error, UnreachableError) else FailureCode.TOOL_ERROR
    )
    return Failure(reason=reason, agent=agent, detail=str(error))


@dataclass
class BuildResult:
    """What a build did: target -> brick, LLM usage, every agent call, a failure if any."""

    placements: dict[int, int] = field(default_factory=dict)
    usage: LLMUsage = LLMUsage()
    decisions: int = 0
    fallbacks: int = 0
    failure: Failure | None = None
    transcript: list[AgentCall] = field(default_factory=list)


class AgentCaller:
    """Puts an agent's request to the reasoner and writes the transcript."""

    def __init__(
        self,
        world: World,
        reasoner: Reasoner,
        tolerances: Tolerances,
        result: BuildResult,
        on_call: CallHook | None = None,
    ) -> None:
        self.world = world
        self.reasoner = reasoner
        self.tol = tolerances
        self.result = result
        self.on_call = on_call

    def ask(
        self, spec: AgentSpec, memory: TaskMemory, attempt: int
    ) -> tuple[AgentAnswer, WorldState]:
        """The reasoner's answer for agent ``spec`` now and the state it was given; an answer
        that is not of the spec's output model ends the trial."""
        progress = Progress(
            placed_ids=tuple(p.brick_id for p in memory.placed),
            current_brick=memory.current_brick,
            step=memory.step,  # the stage asked (the single agent answers every stage)
        )
        state = self.world.observe(progress)
        shown = spec.observation
        pictures = self.world.look() if shown.pictures else ()
        context = replace(self.world.tools(state), pictures=pictures)
        view = StateView.of(state, memory, spec.scope, spec.robot_extras, shown.poses)
        prompt = render_prompt(spec, view, memory, self.tol)
        tool_calls: list[ToolRecord] = []
        knowledge, gates = f"the knowledge base of {spec.key}", "the gates' measurements"
        call = AgentCall(
            call=len(self.result.transcript),
            agent=spec.key,
            brick=memory.current_brick,
            target=memory.current_target,
            attempt=attempt,
            prompt_chars=len(prompt),
            pictures=[PictureRecord.of(picture) for picture in pictures],
            answer={},
        )
        self.result.transcript.append(call)
        try:
            reply = self.reasoner.decide(
                AgentRequest(
                    spec=spec,
                    prompt=prompt,
                    view=view,
                    state=state,
                    memory=memory,
                    tolerances=self.tol,
                    call_tool=partial(_run_tool, spec.tools, knowledge, context, tool_calls),
                    measure=partial(
                        _run_tool, measurements(shown.poses), gates, context, tool_calls
                    ),
                    call=call.call,
                    pictures=pictures,
                )
            )
        except LLMError as error:
            self.result.usage += error.usage
            call.tool_calls, call.usage, call.repairs = tool_calls, error.usage, list(error.repairs)
            call.repair_categories = list(error.repair_categories)
            self.conclude(Outcome.FAILED, error.detail, _failure_category(error))
            raise TrialStopped(error.reason, spec.key, error.detail) from None
        self.result.decisions += 1
        self.result.fallbacks += reply.fallback
        self.result.usage += reply.usage
        call.answer, call.tool_calls = reply.answer.model_dump(mode="json"), tool_calls
        call.usage, call.repairs = reply.usage, list(reply.repairs)
        call.repair_categories = list(reply.repair_categories)
        call.tool_turns, call.fallback = reply.tool_turns, reply.fallback
        call.corruption = reply.corruption
        call.prompt_chars = reply.prompt_chars or call.prompt_chars
        self._tell(call)
        if not isinstance(reply.answer, spec.output_model):
            detail = "answer of the wrong schema"
            self.conclude(Outcome.FAILED, detail, ErrorCategory.SCHEMA)
            raise TrialStopped(FailureCode.INVALID_OUTPUT, spec.key, detail)
        return reply.answer, state

    def conclude(
        self, outcome: Outcome, feedback: str = "", category: ErrorCategory | None = None
    ) -> None:
        """Note in the transcript what became of the last answer (see
        :meth:`AgentCall.conclude` for ``category``)."""
        call = self.result.transcript[-1]
        call.conclude(outcome, feedback, category)
        self._tell(call)

    def judge(self, verdict: GateVerdict, enforced: bool = True) -> GateVerdict:
        """Record a verdict with the last answer (``enforced``: whether it may refuse it);
        the caller acts on it."""
        self.result.transcript[-1].gates.append(GateRecord.of(verdict, enforced))
        self._tell(self.result.transcript[-1])
        return verdict

    def _tell(self, call: AgentCall) -> None:
        if self.on_call is not None:
            self.on_call(call)

    def measure(self, state: WorldState, tool: Tool[In, Out], arguments: In) -> Out:
        """A tool run for verification and gates (not an agent's tool call)."""
        return tool(self.world.tools(state), arguments)


def _failure_category(error: LLMError) -> ErrorCategory:
    """A model that gave no valid answer within its repairs failed as its last repair did;
    one whose server failed (or timed out, or whose session closed) gave no answer."""
    if error.reason is FailureCode.INVALID_OUTPUT and error.repair_categories:
        return error.repair_categories[-1]
    return ErrorCategory.LLM_FAILURE


def _run_tool(
    allowed: Collection[str],
    among: str,
    context: ToolContext,
    log: list[ToolRecord],
    name: str,
    arguments: Mapping[str, Any],
) -> ToolModel:
    """Run a tool for the reasoner if it is one of the ``allowed`` (``among`` names them),
    and log it."""
    record = ToolRecord(name=name[:64], arguments=dict(arguments))
    log.append(record)
    try:
        if name not in allowed:
            raise ToolError(f"tool {name[:60]!r} is not in {among}")
        result = call_tool(name, arguments, context)
    except ToolError as error:
        record.error = str(error)
        raise
    record.result = result.model_dump(mode="json")
    return result
