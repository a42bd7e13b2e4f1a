"""The prompt-only reference model: answers a chat conversation from its text alone.

It is what a perfect reader of our prompts would answer. It never sees the simulator or
any object of the run: everything it knows is parsed from the messages a chat server
receives; in the image tier, the bricks too are read from the prompt's pictures alone
(``sight.py``). From the first message, the agent's prompt, it reads which agent it is, the
state S_t, the memory M_t and the thresholds; from its own earlier answers and the
``Tool results`` messages after them, what each tool call returned. It then runs the
built-in policy on that :class:`Briefing`, in the reasoning tier the prompt names, whose
tools answer from those results. When the policy needs tool results the conversation does
not hold yet, the model answers with those tool calls (one turn's together), as a language
model does, and is asked again with the results.

A prompt missing a fact the policy needs (the state block, a field of it, a tool result
field) cannot be answered: :class:`UnreadableConversation` says which.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import sys
from collections.abc import Mapping, Sequence
from typing import Any

from pydantic import BaseModel, ValidationError

from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.observation import Observation
from actionreasoning.agents.outputs import AgentAnswer, ToolCall
from actionreasoning.agents.prompt import (
    MEMORY_HEADING,
    STATE_HEADING,
    THRESHOLD_LINE,
    THRESHOLDS_HEADING,
)
from actionreasoning.agents.reasoner import Briefing
from actionreasoning.agents.spec import AgentSpec, agent_specs, single_agent_spec
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.agents.view import StateView
from actionreasoning.reasoners import builtin
from actionreasoning.reasoners.chat import image_urls, message_text
from actionreasoning.reasoners.llm import NO_MORE_TOOLS, TOOL_RESULTS
from actionreasoning.tools.base import ToolModel
from actionreasoning.tools.registry import TOOLS
from actionreasoning.world.json_text import JSONTextError, parse_json
from actionreasoning.world.pictures import Picture, PictureKind, png_of
from actionreasoning.world.tolerances import Tolerances

Message = Mapping[str, Any]
_AGENT_HEADING = re.compile(r"# Agent ([1-6]) of 6: ")
_SINGLE_HEADING = "# Single agent"
_TIER_LINE = re.compile(r"^Reasoning tier: (solve|check|none) ", re.M)
_OBSERVATION_LINE = re.compile(r"^Observation: (image|both) ", re.M)
_PICTURES_LINE = re.compile(
    r"^This call carries \d+ pictures of the scene now, in this order: (.+)\.$", re.M
)


class UnreadableConversation(ValueError):
    """A conversation the reference model cannot answer; the message says why."""


class _NeedTools(Exception):
    """The policy asked for tool results the conversation does not hold (one turn's)."""

    def __init__(self, calls: list[ToolCall]) -> None:
        super().__init__(", ".join(call.name for call in calls))
        self.calls = calls


def reply(messages: Sequence[Message]) -> str:
    """The assistant's answer (JSON text) to ``messages``."""
    if not messages:
        raise UnreadableConversation("the conversation has no messages")
    prompt = message_text(messages[0])
    spec = _spec_of(prompt)
    if spec is None:
        return _literal_answer(messages[-1])
    results = _tool_results(messages)
    exhausted = NO_MORE_TOOLS in message_text(messages[-1])

    def call_tools(calls: Sequence[tuple[str, Mapping[str, Any]]]) -> list[ToolModel]:
        missing = [(name, args) for name, args in calls if _key(name, args) not in results]
        if missing and exhausted:
            name, arguments = missing[0]
            raise UnreadableConversation(
                f"needs {name} {_args(arguments)} but may call no more tools"
            )
        if missing:
            raise _NeedTools([ToolCall(name=name, arguments=dict(args)) for name, args in missing])
        return [_result(name, args) for name, args in calls]

    def _result(name: str, arguments: Mapping[str, Any]) -> ToolModel:
        outcome = results[_key(name, arguments)]
        if "error" in outcome:
            raise UnreadableConversation(f"{name} failed: {outcome['error']}")
        try:
            return TOOLS[name].output_model.model_validate(outcome.get("result"))
        except ValidationError as error:
            raise UnreadableConversation(
                f"the result of {name} is incomplete: {_first(error)}"
            ) from None

    briefing = Briefing(
        agent=spec.key,
        view=_block(prompt, STATE_HEADING, StateView),
        memory=_block(prompt, MEMORY_HEADING, TaskMemory),
        tolerances=_thresholds(prompt),
        call_tool=lambda name, arguments: call_tools([(name, arguments)])[0],
        tier=spec.tier,
        call_tools=call_tools,
        observation=spec.observation,
        pictures=() if spec.observation.poses else _pictures(messages[0], prompt),
    )
    try:
        answer: AgentAnswer = builtin.answer(briefing)
    except _NeedTools as need:
        answer = spec.output_model(tool_calls=need.calls, rationale=f"measure with {need} first")
    except UnreadableConversation:
        raise
    except OSError as error:  # a picture whose PNG does not decode
        raise UnreadableConversation(f"a picture cannot be read: {error}") from None
    except (KeyError, ValueError, StopIteration) as error:
        raise UnreadableConversation(
            f"the prompt does not say enough to answer: {error!r}"
        ) from None
    return answer.model_dump_json(exclude_defaults=True)


def _spec_of(prompt: str) -> AgentSpec | None:
    """The agent a prompt is written for, in the tier it names, or None for a message that
    is no agent prompt."""
    found = _AGENT_HEADING.match(prompt)
    if found is None and not prompt.startswith(_SINGLE_HEADING):
        return None
    named = _TIER_LINE.search(prompt)
    if named is None:
        raise UnreadableConversation("the prompt names no reasoning tier")
    tier = ToolTier(named.group(1))
    seen = _OBSERVATION_LINE.search(prompt)
    observation = Observation.STATE if seen is None else Observation(seen.group(1))
    if found is None:
        if not observation.poses:
            raise UnreadableConversation("the single agent observes the state: not image")
        return single_agent_spec(tier, observation)
    return agent_specs(tier, observation)[int(found.group(1)) - 1]


def _pictures(message: Message, prompt: str) -> tuple[Picture, ...]:
    """The pictures of the prompt's message, named as its Cameras section lists them."""
    listed = _PICTURES_LINE.search(prompt)
    if listed is None:
        raise UnreadableConversation("the prompt does not say which pictures it carries")
    names, urls = listed.group(1).split(", "), image_urls(message)
    if len(urls) != len(names):
        raise UnreadableConversation(
            f"the prompt names {len(names)} pictures and its message carries {len(urls)}"
        )
    pictures = []
    for name, url in zip(names, urls, strict=True):
        camera, _, kind = name.partition(".")
        png = png_of(url)
        if png is None or kind not in PictureKind.__members__.values():
            raise UnreadableConversation(f"picture {name[:40]!r} is no base64 PNG data URL")
        pictures.append(Picture(camera, PictureKind(kind), png))
    return tuple(pictures)


def _block(prompt: str, heading: str, model: type[BaseModel]) -> Any:
    """The JSON block under ``heading``, validated as ``model``."""
    found = re.search(re.escape(heading) + r"\n```json\n(.*?)\n```", prompt, re.S)
    if found is None:
        raise UnreadableConversation(f"the prompt has no JSON block under {heading!r}")
    try:
        return model.model_validate_json(found.group(1))
    except ValidationError as error:
        raise UnreadableConversation(f"{heading[3:]}: {_first(error)}") from None


def _thresholds(prompt: str) -> Tolerances:
    """The gate thresholds, from the ``- name = value: ...`` lines under their heading."""
    section = prompt.partition(THRESHOLDS_HEADING + "\n")[2].partition("\n\n")[0]
    pairs = {name: value for name, value, _ in THRESHOLD_LINE.findall(section)}
    if not pairs:
        raise UnreadableConversation(f"the prompt has no {THRESHOLDS_HEADING!r} lines")
    try:
        shown = {name: float(value) for name, value in pairs.items()}
        Tolerances.model_validate(shown)  # each shown value within its bounds
    except (ValueError, ValidationError) as error:
        raise UnreadableConversation(f"thresholds: {error}") from None
    # A threshold the prompt does not show is NaN: a policy that read it would fail its
    # comparisons, never fall back on a default it was not told.
    unknown = {name: math.nan for name in Tolerances.model_fields if name not in shown}
    return Tolerances.model_construct(None, **unknown, **shown)


def _tool_results(messages: Sequence[Message]) -> dict[str, dict[str, Any]]:
    """Each tool call of the model's earlier answers, keyed by name and arguments, with
    what came back for it (``result`` or ``error``)."""
    results: dict[str, dict[str, Any]] = {}
    for asked, answered in itertools.pairwise(messages[1:]):
        text = message_text(answered)
        if asked.get("role") != "assistant" or not text.startswith(TOOL_RESULTS):
            continue
        try:
            calls = parse_json(message_text(asked)).get("tool_calls", [])
            outcomes = parse_json(text[len(TOOL_RESULTS) :].split("\n", 1)[0])
            for call, outcome in zip(calls, outcomes, strict=False):
                results[_key(call["name"], call.get("arguments", {}))] = outcome
        except (JSONTextError, AttributeError, KeyError, TypeError) as error:
            raise UnreadableConversation(f"unreadable tool turn: {error!r}"[:200]) from None
    return results


def _key(name: str, arguments: Mapping[str, Any]) -> str:
    return name + json.dumps(arguments, sort_keys=True)


def _args(arguments: Mapping[str, Any]) -> str:
    return json.dumps(arguments, sort_keys=True)[:120]


def _first(error: ValidationError) -> str:
    item = error.errors()[0]
    return ".".join(str(part) for part in item["loc"]) + f": {item['msg']}"


def _literal_answer(message: Message) -> str:
    """For a message that is no agent's prompt: the first JSON object written in it."""
    text = message_text(message)
    decoder = json.JSONDecoder()
    for start, char in enumerate(text):
        if char != "{":
            continue
        try:
            value, _ = decoder.raw_decode(text, start)
        except json.JSONDecodeError:
            continue
        except RecursionError:
            raise UnreadableConversation("the JSON in the message is nested too deeply") from None
        except ValueError:  # an integer too long to convert
            limit = sys.get_int_max_str_digits()
            raise UnreadableConversation(
                f"a number in the message's JSON has more than {limit} digits"
            ) from None
        if isinstance(value, dict):
            return json.dumps(value)
    raise UnreadableConversation("the last message is no agent prompt and holds no JSON object")
