"""Validation of a model's answer: text in, a checked answer of the agent's schema out.

LLM output is data. It is parsed as JSON (never evaluated), validated against the agent's
output schema, and checked against physical bounds: finite numbers, tool positions inside
the workspace box, unit quaternions (normalised within a tolerance, else refused), brick
ids and target indexes that exist, and tool calls to whitelisted tools of the agent's
knowledge base with typed arguments. An answer that calls no tools must then be a complete
decision (``outputs.DECISIONS``). A failure is an :class:`OutputError` whose message is
short enough to send back to the model for a repair, and whose ``category`` says what kind
of error it is.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any, TypeVar

from pydantic import ValidationError

from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.outputs import (
    DECISIONS,
    AgentAnswer,
    WaypointProposal,
    unit_waypoint,
)
from actionreasoning.agents.spec import AgentSpec
from actionreasoning.errors import ActionReasoningError
from actionreasoning.tools.registry import TOOLS
from actionreasoning.world.json_text import JSONTextError, parse_json
from actionreasoning.world.models import WorldState
from actionreasoning.world.scene_spec import WORKSPACE, WorkspaceBox

MAX_ANSWER_CHARS = 20_000
MAX_ERRORS_SHOWN = 3
_FENCE = re.compile(r"^```(?:json)?\s*(.*?)\s*```$", re.S)

D = TypeVar("D", bound=AgentAnswer)


class OutputError(ActionReasoningError):
    """A model's answer that is not a valid answer; the message says what to repair, the
    ``category`` what kind of error it is."""

    def __init__(self, message: str, category: ErrorCategory) -> None:
        super().__init__(message)
        self.category = category


def parse_answer(
    text: str,
    spec: AgentSpec,
    state: WorldState,
    workspace: WorkspaceBox = WORKSPACE,
    normalise: bool = True,
) -> AgentAnswer:
    """The answer in ``text`` as ``spec``'s output model, checked and normalised (see
    :func:`check_answer` for ``normalise``): a tool turn (it lists ``tool_calls``), or else
    its agent's complete decision."""
    data = _json_object(text)
    try:
        answer = spec.output_model.model_validate(data)
    except ValidationError as error:
        raise OutputError(_describe(error), ErrorCategory.SCHEMA) from None
    checked = check_answer(answer, spec, state, workspace, normalise)
    if checked.tool_calls:
        return checked
    decided = complete(DECISIONS[spec.output_model], checked)
    # The single agent's decision is its step's agent's: its answer goes on as it is.
    return decided if isinstance(decided, spec.output_model) else checked


def complete(decide: Callable[[AgentAnswer], D], answer: AgentAnswer) -> D:
    """``answer`` as the decision ``decide`` makes of it (a function of ``DECISIONS``);
    an incomplete one is an OutputError (``schema``) that names the fields it leaves out."""
    try:
        return decide(answer)
    except ValidationError as error:
        raise OutputError(_describe(error), ErrorCategory.SCHEMA) from None


def check_answer(
    answer: AgentAnswer,
    spec: AgentSpec,
    state: WorldState,
    workspace: WorkspaceBox,
    normalise: bool = True,
) -> AgentAnswer:
    """Physical bounds, known ids and whitelisted tools; returns it with unit quaternions,
    or without ``normalise`` with the quaternion as given (checked to be unit within
    tolerance; the orchestrator normalises every waypoint it executes), so that an answer
    from outside reaches it exactly as the same answer from an in-process reasoner."""
    update: dict[str, Any] = {}
    waypoint = getattr(answer, "waypoint", None)
    if isinstance(waypoint, WaypointProposal):
        if not workspace.contains(waypoint.position_m):
            raise OutputError(
                f"waypoint.position_m {_short(waypoint.position_m)} is outside the workspace "
                f"box {_short(workspace.low_m)} .. {_short(workspace.high_m)} m",
                ErrorCategory.FRAME_UNITS,
            )
        try:
            unit = unit_waypoint(waypoint)
        except ValueError as error:
            raise OutputError(
                f"waypoint.quat_xyzw: {error} (give a unit quaternion)", ErrorCategory.FRAME_UNITS
            ) from None
        if normalise:
            update["waypoint"] = unit
    brick = getattr(answer, "brick_id", None)
    if brick is not None and brick not in {b.id for b in state.bricks}:
        raise OutputError(
            f"brick_id {brick} names no brick (ids 0..{len(state.bricks) - 1})",
            ErrorCategory.HALLUCINATED_ID,
        )
    target = getattr(answer, "target_index", None)
    if target is not None and target >= len(state.goal.targets):
        count = len(state.goal.targets)
        raise OutputError(
            f"target_index {target} names no target (0..{count - 1})",
            ErrorCategory.HALLUCINATED_ID,
        )
    for index, call in enumerate(answer.tool_calls):
        if call.name not in spec.tools:
            raise OutputError(
                f"tool_calls[{index}].name {call.name[:40]!r} is not one of your tools: "
                + ", ".join(spec.tools),
                ErrorCategory.HALLUCINATED_ID,
            )
        try:
            TOOLS[call.name].input_model.model_validate(call.arguments)
        except ValidationError as error:
            raise OutputError(
                f"tool_calls[{index}] ({call.name}): {_describe(error)}", ErrorCategory.SCHEMA
            ) from None
    return answer.model_copy(update=update) if update else answer


def _json_object(text: str) -> dict[str, Any]:
    """The one JSON object in ``text`` (a Markdown code fence around it is allowed)."""
    if len(text) > MAX_ANSWER_CHARS:
        raise OutputError(
            f"the answer is {len(text)} characters; answer with one short object",
            ErrorCategory.SCHEMA,
        )
    stripped = text.strip()
    fenced = _FENCE.match(stripped)
    if fenced:
        stripped = fenced.group(1)
    try:
        data = parse_json(stripped)
    except JSONTextError as error:
        raise OutputError(str(error), ErrorCategory.SCHEMA) from None
    if not isinstance(data, dict):
        raise OutputError(
            f"the answer must be a JSON object, not {type(data).__name__}", ErrorCategory.SCHEMA
        )
    return data


def _describe(error: ValidationError) -> str:
    """The first few schema errors, one line each, without echoing long inputs; an error of
    the whole answer (an incomplete decision) as its message alone."""
    parts = []
    for item in error.errors()[:MAX_ERRORS_SHOWN]:
        where = ".".join(str(part) for part in item["loc"])
        parts.append(f"{where}: {item['msg']}" if where else item["msg"])
    more = len(error.errors()) - MAX_ERRORS_SHOWN
    return "; ".join(parts) + (f"; and {more} more" if more > 0 else "")


def _short(values: Any) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in values) + ")"
