"""An OpenAI-compatible chat server (OpenAI, vLLM, Ollama, llama.cpp's server, LM Studio).

Uses the official ``openai`` client with its own retries (connection errors, 408, 409, 429
and 5xx, with exponential backoff and Retry-After) and a per-request timeout. The base URL
comes from ``--base-url`` or ``OPENAI_BASE_URL``, the key from ``OPENAI_API_KEY``; the key is
given to the client only and never stored, logged or written anywhere. Whatever the server
sends back (answers, model names, error messages) has the key and the base URL's credentials
cut out before anything else sees it, in case a server echoes them, and the base URL is
shown with its user info and query values hidden
(:mod:`~actionreasoning.reasoners.credentials`).

Structured output: the strictest ``response_format`` the server accepts is chosen once per
run by :meth:`OpenAIChat.negotiate`. A server refuses a format with 400 or 422, or, as
llama-cpp-python's does, with a 500 whose message names ``response_format``.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qsl, urlsplit

import openai
from openai.types.chat import ChatCompletion

from actionreasoning.errors import ConfigError, LLMError
from actionreasoning.reasoners.chat import (
    ChatReply,
    ChatRequest,
    StructuredMode,
    response_format,
)
from actionreasoning.reasoners.credentials import Redactor, check_base_url, shown_url
from actionreasoning.records import LLMUsage

#: Answers are a waypoint and a sentence or two; a runaway generation is cut here.
MAX_COMPLETION_TOKENS = 300
_PROBE_SCHEMA = {
    "type": "object",
    "properties": {"ok": {"type": "boolean"}},
    "required": ["ok"],
    "additionalProperties": False,
}


class _FormatRefused(Exception):
    """The server refused the request itself (400, 422, or an error naming response_format)."""


@dataclass(frozen=True)
class ServerOptions:
    """Where the server is and how patiently to ask it. An empty or malformed base URL is
    refused here."""

    base_url: str | None = None
    timeout_s: float = 60.0
    max_retries: int = 2

    def __post_init__(self) -> None:
        if self.base_url is not None:
            check_base_url(self.base_url, "--base-url")


class OpenAIChat:
    """Chat completions from an OpenAI-compatible server."""

    def __init__(
        self,
        model: str,
        options: ServerOptions = ServerOptions(),
        mode: StructuredMode = StructuredMode.JSON_SCHEMA,
    ) -> None:
        if not model:
            raise ConfigError("--llm openai:MODEL needs a model name after 'openai:'")
        self.model = model
        self.label = f"openai:{model}"
        self.mode = mode
        base_url = options.base_url
        if base_url is None and "OPENAI_BASE_URL" in os.environ:
            base_url = os.environ["OPENAI_BASE_URL"]
            check_base_url(base_url, "OPENAI_BASE_URL")
        key = os.environ.get("OPENAI_API_KEY")
        self.redact = Redactor.of(base_url, key)
        url = urlsplit(base_url or "")
        self.client = openai.OpenAI(
            # The query goes with every request, not into the path the client appends to.
            base_url=url._replace(query="").geturl() if base_url else None,
            default_query=dict(parse_qsl(url.query, keep_blank_values=True)),
            # A local server takes any key; the client insists on one.
            api_key=key or "no-key",
            timeout=options.timeout_s,
            max_retries=options.max_retries,
        )
        query = f"?{url.query}" if url.query else ""
        self.where = shown_url(f"{self.client.base_url}{query}")

    def complete(self, request: ChatRequest) -> ChatReply:
        """One completion in this backend's structured-output mode."""
        started = time.perf_counter()
        try:
            completion = self._create(
                list(request.messages),
                response_format(self.mode, request.schema_name, request.schema),
                MAX_COMPLETION_TOKENS,
            )
        except _FormatRefused as refused:
            raise LLMError(
                "llm_bad_request", f"{self.where} refused the request: {refused}"
            ) from None
        latency = time.perf_counter() - started
        if not completion.choices:
            raise LLMError("llm_bad_response", f"{self.where} answered with no choices")
        content = self.redact(completion.choices[0].message.content or "")
        usage = completion.usage
        return ChatReply(
            model=self.redact(completion.model or self.model),
            content=content,
            usage=LLMUsage(
                calls=1,
                prompt_tokens=usage.prompt_tokens if usage else 0,
                completion_tokens=usage.completion_tokens if usage else 0,
                latency_s=latency,
            ),
        )

    def _create(self, messages: list[Any], fmt: dict[str, Any], max_tokens: int) -> ChatCompletion:
        """The raw completion; a refused request raises _FormatRefused, any other failure
        an LLMError."""
        extra = {"response_format": fmt} if fmt else {}
        try:
            completion = self.client.chat.completions.create(
                model=self.model,
                messages=messages,
                temperature=0.0,
                seed=0,
                max_tokens=max_tokens,
                **extra,
            )
        except openai.APITimeoutError:
            raise LLMError(
                "llm_timeout",
                f"{self.where} did not answer within {self.client.timeout} s "
                f"({self.client.max_retries} retries)",
            ) from None
        except openai.APIConnectionError:
            raise LLMError(
                "llm_unreachable",
                f"cannot connect to {self.where} ({self.client.max_retries} retries)",
            ) from None
        except openai.RateLimitError:
            raise LLMError(
                "llm_rate_limited",
                f"{self.where} kept answering 429 ({self.client.max_retries} retries)",
            ) from None
        except openai.APIStatusError as error:
            if error.status_code in (400, 422) or "response_format" in str(error.message):
                raise _FormatRefused(
                    f"HTTP {error.status_code} {self.redact(str(error.message))[:200]}"
                ) from None
            raise LLMError(
                "llm_server_error",
                f"{self.where} answered HTTP {error.status_code} "
                f"({self.client.max_retries} retries)",
            ) from None
        except (openai.APIError, ValueError) as error:  # a body that is not JSON, ...
            raise LLMError(
                "llm_bad_response",
                self.redact(f"{self.where} sent an unreadable answer ({error})")[:300],
            ) from None
        if not isinstance(completion, ChatCompletion):
            raise LLMError("llm_bad_response", f"{self.where} did not send a chat completion")
        return completion

    def negotiate(self) -> StructuredMode:
        """Set and return the strictest structured-output mode the server accepts."""
        messages = [{"role": "user", "content": 'Answer with the JSON object {"ok": true}.'}]
        refusals = []
        for mode in StructuredMode:
            try:
                self._create(messages, response_format(mode, "probe", _PROBE_SCHEMA), 20)
            except _FormatRefused as refused:
                refusals.append(f"{mode}: {refused}")
                continue
            self.mode = mode
            return mode
        raise LLMError("llm_bad_request", f"{self.where} refused every request: {refusals}")
