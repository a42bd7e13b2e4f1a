"""An OpenAI-compatible chat server (OpenAI, vLLM, Ollama, llama.cpp's server, LM Studio).

Uses the official ``openai`` client for each request. Every request has a total deadline,
connect, wait and read together (:mod:`~actionreasoning.reasoners.deadline`): ``timeout_s``
per try, and never past the trial's deadline when one is given. Connection errors, timeouts,
408, 409, 429 and 5xx are retried here, not by the client, with exponential backoff or the
server's Retry-After, so no wait outlasts the trial either.

The base URL comes from ``--base-url`` or ``OPENAI_BASE_URL``, the key from ``OPENAI_API_KEY``
and extra headers from ``ACTIONREASONING_LLM_HEADERS``; the key and the header values are
given to the client only and never stored, logged or written anywhere. Whatever the server
sends back (answers, model names, error messages) has the key, the header values and the base
URL's credentials cut out before anything else sees it, in case a server echoes them, and the
base URL is shown with its user info and query values hidden
(:mod:`~actionreasoning.reasoners.credentials`).

Sampling (:class:`~actionreasoning.reasoners.sampling.Sampling`): temperature, seed and the
token cap go with every request, ``top_p`` and ``reasoning_effort`` when set. With a reasoning
effort the cap is sent as ``max_completion_tokens``, the field OpenAI's reasoning models take
in place of ``max_tokens`` (it counts their reasoning as well).

Structured output: the strictest ``response_format`` the server accepts is chosen once per
run by :meth:`OpenAIChat.negotiate`. A server refuses a format with 400 or 422, or, as
llama-cpp-python's does, with a 500 whose message names ``response_format``.
"""

from __future__ import annotations

import math
import os
import random
import time
import weakref
from typing import Any
from urllib.parse import parse_qsl, urlsplit

import openai
from openai.types.chat import ChatCompletion

from actionreasoning.errors import ConfigError, LLMError
from actionreasoning.reasoners.backend import ServerOptions
from actionreasoning.reasoners.chat import (
    ChatReply,
    ChatRequest,
    StructuredMode,
    response_format,
)
from actionreasoning.reasoners.credentials import (
    Redactor,
    check_base_url,
    extra_headers,
    shown_url,
)
from actionreasoning.reasoners.deadline import Watchdog
from actionreasoning.reasoners.sampling import Sampling
from actionreasoning.records import FailureCode, LLMUsage

_PROBE_SCHEMA = {
    "type": "object",
    "properties": {"ok": {"type": "boolean"}},
    "required": ["ok"],
    "additionalProperties": False,
}
#: HTTP statuses worth another try (besides 5xx): timeout, conflict, rate limit.
_RETRIED_STATUS = (408, 409, 429)
#: Backoff before retry n (from 0): FIRST_BACKOFF_S * 2**n, at most MAX_BACKOFF_S, less up to
#: a quarter at random; a server's Retry-After of up to MAX_RETRY_AFTER_S is taken instead.
FIRST_BACKOFF_S = 0.5
MAX_BACKOFF_S = 8.0
MAX_RETRY_AFTER_S = 60.0


#: What an HTTP status most likely means of a chat completion request.
_LIKELY_CAUSE = {
    404: ": no such endpoint or model (check --base-url, which ends in /v1, and the model name)",
    431: ": the request's headers are too large (check ACTIONREASONING_LLM_HEADERS)",
}


class _FormatRefused(Exception):
    """The server refused the request itself (400, 422, or an error naming response_format)."""


