"""An agent's conversation between :class:`~actionreasoning.reasoners.llm.LLMReasoner`'s
form and Inspect's.

The reasoner keeps a conversation as text: the prompt, the model's answers, tool results
and repair requests. A model that calls tools natively gets its tool calls back in the
reasoner's in-band form, an answer listing ``tool_calls`` (:func:`in_band`), which the
reasoner validates and runs as it does any answer. Going back to the model, each answer is
the model's own message again (its reasoning kept), a native tool call answered by one tool
message per call, split from the reasoner's tool results; a tool call the reasoner refused
or did not run stays its in-band text, as no tool message answers it. A prompt that
carries pictures (``--observe image`` or ``both``) goes as its text and one image per
picture, the same base64 PNG ``data:`` URLs.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence

from inspect_ai.model import (
    ChatMessage,
    ChatMessageAssistant,
    ChatMessageTool,
    ChatMessageUser,
    Content,
    ContentImage,
    ContentText,
)

from actionreasoning.reasoners.chat import Message, image_urls, message_text
from actionreasoning.reasoners.llm import TOOL_RESULTS


def in_band(message: ChatMessageAssistant) -> str:
    """The model's answer as the reasoner reads it: its text, or, if it called tools, an
    answer listing them (a call whose arguments were not JSON keeps the parse error as its
    arguments, for validation to refuse)."""
    if not message.tool_calls:
        return message.text
    calls = [
        {
            "name": call.function,
            "arguments": call.arguments if call.parse_error is None else call.parse_error,
        }
        for call in message.tool_calls
    ]
    return _json({"tool_calls": calls})


def chat_messages(
    messages: Sequence[Message], said: Mapping[str, ChatMessageAssistant]
) -> list[ChatMessage]:
    """The reasoner's conversation as Inspect messages; ``said`` maps each answer's text
    (as :func:`in_band` gave it) to the model's message."""
    chat: list[ChatMessage] = []
    answered = False
    for index, message in enumerate(messages):
        if answered:  # the tool results, already given as tool messages
            answered = False
            continue
        if message["role"] != "assistant":
            chat.append(ChatMessageUser(content=_content(message)))
            continue
        text = message["content"]
        own = said.get(text)
        if own is None:
            chat.append(ChatMessageAssistant(content=text))
        elif not own.tool_calls:
            chat.append(own)
        elif (results := _tool_messages(own, messages[index + 1 : index + 2])) is not None:
            chat += [own, *results]
            answered = True
        else:
            chat.append(ChatMessageAssistant(content=text))
    return chat


def _content(message: Message) -> str | list[Content]:
    """A user message's content in Inspect's terms: its text, then its pictures if any."""
    urls = image_urls(message)
    if not urls:
        return message_text(message)
    return [ContentText(text=message_text(message)), *(ContentImage(image=u) for u in urls)]


def _tool_messages(
    call: ChatMessageAssistant, following: Sequence[Message]
) -> list[ChatMessage] | None:
    """The tool messages answering ``call``'s tool calls and the reasoner's words after
    them, from the message following it if that holds one result per call; else None."""
    told = message_text(following[0]) if following else ""
    if not told.startswith(TOOL_RESULTS):
        return None
    results_text, _, then = told[len(TOOL_RESULTS) :].partition("\n")
    results = json.loads(results_text)
    calls = call.tool_calls or []
    if len(results) != len(calls):
        return None
    answers: list[ChatMessage] = [
        ChatMessageTool(content=_json(result), tool_call_id=tool.id, function=tool.function)
        for tool, result in zip(calls, results, strict=True)
    ]
    return [*answers, ChatMessageUser(content=then)]


def _json(data: object) -> str:
    """Compact JSON, numbers as they are."""
    return json.dumps(data, separators=(",", ":"))
