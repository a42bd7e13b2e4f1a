"""One trial driven from outside: one agent answer or one tool call at a time.

The trial runs as ``eval`` runs it (:func:`~actionreasoning.trial.runner.run_trial`: the same
scene, agents, validation, gates and controller) in a thread of its own, with an outside
agent as its reasoner. When an agent asks, the trial waits; the session's caller reads the
question (:meth:`TrialSession.turn`), calls the agent's tools (and, whichever agent waits,
the gates' measurements: :meth:`TrialSession.measure`) and submits an answer as text. The
answer is parsed and checked as a language model's is (``agents/validation.py``; its
quaternion goes on as given, for the orchestrator to normalise once, as an in-process
reasoner's does): a refused one changes nothing and the agent waits for another; one that
lists tool calls gets their results back and the agent waits too. A valid decision goes to
the gates and the controller, and the call returns when the trial asks its next question or
ends, with the answer's gate verdicts, outcome and feedback. The threads hand the simulator
over: while one runs, the other waits, so PyBullet never runs in both at once. Closing the
session ends a trial still running with the failure ``abandoned``, measured like any other.

The Gymnasium environment (``gym_env``) and the MCP server are doors to this one core.
"""

from __future__ import annotations

import os
import queue
import threading
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from enum import StrEnum
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from pydantic import BaseModel, Field

from actionreasoning.agents.answer_errors import AnswerErrors
from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.observation import DEFAULT_OBSERVATION, load_observation
from actionreasoning.agents.reasoner import AgentReply, AgentRequest, ToolRunner
from actionreasoning.agents.tiers import DEFAULT_TIER, load_tier
from actionreasoning.agents.transcript import AgentCall
from actionreasoning.agents.validation import OutputError, parse_answer
from actionreasoning.agents.verification import Verification
from actionreasoning.errors import (
    ActionReasoningError,
    ConfigError,
    LLMError,
    PatternError,
    ToolError,
)
from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.records import FailureCode
from actionreasoning.sim.camera import overview, render
from actionreasoning.sim.scene import Scene
from actionreasoning.tools.base import ToolModel
from actionreasoning.tools.registry import (
    GATE_MEASUREMENTS,
    ToolSchema,
    measurements,
    tool_schema,
)
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.placed import PlacedCount
from actionreasoning.trial.results import TrialResult
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialObserver, TrialRun, TrialSpec, run_trial
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.config_files import check_file_name
from actionreasoning.world.models import GoalPattern, WorldState
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scenarios import load_noise, load_physics
from actionreasoning.world.stages import StageEvent

T = TypeVar("T")


class SessionError(ActionReasoningError):
    """The session cannot do what was asked now (the trial has ended, a request was
    already answered)."""


class AgentLabel(StrEnum):
    """What the results line (``llm``) calls a session's outside agent: the door it came
    through."""

    OUTSIDE = "outside"  # none: the session itself, called from Python
    GYM = "gym"  # the Gymnasium environment
    MCP = "mcp"  # the MCP server


class RefusalCode(StrEnum):
    """Why an outside agent's action changed nothing."""

    INVALID_ACTION = "invalid_action"  # neither a tool call nor an answer (a door's format)
    INVALID_ANSWER = "invalid_answer"  # not JSON, not the agent's schema, or out of bounds
    UNKNOWN_TOOL = "unknown_tool"  # neither the waiting agent's tool nor a gate measurement
    TOOL_ERROR = "tool_error"  # the tool refused its arguments
    TRIAL_OVER = "trial_over"  # no agent waits: the trial has ended
    NO_TRIAL = "no_trial"  # no trial was started (a door's: the MCP server's before start)


class Refusal(BaseModel):
    """A typed refusal: its code and what to change."""

    code: RefusalCode
    detail: str


class ToolReply(BaseModel):
    """A tool's result (its output model as JSON), or why it did not run."""

    tool: str
    result: dict[str, Any] | None = None
    refusal: Refusal | None = None