class OpenAIChat:
    """Chat completions from an OpenAI-compatible server, each given up at ``deadline``
    (``time.monotonic()`` seconds) if one is set."""

    def __init__(
        self,
        model: str,
        options: ServerOptions = ServerOptions(),
        mode: StructuredMode = StructuredMode.JSON_SCHEMA,
        deadline: float | None = None,
        sampling: Sampling = Sampling(),
    ) -> None:
        if not model:
            raise ConfigError("--llm openai:MODEL needs a model name after 'openai:'")
        self.model = model
        self.label = f"openai:{model}"
        self.mode = mode
        self.options = options
        self.sampling = sampling
        self.deadline = math.inf if deadline is None else deadline
        base_url = options.base_url
        if base_url is None and "OPENAI_BASE_URL" in os.environ:
            base_url = os.environ["OPENAI_BASE_URL"]
            check_base_url(base_url, "OPENAI_BASE_URL")
        key = os.environ.get("OPENAI_API_KEY")
        headers = extra_headers()
        self.header_names = tuple(sorted(headers))
        self.redact = Redactor.of(base_url, key, headers.values())
        self._watchdog = Watchdog()
        http_client = openai.DefaultHttpxClient(event_hooks={"request": [self._watchdog.hook]})
        weakref.finalize(self, http_client.close)
        url = urlsplit(base_url or "")
        self.client = openai.OpenAI(
            # The query goes with every request, not into the path the client appends to.
            base_url=url._replace(query="").geturl() if base_url else None,
            default_query=dict(parse_qsl(url.query, keep_blank_values=True)),
            # A local server takes any key; the client insists on one.
            api_key=key or "no-key",
            default_headers=headers,
            max_retries=0,  # retried by _create, within the deadlines
            http_client=http_client,
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
                self.sampling.max_tokens,
            )
        except _FormatRefused as refused:
            raise LLMError(
                FailureCode.LLM_BAD_REQUEST, f"{self.where} refused the request: {refused}"
            ) from None
        latency = time.perf_counter() - started
        if not completion.choices:
            raise LLMError(FailureCode.LLM_BAD_RESPONSE, f"{self.where} answered with no choices")
        content = self.redact(completion.choices[0].message.content or "")
        usage = completion.usage
        if usage and min(usage.prompt_tokens, usage.completion_tokens) < 0:
            raise LLMError(
                FailureCode.LLM_BAD_RESPONSE,
                f"{self.where} counted a negative number of tokens (prompt "
                f"{usage.prompt_tokens}, completion {usage.completion_tokens})",
            )
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
        """The raw completion, with retries; a refused request raises _FormatRefused, any
        other failure an LLMError."""
        fields = sampling_fields(self.sampling, max_tokens)
        if fmt:
            fields["response_format"] = fmt
        retries = 0
        while True:
            seconds = min(self.options.timeout_s, self.deadline - time.monotonic())
            if seconds <= 0:
                raise self._out_of_time()
            try:
                with self._watchdog.limit(seconds):
                    completion = self.client.chat.completions.create(
                        model=self.model,
                        messages=messages,
                        timeout=seconds,
                        **fields,
                    )
            except (openai.APIConnectionError, openai.APIStatusError) as error:
                failure = self._failure(error, retries)
                wait = self._retry_wait(error, retries)
                if isinstance(failure, _FormatRefused) or wait is None:
                    raise failure from None
                time.sleep(wait)
                retries += 1
                continue
            except (openai.APIError, ValueError) as error:  # a body that is not JSON, ...
                raise LLMError(
                    FailureCode.LLM_BAD_RESPONSE,
                    self.redact(f"{self.where} sent an unreadable answer ({error})")[:300],
                ) from None
            if not isinstance(completion, ChatCompletion):
                raise LLMError(
                    FailureCode.LLM_BAD_RESPONSE, f"{self.where} did not send a chat completion"
                )
            return completion

    def _failure(
        self, error: openai.APIConnectionError | openai.APIStatusError, retries: int
    ) -> LLMError | _FormatRefused:
        """What a failed try means, after ``retries`` retries."""
        if time.monotonic() >= self.deadline:
            return self._out_of_time()
        if isinstance(error, openai.APITimeoutError) or self._watchdog.expired:
            return LLMError(
                FailureCode.LLM_TIMEOUT,
                f"{self.where} did not answer within {self.options.timeout_s:g} s "
                f"({retries} retries)",
            )
        if isinstance(error, openai.APIConnectionError):
            return LLMError(
                FailureCode.LLM_UNREACHABLE, f"cannot connect to {self.where} ({retries} retries)"
            )
        status = error.status_code
        if status in (400, 422) or "response_format" in str(error.message):
            return _FormatRefused(f"HTTP {status} {self.redact(str(error.message))[:200]}")
        if status == 429:
            return LLMError(
                FailureCode.LLM_RATE_LIMITED, f"{self.where} kept answering 429 ({retries} retries)"
            )
        # A 4xx is the server refusing the request (404: a wrong URL or model), not failing.
        code = FailureCode.LLM_SERVER_ERROR if status >= 500 else FailureCode.LLM_BAD_REQUEST
        return LLMError(
            code,
            f"{self.where} answered HTTP {status}{_LIKELY_CAUSE.get(status, '')} "
            f"({retries} retries)",
        )

    def _retry_wait(
        self, error: openai.APIConnectionError | openai.APIStatusError, retries: int
    ) -> float | None:
        """Seconds to wait before the next try, or None if there is none: retries spent, a
        status not worth another try, or a wait that would outlast the deadline."""
        if retries >= self.options.max_retries:
            return None
        wait = min(FIRST_BACKOFF_S * 2**retries, MAX_BACKOFF_S) * (1 - 0.25 * random.random())
        if isinstance(error, openai.APIStatusError):
            if error.status_code not in _RETRIED_STATUS and error.status_code < 500:
                return None
            wait = _retry_after(error.response.headers.get("retry-after", ""), wait)
        return wait if time.monotonic() + wait < self.deadline else None

    def _out_of_time(self) -> LLMError:
        return LLMError(
            FailureCode.TIME_BUDGET, f"the trial's wall time ran out while waiting for {self.where}"
        )

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
        raise LLMError(
            FailureCode.LLM_BAD_REQUEST, f"{self.where} refused every request: {refusals}"
        )


def sampling_fields(sampling: Sampling, max_tokens: int) -> dict[str, Any]:
    """The request fields of ``sampling``, with ``max_tokens`` as the token cap."""
    cap = "max_completion_tokens" if sampling.reasoning_effort else "max_tokens"
    fields: dict[str, Any] = {"temperature": sampling.temperature, "seed": sampling.seed}
    fields[cap] = max_tokens
    if sampling.top_p is not None:
        fields["top_p"] = sampling.top_p
    if sampling.reasoning_effort is not None:
        fields["reasoning_effort"] = str(sampling.reasoning_effort)
    return fields


def _retry_after(header: str, default: float) -> float:
    """A server's Retry-After in seconds, if it gives one from 0 to MAX_RETRY_AFTER_S."""
    try:
        seconds = float(header)
    except ValueError:
        return default
    return seconds if 0 <= seconds <= MAX_RETRY_AFTER_S else default
