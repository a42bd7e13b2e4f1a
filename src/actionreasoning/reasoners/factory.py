"""From ``--llm SPEC`` and its options to a reasoner: builtin, openai, llamacpp or replay.

:func:`prepare` runs once per run (it checks the spec and the options, negotiates an
OpenAI-compatible server's structured-output mode and names its extra headers, and reads a
replay's header); :func:`make_reasoner` then builds each trial's reasoner from the prepared
configuration.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from pydantic import ValidationError

from actionreasoning.agents.outputs import GraspAnswer
from actionreasoning.agents.reasoner import Reasoner
from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.reasoners.chat import ChatBackend, ChatRequest, StructuredMode
from actionreasoning.reasoners.llamacpp_chat import LlamaCppChat
from actionreasoning.reasoners.llm import LLMReasoner
from actionreasoning.reasoners.openai_chat import OpenAIChat
from actionreasoning.reasoners.recording import RecordingChat, ReplayChat
from actionreasoning.reasoners.sampling import Sampling

KINDS = ("builtin", "openai", "llamacpp", "replay")
CHECK_PROMPT = (
    "You control a robot gripper that is at its grasp pose around a brick. Answer with a JSON "
    'object: {"close": true, "rationale": "<one short sentence>"}.'
)


def prepare(config: LLMConfig) -> LLMConfig:
    """Check the configuration and settle what is fixed per run (mode, label, headers, and a
    replay's sampling settings: the recording's)."""
    if config.kind not in KINDS or (config.kind == "builtin") != (config.spec == "builtin"):
        raise ConfigError(
            f"--llm {config.spec!r}: use builtin, openai:MODEL, llamacpp:PATH or replay:FILE"
        )
    if config.kind == "builtin":
        if config.server.base_url or config.record or config.fallback:
            raise ConfigError(
                "--base-url, --record and --fallback need an --llm other than builtin"
            )
        if config.sampling.changed():
            raise ConfigError(
                f"{', '.join(config.sampling.options())}: the built-in reasoner samples "
                "nothing; give an --llm other than builtin"
            )
        return config
    if config.server.base_url and config.kind != "openai":
        raise ConfigError("--base-url is for --llm openai:MODEL")
    if config.kind == "replay":
        if config.record:
            raise ConfigError("--record cannot record a replay")
        replay = ReplayChat(Path(config.argument))
        if config.sampling not in (Sampling(), replay.sampling):
            raise ConfigError(
                f"--llm {config.spec} serves answers sampled with {replay.sampling}: "
                f"drop {', '.join(config.sampling.options())}"
            )
        return replace(config, mode=replay.mode, label=replay.label, sampling=replay.sampling)
    if config.kind == "openai":
        chat = OpenAIChat(config.argument, config.server, sampling=config.sampling)
        mode = chat.negotiate()
        return replace(config, mode=mode, label=chat.label, headers=chat.header_names)
    if config.sampling.reasoning_effort is not None:
        raise ConfigError(
            "--reasoning-effort is for --llm openai:MODEL: llama-cpp-python has no such setting"
        )
    return replace(config, mode=StructuredMode.JSON_OBJECT_SCHEMA, label=config.spec)


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
    if config.kind == "builtin":
        raise ConfigError("--llm builtin needs no server; give openai:MODEL, llamacpp:PATH or ...")
    prepared = prepare(config)
    backend = _backend(prepared)
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
    if config.kind == "builtin":
        return builtin
    backend = _backend(config, deadline)
    if config.record is not None:
        mode = config.mode or StructuredMode.TEXT
        backend = RecordingChat(backend, config.record, mode, config.sampling)
    return LLMReasoner(backend, config.limits, fallback=builtin if config.fallback else None)


def _backend(config: LLMConfig, deadline: float | None = None) -> ChatBackend:
    if config.kind == "replay":
        return ReplayChat(Path(config.argument))
    if config.kind == "openai":
        mode = config.mode or StructuredMode.TEXT
        return OpenAIChat(config.argument, config.server, mode, deadline, config.sampling)
    return LlamaCppChat(config.argument, config.sampling)
