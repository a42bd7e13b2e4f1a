"""The one-method reasoner interface: an agent's request in, a validated answer and usage out."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from pydantic import BaseModel

from actionreasoning.agents.answer_errors import AnswerCorruption
from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
from actionreasoning.agents.outputs import AgentAnswer
from actionreasoning.agents.spec import AgentKey, AgentSpec
from actionreasoning.agents.tiers import DEFAULT_TIER, ToolTier
from actionreasoning.agents.view import StateView
from actionreasoning.records import LLMUsage
from actionreasoning.tools.base import In, Out, Tool, ToolModel
from actionreasoning.world.models import WorldState
from actionreasoning.world.pictures import Picture
from actionreasoning.world.tolerances import Tolerances

ToolRunner = Callable[[str, Mapping[str, Any]], ToolModel]
#: Runs several tool calls of one turn, (name, arguments) each, and returns their results.
BatchRunner = Callable[[Sequence[tuple[str, Mapping[str, Any]]]], list[ToolModel]]


@dataclass(frozen=True)
class AgentRequest:
    """What an agent is asked: its rendered prompt and the same context in structured form.

    ``view``, ``memory`` and ``tolerances`` are what the prompt shows; ``call_tool`` runs a
    whitelisted tool of the agent's knowledge base on the current world, the only way a
    reasoner learns more than the prompt says. ``measure`` runs one of the gates'
    measurements (``GATE_MEASUREMENTS``) on that world, for an agent answered from outside
    (the in-process reasoners never call it); both log the call in the transcript.
    ``state`` is the whole measured state, for validating an answer's ids (a reasoner does
    not read it). ``call`` is the index of this call in the trial (its transcript record's).
    ``pictures`` are the cameras' pictures the call carries (none when the agents observe
    the state only, ``agents/observation.py``).
    """

    spec: AgentSpec
    prompt: str
    view: StateView
    state: WorldState
    memory: TaskMemory
    tolerances: Tolerances
    call_tool: ToolRunner
    measure: ToolRunner
    call: int = 0
    pictures: tuple[Picture, ...] = ()


@dataclass(frozen=True)
class Briefing:
    """What a prompt tells an agent, in structured form, and the agent's tools: all a
    policy may read, whether it gets it as objects or parses it from the prompt's text.

    ``tier`` is the reasoning tier the prompt is written for; ``call_tools``, if given,
    runs the calls of one turn together (a model lists them in one answer), else they run
    one by one through ``call_tool``. ``observation`` is what the prompt shows of the scene,
    ``pictures`` the pictures that came with it."""

    agent: AgentKey
    view: StateView
    memory: TaskMemory
    tolerances: Tolerances
    call_tool: ToolRunner
    tier: ToolTier = DEFAULT_TIER
    call_tools: BatchRunner | None = None
    observation: Observation = DEFAULT_OBSERVATION
    pictures: tuple[Picture, ...] = ()

    def use(self, tool: Tool[In, Out], arguments: In) -> Out:
        """Run one of the agent's tools as a language model calls it: by name, with the
        arguments given as JSON."""
        result: Out = self.use_all((tool, arguments))[0]
        return result

    def use_all(self, *calls: tuple[Tool[Any, Any], BaseModel]) -> list[Any]:
        """Run the (tool, arguments) ``calls`` in one turn of tool calls; their results in
        order."""
        named = [
            (tool.name, args.model_dump(mode="json", exclude_unset=True)) for tool, args in calls
        ]
        if self.call_tools is None:
            results = [self.call_tool(name, args) for name, args in named]
        else:
            results = self.call_tools(named)
        for (tool, _), result in zip(calls, results, strict=True):
            if not isinstance(result, tool.output_model):
                raise TypeError(f"{tool.name} answered a {type(result).__name__}")
        return results


@dataclass(frozen=True)
class AgentReply:
    """A validated answer (an instance of the agent's output model) and what it cost.

    ``repairs`` are the errors that sent the model's earlier outputs back for repair,
    ``repair_categories`` their categories (one each), ``tool_turns`` how many rounds of
    tool calls it made, and ``fallback`` whether the built-in reasoner answered after the
    repair budget was spent. ``prompt_chars`` is how many characters went to the model over
    all its turns (None: the prompt once).
    ``corruption`` says what ``eval --answer-errors`` changed in the answer, if anything.
    """

    answer: AgentAnswer
    usage: LLMUsage = LLMUsage()
    repairs: tuple[str, ...] = ()
    repair_categories: tuple[ErrorCategory, ...] = ()
    tool_turns: int = 0
    fallback: bool = False
    prompt_chars: int | None = None
    corruption: AnswerCorruption | None = None


class Reasoner(Protocol):
    """Anything that answers agents: the built-in policy, an LLM backend, a replay."""

    name: str

    def decide(self, request: AgentRequest) -> AgentReply:
        """Answer one agent request."""
        ...
