"""One connection's door to a trial: the MCP server's tools as calls on a
:class:`~actionreasoning.trial.session.TrialSession`, with no protocol in them.

A connection holds at most one trial. ``start_trial`` starts one (ending one still running
as ``abandoned``); ``read_state`` shows the waiting agent's turn; each registry tool runs
through the session, within the registry's bounds: a tool of the agents' knowledge bases
only for the agent whose tool it is, a gate's measurement for whichever agent waits;
``submit_answer`` hands the session an answer as text, to be validated, gated and
executed as a language model's is; ``finish_trial`` ends the trial and gives its results
line. Whatever a call asks, it comes back as JSON data of its tool's output schema
(``replies.py``): a refusal, ``{"refusal": {code, detail}}``, is data too, never an
exception. An argument holding a lone surrogate (a string, at any depth, that JSON can
escape but Unicode has no character for) is refused.
"""

from __future__ import annotations

import json
import re
import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError
from pydantic_core import to_json

from actionreasoning.agents.answer_errors import AnswerErrors
from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
from actionreasoning.agents.prompt import state_blocks
from actionreasoning.agents.spec import single_agent_spec
from actionreasoning.agents.tiers import DEFAULT_TIER, TIER_HELP, ToolTier
from actionreasoning.errors import ActionReasoningError
from actionreasoning.mcp_server.replies import (
    AgentTurn,
    Finished,
    Judged,
    Refused,
    Started,
    StateRead,
    TrialConditions,
    output_schema,
    tool_reply,
)
from actionreasoning.tools.registry import GATE_MEASUREMENTS, tool_schema
from actionreasoning.trial.provenance import current_provenance, stamp
from actionreasoning.trial.results import TrialResult
from actionreasoning.trial.session import (
    AgentLabel,
    Conditions,
    Refusal,
    RefusalCode,
    TrialSession,
)
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.pictures import Picture
from actionreasoning.world.scenarios import NOISE, PATTERNS, PHYSICS
from actionreasoning.world.tolerances import Tolerances

#: The tools of the six agents' knowledge bases together, in pipeline order, in any tier,
#: with pictures or not (an agent is served only those of its own knowledge base in the
#: trial's tier and observation).
KNOWLEDGE_TOOLS: tuple[str, ...] = tuple(
    dict.fromkeys(
        name
        for tier in ToolTier
        for observation in (Observation.STATE, Observation.BOTH)
        for name in single_agent_spec(tier, observation).tools
    )
)
#: Every registry tool the door serves: the knowledge bases', then the gates' measurements.
REGISTRY_TOOLS: tuple[str, ...] = tuple(dict.fromkeys(KNOWLEDGE_TOOLS + GATE_MEASUREMENTS))
#: A surrogate code point: in a Python string (where a pair is one character), a lone one.
LONE_SURROGATE = re.compile("[\ud800-\udfff]")


def _named(builtins: Iterable[str]) -> str:
    """The names of built-ins, quoted: 'a', 'b'."""
    return ", ".join(f"'{name}'" for name in builtins)


