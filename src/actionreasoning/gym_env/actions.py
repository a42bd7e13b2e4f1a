"""An action's JSON text: one tool call, ``{"tool": NAME, "arguments": {...}}``, or one
answer, ``{"answer": {...}}`` (the agent's output as an object, or as the text a model
would write). Anything else is a typed refusal, never an error."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from actionreasoning.gym_env.observation import MAX_ACTION_CHARS, foreign_character
from actionreasoning.trial.session import Refusal, RefusalCode
from actionreasoning.world.json_text import JSONTextError, parse_json

FORMAT = 'an action is {"tool": NAME, "arguments": {...}} or {"answer": {...}}'


@dataclass(frozen=True)
class ToolAction:
    """Run one of the waiting agent's tools, or one of the gates' measurements."""

    name: str
    arguments: Any


@dataclass(frozen=True)
class AnswerAction:
    """Submit the waiting agent's answer, as JSON text."""

    text: str


def parse_action(action: object) -> ToolAction | AnswerAction | Refusal:
    """What ``action`` asks for, or why it asks for nothing."""
    if not isinstance(action, str):
        return _refused(f"the action is JSON text, not {type(action).__name__}")
    if len(action) > MAX_ACTION_CHARS:
        return _refused(f"the action is {len(action)} characters, more than {MAX_ACTION_CHARS}")
    if (index := foreign_character(action)) is not None:
        code = ord(action[index])
        return _refused(
            f"character {index} of the action, U+{code:04X}, is outside the action space: "
            "a surrogate, or a control character other than tab, newline and carriage return"
        )
    try:
        data = parse_json(action)
    except JSONTextError as error:
        return _refused(f"{error}; {FORMAT}")
    if isinstance(data, dict) and data.keys() == {"answer"}:
        answer = data["answer"]
        return AnswerAction(answer if isinstance(answer, str) else json.dumps(answer))
    if isinstance(data, dict) and data.keys() in ({"tool"}, {"tool", "arguments"}):
        if isinstance(data["tool"], str):
            return ToolAction(data["tool"], data.get("arguments", {}))
    return _refused(FORMAT)


def _refused(detail: str) -> Refusal:
    return Refusal(code=RefusalCode.INVALID_ACTION, detail=detail)
