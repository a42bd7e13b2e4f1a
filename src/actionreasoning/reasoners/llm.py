"""An LLM as the reasoner: the agent's prompt out, tool turns, validation and repair.

Per agent request: the rendered prompt goes to the model with the agent's output schema.
An answer that lists ``tool_calls`` gets the tools run (whitelisted, on the measured world)
and their results back, for a bounded number of turns. Every answer is parsed and
validated as data (``agents/validation.py``); a refused one goes back with a short error
for a bounded number of repairs. After that the step fails with ``invalid_output``, or,
with a fallback, the built-in reasoner answers and the reply says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pydantic import NonNegativeInt

from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.outputs import AgentAnswer
from actionreasoning.agents.prompt import compact_json
from actionreasoning.agents.reasoner import AgentReply, AgentRequest, Reasoner
from actionreasoning.agents.validation import OutputError, parse_answer
from actionreasoning.errors import LLMError, ToolError
from actionreasoning.reasoners.chat import (
    ChatBackend,
    ChatRequest,
    Message,
    message_text,
    user_message,
)
from actionreasoning.records import FailureCode, LLMUsage

#: How a tool turn's results and its last turn are announced to the model.
TOOL_RESULTS = "Tool results: "
NO_MORE_TOOLS = "No more tool calls now"


@dataclass(frozen=True)
class LLMLimits:
    """Turn budgets of one agent request."""

    tool_turns: NonNegativeInt = 2
    repairs: NonNegativeInt = 2


class LLMReasoner:
    """Answers agents with a language model behind a :class:`ChatBackend`."""

    def __init__(
        self,
        backend: ChatBackend,
        limits: LLMLimits = LLMLimits(),
        fallback: Reasoner | None = None,
    ) -> None:
        self.backend = backend
        self.name = backend.label
        self.limits = limits
        self.fallback = fallback

    def decide(self, request: AgentRequest) -> AgentReply:
        """Ask the model until it gives a valid answer, within the turn budgets."""
        schema = request.spec.output_model.model_json_schema()
        messages: list[Message] = [user_message(request.prompt, request.pictures)]
        # Every completion is sent the whole conversation, the prompt's pictures included.
        pictures = LLMUsage(image_bytes=sum(len(picture.png) for picture in request.pictures))
        usage, tool_turns, sent = LLMUsage(), 0, 0
        repairs: list[str] = []
        categories: list[ErrorCategory] = []
        while True:
            sent += sum(len(message_text(message)) for message in messages)
            try:
                reply = self.backend.complete(
                    ChatRequest(
                        messages=tuple(messages), schema_name=request.spec.key, schema=schema
                    )
                )
            except LLMError as error:  # keep what this step cost and why it was repaired
                raise LLMError(
                    error.reason,
                    error.detail,
                    tuple(repairs),
                    usage + error.usage,
                    tuple(categories),
                ) from None
            usage += reply.usage + pictures
            messages.append({"role": "assistant", "content": reply.content})
            try:
                answer = parse_answer(reply.content, request.spec, request.state)
            except OutputError as error:
                repairs.append(str(error))
                categories.append(error.category)
                if len(repairs) > self.limits.repairs:
                    return self._give_up(request, usage, tuple(repairs), tuple(categories), sent)
                messages.append({"role": "user", "content": _repair_prompt(str(error))})
                continue
            if answer.tool_calls and tool_turns < self.limits.tool_turns:
                tool_turns += 1
                last = tool_turns == self.limits.tool_turns
                messages.append({"role": "user", "content": _tool_results(request, answer, last)})
                continue
            return AgentReply(
                answer=answer,
                usage=usage,
                repairs=tuple(repairs),
                repair_categories=tuple(categories),
                tool_turns=tool_turns,
                prompt_chars=sent,
            )

    def _give_up(
        self,
        request: AgentRequest,
        usage: LLMUsage,
        repairs: tuple[str, ...],
        categories: tuple[ErrorCategory, ...],
        sent: int,
    ) -> AgentReply:
        if self.fallback is None:
            raise LLMError(
                FailureCode.INVALID_OUTPUT,
                f"{len(repairs)} answers refused; last: {repairs[-1]}",
                repairs=repairs,
                usage=usage,
                repair_categories=categories,
            )
        reply = self.fallback.decide(request)
        return AgentReply(
            answer=reply.answer,
            usage=usage,
            repairs=repairs,
            repair_categories=categories,
            fallback=True,
            prompt_chars=sent,
        )


def _repair_prompt(error: str) -> str:
    return (
        f"Your answer was refused: {error}. Answer again with one JSON object that matches "
        "the output schema, and nothing else."
    )


def _tool_results(request: AgentRequest, answer: AgentAnswer, last: bool) -> str:
    """Run the answer's tool calls and describe their results (or errors) as JSON."""
    results: list[dict[str, Any]] = []
    for call in answer.tool_calls:
        try:
            result = request.call_tool(call.name, call.arguments)
            results.append({"tool": call.name, "result": result.model_dump(mode="json")})
        except ToolError as error:
            results.append({"tool": call.name, "error": str(error)})
    then = (
        f"{NO_MORE_TOOLS}: answer with your decision and an empty tool_calls."
        if last
        else "Call more tools, or answer with your decision and an empty tool_calls."
    )
    return f"{TOOL_RESULTS}{compact_json(results)}\n{then}"