class AnswerReply(BaseModel):
    """What became of a submitted answer: refused (nothing ran), tool calls run (the agent
    waits for its decision), or judged: the agent call's record with the gate verdicts,
    every check, the outcome and the feedback."""

    refusal: Refusal | None = None
    tools: list[ToolReply] = Field(default_factory=list)
    call: AgentCall | None = None


class Turn(BaseModel):
    """What the waiting agent is asked: its prompt, the measured state S_t, its tools and
    the gates' measurements it may run too, with their schemas, the schema of its answer,
    and the feedback on its last refused answer."""

    agent: str
    prompt: str
    state: WorldState
    tools: list[ToolSchema]
    measurements: list[ToolSchema]
    answer_schema: dict[str, Any]
    feedback: str


@dataclass(frozen=True)
class Conditions:
    """What ``eval`` runs a pattern under, loaded as the command loads it (a pattern name
    or file, a physics profile, a noise level, the trial's budget, the reasoning tier, and
    for eval's own trials the reasoning backend, its answer errors, the rung of
    verification and what the agents observe)."""

    pattern_name: str
    goal: GoalPattern
    config: TrialConfig

    @classmethod
    def load(
        cls,
        pattern: str = "pyramid",
        physics: str = "paper",
        noise: str = "none",
        budget: TrialBudget = TrialBudget(),
        tools: str = DEFAULT_TIER,
        *,
        llm: LLMConfig | None = LLMConfig(),
        answer_errors: AnswerErrors = AnswerErrors(),
        verify: Verification | None = None,
        observe: str = DEFAULT_OBSERVATION,
    ) -> Conditions:
        """The conditions named as on the command line; a bad name or file is refused."""
        check_file_name(pattern, "pattern", PatternError)
        if Path(pattern).is_file():  # one file, however it is spelled: ./x.json is x.json
            pattern = os.path.normpath(pattern)
        config = TrialConfig(
            llm=llm,
            budget=budget,
            physics=load_physics(physics),
            noise=load_noise(noise),
            answer_errors=answer_errors,
            tools=load_tier(tools),
            verify=verify,
            observe=load_observation(observe),
        )
        return cls(pattern_name=pattern, goal=load_pattern(pattern, config.scene), config=config)

    def spec(self, seed: int, trial: int) -> TrialSpec:
        """Trial ``trial`` of ``eval --seed seed`` under these conditions: the same bricks."""
        for name, value in (("seed", seed), ("trial", trial)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ConfigError(f"{name} must be a whole number >= 0, not {value!r}")
        return TrialSpec(
            method=Method.AGENTS,
            pattern_name=self.pattern_name,
            goal=self.goal,
            run_seed=seed,
            trial=trial,
            config=self.config,
        )


class TrialSession:
    """One trial, its agents answered by the caller; results name the reasoner ``agent``.

    The constructor returns when the first agent asks (or the trial has ended). Use it as a
    context manager, or call :meth:`close`; a session dropped unclosed is closed too. With
    ``final_picture``, it keeps the overview picture of the trial's final scene for
    :meth:`picture`.
    """

    def __init__(
        self,
        spec: TrialSpec,
        observers: Sequence[TrialObserver] = (),
        agent: str = AgentLabel.OUTSIDE,
        *,
        final_picture: bool = False,
    ) -> None:
        self.spec = spec
        self._inbox: queue.Queue[object] = queue.Queue()
        self._outbox: queue.Queue[object] = queue.Queue()
        self._lock = threading.Lock()
        self._request: AgentRequest | None = None
        self._run: TrialRun | None = None
        self._ended = False
        self._watch = _Watch()
        self._placed = PlacedCount(spec.goal, spec.config.success_rule)
        self._final = _FinalPicture() if final_picture else None
        watchers = (self._watch, self._placed, *([self._final] if self._final else []))
        outside = _OutsideAgent(str(agent), self._inbox, self._outbox, self._watch)
        self._thread = threading.Thread(
            target=_run,
            args=(spec, (*watchers, *observers), outside, self._outbox),
            name=f"trial {spec.run_seed}/{spec.trial}",
            daemon=True,
        )
        # Dropped unclosed: end the trial then (not at interpreter exit, when the daemon
        # thread is stopped where it is).
        weakref.finalize(self, self._inbox.put, _CLOSE).atexit = False
        self._thread.start()
        self._await()

    def __enter__(self) -> TrialSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def done(self) -> bool:
        """Whether the trial has ended."""
        return self._ended

    @property
    def run(self) -> TrialRun | None:
        """The finished trial: result line and transcript (None while it runs)."""
        return self._run

    @property
    def result(self) -> TrialResult | None:
        """The finished trial's result line, as ``eval`` writes it (None while it runs)."""
        return None if self._run is None else self._run.result

    @property
    def placed(self) -> int:
        """Bricks within the success rule of their targets: while the trial runs, as counted
        after its last accepted release (``placed.py``); once it has ended, its result's
        ``bricks_placed`` (after the final settle)."""
        result = self.result
        return self._placed.count if result is None else result.bricks_placed

    @property
    def request(self) -> AgentRequest | None:
        """The waiting agent's request (None once the trial has ended). Its ``call_tool``
        and ``measure`` run a tool in the trial, as the agent's tool call, and raise
        ToolError on a refusal: a :class:`~actionreasoning.agents.reasoner.Reasoner` can
        answer it."""
        request = self._request
        if request is None:
            return None

        def runner(measure: bool) -> ToolRunner:
            def run(name: str, arguments: Mapping[str, Any]) -> ToolModel:
                if self._request is not request:
                    raise SessionError("this request was answered: read session.request again")
                outcome = self._send(_ToolCall(name, dict(arguments), measure))
                if isinstance(outcome, ToolError):
                    raise ToolError(str(outcome))
                return outcome

            return run

        return replace(request, call_tool=runner(False), measure=runner(True))

    def turn(self) -> Turn | None:
        """The waiting agent's question as data (None once the trial has ended)."""
        request = self._request
        if request is None:
            return None
        return Turn(
            agent=str(request.spec.key),
            prompt=request.prompt,
            state=request.state,
            tools=[tool_schema(name) for name in request.spec.tools],
            measurements=[
                tool_schema(name) for name in measurements(request.spec.observation.poses)
            ],
            answer_schema=request.spec.output_model.model_json_schema(),
            feedback=request.memory.last_feedback,
        )

    def call_tool(self, name: str, arguments: Mapping[str, Any]) -> ToolReply:
        """Run one of the waiting agent's tools; its result, or a typed refusal."""
        return self._tool(name, arguments, measure=False)

    def measure(self, name: str, arguments: Mapping[str, Any]) -> ToolReply:
        """Run one of the gates' measurements (``GATE_MEASUREMENTS``) on the waiting agent's
        measured world, whichever agent waits, logged in its call as its tool calls are;
        its result, or a typed refusal."""
        return self._tool(name, arguments, measure=True)

    def use_tool(self, name: str, arguments: Mapping[str, Any]) -> ToolReply:
        """Run a tool by its name, as a door offers them all: a gate's measurement with
        :meth:`measure`, any other with :meth:`call_tool`."""
        run = self.measure if name in GATE_MEASUREMENTS else self.call_tool
        return run(name, arguments)

    def answer(self, text: str) -> AnswerReply:
        """Submit the waiting agent's answer (JSON text, as a language model writes it).

        Refused: nothing moved and the agent still waits. With tool calls: their results,
        and the agent still waits. Otherwise gated and executed; returns once the trial
        asks again or ends, with the call's record.
        """
        if not isinstance(text, str):
            detail = f"an answer is JSON text, not {type(text).__name__}"
            return AnswerReply(refusal=Refusal(code=RefusalCode.INVALID_ANSWER, detail=detail))
        if self._request is None:
            return AnswerReply(refusal=_over())
        replied = self._send(_Answer(text))
        if isinstance(replied, AnswerReply):
            return replied
        call = self._watch.last_call  # the answer's: recorded as soon as it was accepted
        assert call is not None
        return AnswerReply(call=call.model_copy(deep=True))

    def in_scene(self, do: Callable[[Scene], T]) -> T:
        """``do(scene)`` run in the trial's thread while the agent waits (pictures: it must
        only read). Its error is raised here."""
        if self._request is None:
            raise SessionError("the trial has ended: its scene is closed")
        outcome = self._send(_InScene(do))
        if isinstance(outcome, _Failed):
            raise outcome.error
        return outcome

    def picture(self) -> np.ndarray:
        """The overview camera's picture (height x width x 3, uint8) of the scene now, or,
        once the trial has ended, of its final scene (kept with ``final_picture``)."""
        if not self._ended:
            return self.in_scene(_overview)
        if self._final is None or self._final.image is None:
            raise SessionError("the trial has ended and its final picture was not kept")
        return self._final.image

    def close(self) -> TrialRun | None:
        """End the trial (``abandoned`` if an agent still waits) and return it."""
        if not self._ended:
            self._send(_CLOSE)
        return self._run

    def _tool(self, name: str, arguments: Mapping[str, Any], measure: bool) -> ToolReply:
        if not isinstance(name, str) or not _is_object(arguments):
            detail = "a tool call is a tool name and a JSON object of arguments"
            refusal = Refusal(code=RefusalCode.TOOL_ERROR, detail=detail)
            return ToolReply(tool=str(name)[:64], refusal=refusal)
        if self._request is None:
            return ToolReply(tool=name[:64], refusal=_over())
        known = name in (GATE_MEASUREMENTS if measure else self._request.spec.tools)
        return _tool_reply(name, self._send(_ToolCall(name, dict(arguments), measure)), known)

    def _send(self, command: object) -> Any:
        """Hand ``command`` to the waiting trial and wait for it to hand back: the command's
        value, or None when the trial moved on to its next request or ended."""
        with self._lock:
            if self._ended:
                raise SessionError("the trial has ended")
            self._inbox.put(command)
            return self._await()

    def _await(self) -> Any:
        event = self._outbox.get()
        if isinstance(event, _Asked):
            self._request = event.request
            return None
        if isinstance(event, _Ended):
            self._request, self._run, self._ended = None, event.run, True
            self._thread.join()
            if event.error is not None:
                raise event.error
            return None
        assert isinstance(event, _Replied)
        return event.value


_CLOSE = object()


@dataclass(frozen=True)
class _ToolCall:
    name: str
    arguments: dict[str, Any]
    measure: bool = False


@dataclass(frozen=True)
class _Answer:
    text: str


@dataclass(frozen=True)
class _InScene:
    do: Callable[[Scene], Any]


@dataclass(frozen=True)
class _Failed:
    error: Exception


@dataclass(frozen=True)
class _Asked:
    request: AgentRequest


@dataclass(frozen=True)
class _Replied:
    value: Any


@dataclass(frozen=True)
class _Ended:
    run: TrialRun | None
    error: Exception | None = None


class _Watch(TrialObserver):
    """The trial's scene and the record of its latest agent call."""

    def __init__(self) -> None:
        self.scene: Scene | None = None
        self.last_call: AgentCall | None = None

    def start(self, scene: Scene) -> None:
        self.scene = scene

    def call(self, scene: Scene, call: AgentCall) -> None:
        self.last_call = call


class _FinalPicture(TrialObserver):
    """The overview picture of the trial's final scene (rendered in the trial's thread)."""

    def __init__(self) -> None:
        self.image: np.ndarray | None = None

    def stage(self, scene: Scene, event: StageEvent) -> None:
        if event.brick < 0:
            self.image = _overview(scene)


def _overview(scene: Scene) -> np.ndarray:
    return render(scene, overview(scene))


class _OutsideAgent:
    """The trial's reasoner: hands each request out and waits for the session's commands,
    in the trial's thread."""

    def __init__(
        self, name: str, inbox: queue.Queue[object], outbox: queue.Queue[object], watch: _Watch
    ) -> None:
        self.name = name
        self.inbox, self.outbox, self.watch = inbox, outbox, watch

    def decide(self, request: AgentRequest) -> AgentReply:
        """Wait for a valid decision on ``request``; run the tools and the scene reads asked
        for meanwhile."""
        self.outbox.put(_Asked(request))
        refused: list[str] = []
        categories: list[ErrorCategory] = []
        turns = 0
        while True:
            command = self.inbox.get()
            if command is _CLOSE:
                detail = "the session closed while the agent waited"
                raise LLMError(
                    FailureCode.ABANDONED,
                    detail,
                    tuple(refused),
                    repair_categories=tuple(categories),
                )
            if isinstance(command, _InScene):
                self.outbox.put(_Replied(self._in_scene(command)))
                continue
            if isinstance(command, _ToolCall):
                turns += 1
                run = request.measure if command.measure else request.call_tool
                self.outbox.put(_Replied(_run_tool(run, command.name, command.arguments)))
                continue
            assert isinstance(command, _Answer)
            try:
                answer = parse_answer(command.text, request.spec, request.state, normalise=False)
            except OutputError as error:
                refused.append(str(error))
                categories.append(error.category)
                refusal = Refusal(code=RefusalCode.INVALID_ANSWER, detail=str(error))
                self.outbox.put(_Replied(AnswerReply(refusal=refusal)))
                continue
            if answer.tool_calls:
                turns += 1
                tools = [
                    _tool_reply(
                        call.name, _run_tool(request.call_tool, call.name, call.arguments), True
                    )
                    for call in answer.tool_calls
                ]
                self.outbox.put(_Replied(AnswerReply(tools=tools)))
                continue
            return AgentReply(
                answer=answer,
                repairs=tuple(refused),
                repair_categories=tuple(categories),
                tool_turns=turns,
            )

    def _in_scene(self, command: _InScene) -> Any:
        assert self.watch.scene is not None  # started before the first request
        try:
            return command.do(self.watch.scene)
        except Exception as error:  # the caller's function: its error is the caller's
            return _Failed(error)


def _run(
    spec: TrialSpec,
    observers: Sequence[TrialObserver],
    outside: _OutsideAgent,
    outbox: queue.Queue[object],
) -> None:
    """The trial thread: run the trial and hand back its end (or the error it crashed with)."""
    try:
        run = run_trial(spec, observers, outside)
    except Exception as error:
        outbox.put(_Ended(None, error))
        return
    outbox.put(_Ended(run))


def _run_tool(run: ToolRunner, name: str, arguments: Mapping[str, Any]) -> Any:
    """The tool's result, or the ToolError it was refused with (in the trial's thread)."""
    try:
        return run(name, arguments)
    except ToolError as error:
        return error


def _tool_reply(name: str, outcome: ToolModel | ToolError, known: bool) -> ToolReply:
    if isinstance(outcome, ToolError):
        code = RefusalCode.TOOL_ERROR if known else RefusalCode.UNKNOWN_TOOL
        return ToolReply(tool=name[:64], refusal=Refusal(code=code, detail=str(outcome)))
    return ToolReply(tool=name, result=outcome.model_dump(mode="json"))


def _is_object(arguments: object) -> bool:
    return isinstance(arguments, Mapping) and all(isinstance(key, str) for key in arguments)


def _over() -> Refusal:
    return Refusal(code=RefusalCode.TRIAL_OVER, detail="the trial has ended; no agent waits")