class _Arguments(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class StartTrial(_Arguments):
    """Start trial ``trial`` of ``eval --seed seed`` (the same bricks) under the conditions
    named as on the command line. A trial still running on this connection is abandoned."""

    pattern: str = Field("pyramid", description=f"{_named(PATTERNS)} or a pattern file's path.")
    physics: str = Field("paper", description=f"{_named(PHYSICS)} or a profile file's path.")
    noise: str = Field("none", description=f"{_named(NOISE)} or a noise file.")
    tools: str = Field(
        DEFAULT_TIER.value,
        description="The reasoning tier: "
        + "; ".join(f"'{tier}': {text}" for tier, text in TIER_HELP.items())
        + ".",
    )
    observe: str = Field(
        DEFAULT_OBSERVATION.value,
        description="What the agents observe, as eval's --observe: 'state', the bricks' "
        "measured poses; 'image', the cameras' pictures and no brick's pose (agent 1 names "
        "its brick by where it lies; tools check or none); 'both', the poses and the "
        "pictures. start_trial and read_state return the pictures as PNG image content "
        "after their JSON, in the order the prompt's Cameras section names them.",
        json_schema_extra={"enum": list(Observation)},
        exclude_if=lambda shown: shown == DEFAULT_OBSERVATION,
    )
    seed: int = Field(0, ge=0, description="The run seed, as eval's --seed.")
    trial: int = Field(0, ge=0, description="The trial's index in that run.")
    max_trial_s: float = Field(
        TrialBudget().max_wall_s, gt=0, description="Wall-clock seconds the trial may take."
    )
    answer_errors: float = Field(
        0.0,
        ge=0,
        le=1,
        exclude_if=lambda rate: rate == 0,
        description="Probability that each answer is corrupted, as eval's --answer-errors, "
        "before it is validated and gated; the results line counts what the gates caught.",
    )


class ReadState(_Arguments):
    """The waiting agent's turn: its prompt (role, measured state, memory, thresholds,
    tools, answer format), the prompt's state and memory blocks as JSON, its tools with
    their schemas, the schema of its answer and the feedback on its last refused answer;
    once the trial has ended, its results line."""


class SubmitAnswer(_Arguments):
    """Submit the waiting agent's answer. It is validated as a language model's answer is
    (schema, finite numbers, workspace, unit quaternions, ids, tools; without tool_calls,
    every field of a complete decision): a refused one moves nothing. An answer with
    tool_calls gets their results back. A decision is checked by the agent's gate before
    the arm moves: the verdict comes back with every check, the outcome and the feedback,
    once the next agent waits or the trial has ended."""

    answer: dict[str, Any] | str = Field(
        description="The answer: the object the agent's answer_schema asks for, or its JSON text."
    )


class FinishTrial(_Arguments):
    """End the trial (abandoned if an agent still waits) and return its results line:
    success, bricks placed, per-brick and mean placement metrics, failure, steps."""


@dataclass(frozen=True)
class ToolEntry:
    """A tool as the server lists it."""

    name: str
    description: str
    input_schema: dict[str, Any]
    output_schema: dict[str, Any]


@dataclass(frozen=True)
class Reply:
    """What a call gives back: JSON data (non-finite numbers as null, as in results.jsonl),
    whether the call was refused, and the pictures the waiting agent's call carries."""

    data: dict[str, Any]
    refused: bool
    pictures: tuple[Picture, ...] = ()

    @classmethod
    def of(
        cls,
        data: BaseModel | Mapping[str, Any],
        refused: bool = False,
        pictures: tuple[Picture, ...] = (),
    ) -> Reply:
        """``data`` (models in it too) as JSON data."""
        return cls(json.loads(to_json(data)), refused, pictures)

    @classmethod
    def refusal(cls, code: RefusalCode, detail: str) -> Reply:
        """A typed refusal: nothing was done."""
        return cls.of(Refused(refusal=Refusal(code=code, detail=detail)), refused=True)


class Door:
    """One connection's trial and the tools that reach it; calls are served one at a time."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._session: TrialSession | None = None
        self._trial: TrialConditions | None = None
        self._provenance = current_provenance()
        self._calls: dict[str, tuple[type[_Arguments], type[BaseModel], Callable[[Any], Reply]]] = {
            "start_trial": (StartTrial, Started, self._start),
            "read_state": (ReadState, StateRead, lambda _: self._state()),
            "submit_answer": (SubmitAnswer, Judged, self._answer),
            "finish_trial": (FinishTrial, Finished, lambda _: self._finish()),
        }

    def tools(self) -> list[ToolEntry]:
        """The door's own tools, then the registry's, with their input and output schemas."""
        own = [
            ToolEntry(name, _description(model), model.model_json_schema(), output_schema(reply))
            for name, (model, reply, _) in self._calls.items()
        ]
        registry = []
        for name in REGISTRY_TOOLS:
            schema = tool_schema(name)
            note = _GATE_NOTE if name in GATE_MEASUREMENTS else _KNOWLEDGE_NOTE
            registry.append(
                ToolEntry(
                    name,
                    f"{schema.description} {note}",
                    schema.input_schema,
                    output_schema(tool_reply(name)),
                )
            )
        return own + registry

    def call(self, name: str, arguments: Mapping[str, Any] | None) -> Reply:
        """Run tool ``name`` on ``arguments``; a typed refusal for anything it cannot do."""
        with self._lock:
            if name not in self._names():
                detail = f"no tool {name[:64]!r}; the tools are {', '.join(self._names())}"
                return Reply.refusal(RefusalCode.UNKNOWN_TOOL, detail)
            unicode = _not_unicode(arguments or {})
            if unicode is not None:
                detail = f"{name}: {unicode}: not valid Unicode (holds a lone surrogate)"
                return Reply.refusal(RefusalCode.INVALID_ACTION, detail)
            if name in REGISTRY_TOOLS:
                return self._tool(name, dict(arguments or {}))
            model, _, run = self._calls[name]
            try:
                parsed = model.model_validate(dict(arguments or {}))
            except ValidationError as error:
                return Reply.refusal(RefusalCode.INVALID_ACTION, f"{name}: {_first(error)}")
            return run(parsed)

    def close(self) -> None:
        """End the trial still running, if any (``abandoned``)."""
        with self._lock:
            self._end()

    # --- the tools --------------------------------------------------------------------------
    def _start(self, start: StartTrial) -> Reply:
        try:
            budget = TrialBudget(max_wall_s=start.max_trial_s)
            errors = AnswerErrors(rate=start.answer_errors + 0.0)  # -0 is 0, as eval's
            conditions = Conditions.load(
                start.pattern,
                start.physics,
                start.noise,
                budget,
                start.tools,
                answer_errors=errors,
                observe=start.observe,
            )
            Tolerances.derive().for_goal(conditions.goal)  # joints the gates work with
            spec = conditions.spec(start.seed, start.trial)
        except ActionReasoningError as error:
            return Reply.refusal(RefusalCode.INVALID_ACTION, f"start_trial: {error}")
        previous = self._end()
        session = self._session = TrialSession(spec, agent=AgentLabel.MCP)
        trial = self._trial = TrialConditions.model_validate(
            start.model_dump(exclude={"max_trial_s"}) | {"pattern": spec.pattern_name}
        )
        started = Started(**dict(self._view(session, trial)), previous_result=previous)
        return Reply.of(started, pictures=_pictures(session))

    def _state(self) -> Reply:
        session, trial = self._session, self._trial
        if session is None or trial is None:
            return _no_trial()
        return Reply.of(self._view(session, trial), pictures=_pictures(session))

    def _tool(self, name: str, arguments: dict[str, Any]) -> Reply:
        session = self._session
        if session is None:
            return _no_trial()
        reply = session.use_tool(name, arguments)
        return Reply.of(reply.model_dump(exclude_none=True), refused=reply.refusal is not None)

    def _answer(self, submit: SubmitAnswer) -> Reply:
        session = self._session
        if session is None:
            return _no_trial()
        answer = submit.answer
        reply = session.answer(answer if isinstance(answer, str) else json.dumps(answer))
        if reply.refusal is not None:
            return Reply.of(Refused(refusal=reply.refusal), refused=True)
        turn = session.turn()
        return Reply.of(
            Judged(
                tools=reply.tools,
                call=reply.call,
                agent=None if turn is None else turn.agent,
                result=self._line(session),
            )
        )

    def _finish(self) -> Reply:
        if self._session is None:
            return _no_trial()
        return Reply.of(Finished(result=self._end()))

    # --- helpers ----------------------------------------------------------------------------
    def _end(self) -> TrialResult | None:
        """Close the trial (if any) and forget it; its results line."""
        session, self._session, self._trial = self._session, None, None
        if session is None:
            return None
        session.close()
        return self._line(session)

    def _view(self, session: TrialSession, trial: TrialConditions) -> StateRead:
        """What read_state shows: the trial, the waiting agent's turn, the results line."""
        return StateRead(trial=trial, turn=_turn(session), result=self._line(session))

    def _line(self, session: TrialSession) -> TrialResult | None:
        """The trial's results line once it has ended, stamped with the code that wrote it
        as eval stamps it."""
        result = session.result
        return None if result is None else stamp(result, self._provenance)

    def _names(self) -> list[str]:
        return [*self._calls, *REGISTRY_TOOLS]


_KNOWLEDGE_NOTE = (
    "Runs on the measured world for the waiting agent; only that agent's own tools run "
    "(read_state lists them with their result schemas)."
)
_GATE_NOTE = (
    "A gate's measurement: runs on the measured world for whichever agent waits, and is "
    "logged with its call (read_state lists the measurements with their result schemas)."
)


def _turn(session: TrialSession) -> AgentTurn | None:
    """The waiting agent's turn, its state and memory as its prompt shows them (None once
    the trial has ended)."""
    turn, request = session.turn(), session.request
    if turn is None or request is None:
        return None
    state, memory = state_blocks(request.spec, request.view, request.memory)
    pictures = [picture.name for picture in request.pictures]
    return AgentTurn(**{**dict(turn), "state": state, "memory": memory, "pictures": pictures})


def _pictures(session: TrialSession) -> tuple[Picture, ...]:
    """The pictures the waiting agent's call carries (none once the trial has ended)."""
    request = session.request
    return () if request is None else request.pictures


def _description(model: type[BaseModel]) -> str:
    return " ".join((model.__doc__ or "").split())


def _not_unicode(arguments: Mapping[str, Any]) -> str | None:
    """The name of the first argument whose name or value (any string in it, keys too)
    holds a lone surrogate, shown with it escaped; None if none does."""
    for name, value in arguments.items():
        stack: list[object] = [name, value]
        while stack:  # not recursive: arguments may nest as deep as JSON does
            item = stack.pop()
            if isinstance(item, str) and LONE_SURROGATE.search(item):
                return name[:64].encode("utf-8", "backslashreplace").decode()
            if isinstance(item, Mapping):
                stack.extend(item)
                stack.extend(item.values())
            elif isinstance(item, list):
                stack.extend(item)
    return None


def _first(error: ValidationError) -> str:
    item = error.errors()[0]
    where = ".".join(str(part) for part in item["loc"]) or "arguments"
    return f"{where}: {item['msg']}"


def _no_trial() -> Reply:
    return Reply.refusal(RefusalCode.NO_TRIAL, "no trial on this connection: call start_trial")
