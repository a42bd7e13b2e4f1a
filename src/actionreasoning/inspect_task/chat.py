"""Inspect's model as a :class:`~actionreasoning.reasoners.chat.ChatBackend`.

A trial runs in a worker thread of Inspect's event loop (``anyio.to_thread``); each
completion is Inspect's ``generate`` run back on that loop (``anyio.from_thread``), so
Inspect's retries, cache, limits and transcript apply to every agent call. A request sends
the reasoner's conversation (``conversation.py``), the answer's schema as structured output
and the agent's tools as tools the model may call natively; the model's answer goes back to
:class:`~actionreasoning.reasoners.llm.LLMReasoner` as text, native tool calls in its
in-band form, for validation, repairs, tool turns and the gates as in ``eval``. A model
that answers with no choice at all is ``llm_bad_response``; an error Inspect raises (after
its own retries) is not the model's answer and ends the sample with that error, for
``inspect eval-retry``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence

import anyio.from_thread
from inspect_ai.model import (
    ChatMessageAssistant,
    GenerateConfig,
    Model,
    ModelOutput,
    ModelUsage,
)
from inspect_ai.tool import ToolInfo

from actionreasoning.errors import LLMError
from actionreasoning.inspect_task.conversation import chat_messages, in_band
from actionreasoning.inspect_task.schemas import response_schema
from actionreasoning.reasoners.chat import ChatReply, ChatRequest
from actionreasoning.records import FailureCode, LLMUsage


class InspectChat:
    """Completions of Inspect's ``model`` for one trial, whose agents (by key) have
    ``tools``."""

    def __init__(self, model: Model, tools: Mapping[str, Sequence[ToolInfo]]) -> None:
        self.model = model
        self.tools = tools
        self.label = f"inspect:{model}"
        self._said: dict[str, ChatMessageAssistant] = {}

    def complete(self, request: ChatRequest) -> ChatReply:
        """One completion; call it from a worker thread of Inspect's event loop."""
        started = time.perf_counter()
        output = anyio.from_thread.run(self._generate, request)
        latency = time.perf_counter() - started
        if output.empty:
            why = f": {output.error}" if output.error else ""
            raise LLMError(FailureCode.LLM_BAD_RESPONSE, f"{self.model} gave no answer{why}")
        content = in_band(output.message)
        self._said[content] = output.message
        usage = output.usage or ModelUsage()
        cached = (usage.input_tokens_cache_read or 0) + (usage.input_tokens_cache_write or 0)
        return ChatReply(
            content=content,
            model=output.model or str(self.model),
            usage=LLMUsage(
                calls=1,
                prompt_tokens=usage.input_tokens + cached,  # Inspect counts cached input apart
                completion_tokens=usage.output_tokens,
                latency_s=latency,
            ),
        )

    async def _generate(self, request: ChatRequest) -> ModelOutput:
        return await self.model.generate(
            chat_messages(request.messages, self._said),
            tools=list(self.tools.get(request.schema_name, ())),
            config=GenerateConfig(
                response_schema=response_schema(request.schema_name, request.schema)
            ),
        )
