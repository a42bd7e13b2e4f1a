"""What an LLM reasoner needs from a model server: one chat completion with a JSON schema.

Backends (an OpenAI-compatible server, llama.cpp in process, a recording) implement
:class:`ChatBackend`; they raise :class:`~actionreasoning.errors.LLMError` with a failure
code when the model cannot be reached or answers with something that is not a completion.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, Protocol

from actionreasoning.records import LLMUsage
from actionreasoning.world.pictures import Picture

#: A chat message: ``role`` and ``content``, the content text, or, for a prompt that carries
#: pictures, OpenAI's list of content parts: the text, then one ``image_url`` part per
#: picture (a base64 PNG ``data:`` URL).
Message = dict[str, Any]


def user_message(text: str, pictures: Sequence[Picture] = ()) -> Message:
    """A user message of ``text``, with ``pictures`` as image parts after it if any."""
    if not pictures:
        return {"role": "user", "content": text}
    images = [{"type": "image_url", "image_url": {"url": p.data_url}} for p in pictures]
    return {"role": "user", "content": [{"type": "text", "text": text}, *images]}


def message_text(message: Mapping[str, Any]) -> str:
    """The text of a message: its content, or its text parts' joined by newlines."""
    content = message.get("content")
    if isinstance(content, list):
        return "\n".join(
            str(part.get("text", ""))
            for part in content
            if isinstance(part, Mapping) and part.get("type") == "text"
        )
    return str(content or "")


def image_urls(message: Mapping[str, Any]) -> list[str]:
    """The URLs of a message's image parts, in order."""
    content = message.get("content")
    if not isinstance(content, list):
        return []
    return [
        str(part["image_url"].get("url", ""))
        for part in content
        if isinstance(part, Mapping)
        and part.get("type") == "image_url"
        and isinstance(part.get("image_url"), Mapping)
    ]


class StructuredMode(StrEnum):
    """How a server is asked for JSON, from the strictest to none."""

    JSON_SCHEMA = "json_schema"  # OpenAI structured outputs
    JSON_OBJECT_SCHEMA = "json_object_schema"  # llama-cpp-python: json_object with a schema
    JSON_OBJECT = "json_object"  # plain JSON mode; validation does the rest
    TEXT = "text"  # no response format at all


def response_format(mode: StructuredMode, name: str, schema: dict[str, Any]) -> dict[str, Any]:
    """The ``response_format`` request field for ``mode`` (empty for plain text)."""
    if mode is StructuredMode.JSON_SCHEMA:
        return {"type": "json_schema", "json_schema": {"name": name, "schema": schema}}
    if mode is StructuredMode.JSON_OBJECT_SCHEMA:
        return {"type": "json_object", "schema": schema}
    if mode is StructuredMode.JSON_OBJECT:
        return {"type": "json_object"}
    return {}


@dataclass(frozen=True)
class ChatRequest:
    """One completion request: the conversation so far and the answer's JSON schema."""

    messages: tuple[Message, ...]
    schema_name: str
    schema: dict[str, Any]


@dataclass(frozen=True)
class ChatReply:
    """The model's text, what it cost, and the model's name as the server gave it."""

    content: str
    usage: LLMUsage
    model: str = ""


class ChatBackend(Protocol):
    """A model behind a chat-completion interface."""

    label: str  # the --llm spec the results name, e.g. "openai:gpt-4o-mini"

    def complete(self, request: ChatRequest) -> ChatReply:
        """One completion; raises LLMError if the server fails."""
        ...
