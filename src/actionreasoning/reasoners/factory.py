"""From ``--llm SPEC`` and its options to a reasoner, through the backends of
:mod:`~actionreasoning.reasoners.registry`.

:func:`prepare` runs once per run (it checks the spec and the options, negotiates an
OpenAI-compatible server's structured-output mode and names its extra headers, and reads a
replay's header); :func:`make_reasoner` then builds each trial's reasoner from the prepared
configuration. A model client is imported only when its backend is prepared or built.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import ValidationError

from actionreasoning.agents.outputs import GraspAnswer
from actionreasoning.agents.reasoner import Reasoner
from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.reasoners.chat import ChatRequest, StructuredMode
from actionreasoning.reasoners.llm import LLMReasoner
from actionreasoning.reasoners.recording import RecordingChat
from actionreasoning.reasoners.registry import BACKENDS, backend_kind, usage

CHECK_PROMPT = (
    "You control a robot gripper that is at its grasp pose around a brick. Answer with a JSON "
    'object: {"close": true, "rationale": "<one short sentence>"}.'
)


def prepare(config: LLMConfig, deadline: float | None = None) -> LLMConfig:
    """Check the configuration and settle what is fixed per run (mode, label, headers, and a
    replay's sampling settings: the recording's), asking a server no later than
    ``deadline`` (``time.monotonic()`` seconds)."""
    kind = backend_kind(config.spec)
    if kind.asks_model and config.server.base_url and not kind.server:
        servers = " or ".join(k.usage for k in BACKENDS.values() if k.server)
        raise ConfigError(f"--base-url is for --llm {servers}")
    return kind.prepare(config, deadline)


@dataclass(frozen=True)
class CheckReport:
    """What one schema-constrained request to a backend gave."""

    label: str
    model: str
    mode: str
    latency_s: float
    prompt_tokens: int
    completion_tokens: int
    valid: bool
    detail: str


def check_backend(config: LLMConfig) -> CheckReport:
    """Connect, settle the structured-output mode, and send one schema-constrained request."""
    kind = backend_kind(config.spec)
    if not kind.asks_model:
        raise ConfigError(f"--llm {config.spec} needs no server; give {usage(model=True)}")
    prepared = prepare(config)
    backend = kind.client(prepared)
    schema = GraspAnswer.model_json_schema()
    reply = backend.complete(
        ChatRequest(
            messages=({"role": "user", "content": CHECK_PROMPT},),
            schema_name="grasp",
            schema=schema,
        )
    )
    try:
        GraspAnswer.model_validate_json(reply.content)
        valid, detail = True, reply.content
    except ValidationError as error:
        valid, detail = False, f"{error.error_count()} schema errors in {reply.content!r}"
    return CheckReport(
        label=prepared.label,
        model=reply.model,
        mode=str(prepared.mode),
        latency_s=reply.usage.latency_s,
        prompt_tokens=reply.usage.prompt_tokens,
        completion_tokens=reply.usage.completion_tokens,
        valid=valid,
        detail=detail[:300],
    )


def make_reasoner(config: LLMConfig, deadline: float | None = None) -> Reasoner:
    """A fresh reasoner for one trial, from a prepared configuration; a server's answers
    are given up at ``deadline`` (``time.monotonic()`` seconds), the trial's end."""
    builtin = BuiltinReasoner()
    kind = backend_kind(config.spec)
    if not kind.asks_model:
        return builtin
    backend = kind.client(config, deadline)
    if config.record is not None:
        mode = config.mode or StructuredMode.TEXT
        backend = RecordingChat(backend, config.record, mode, config.sampling)
    return LLMReasoner(backend, config.limits, fallback=builtin if config.fallback else None)
