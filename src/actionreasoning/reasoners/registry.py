"""The reasoning backends ``--llm`` names: one :class:`BackendKind` each in :data:`BACKENDS`.

A spec is a backend's name and, for all but ``builtin``, its argument: ``openai:MODEL``.
An entry says what the argument is, a few words for ``--help``, the package extra its client
needs (if any), how a run checks and settles it once
(:func:`~actionreasoning.reasoners.factory.prepare`) and how a trial gets its chat client.
Clients are imported only when a backend is prepared or built, so naming the backends
(``--help``, a classical run) loads no model client. Adding a backend is one entry.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.chat import StructuredMode
from actionreasoning.reasoners.sampling import Sampling

if TYPE_CHECKING:
    from actionreasoning.reasoners.backend import LLMConfig
    from actionreasoning.reasoners.chat import ChatBackend


@dataclass(frozen=True)
class Extra:
    """An optional dependency: the package extra that installs ``package``, which provides
    the module ``module``."""

    name: str
    package: str
    module: str


@dataclass(frozen=True)
class BackendKind:
    """One reasoning backend: its spec, help, extra, and how it is prepared and connected.

    ``prepare`` checks a run's configuration and settles what is fixed per run (mode,
    label, headers), asking a server no later than a deadline (``time.monotonic()``
    seconds; None: none); ``connect`` makes a trial's chat client from a prepared configuration
    and the trial's deadline (``time.monotonic()`` seconds); None for the built-in
    reasoner, which asks no model. ``server``: it talks to a server at ``--base-url``.
    """

    name: str
    argument: str | None  # what follows "name:" (MODEL, PATH, FILE); None: the name alone
    help: str  # for --help, after the spec; "" if the name says it
    prepare: Callable[[LLMConfig, float | None], LLMConfig]
    connect: Callable[[LLMConfig, float | None], ChatBackend] | None = None
    server: bool = False
    extra: Extra | None = None

    @property
    def asks_model(self) -> bool:
        """Whether it answers through a chat client (all but the built-in reasoner)."""
        return self.connect is not None

    @property
    def usage(self) -> str:
        """The spec as written on the command line: ``openai:MODEL``."""
        return self.name if self.argument is None else f"{self.name}:{self.argument}"

    def client(self, config: LLMConfig, deadline: float | None = None) -> ChatBackend:
        """A trial's chat client; a missing extra is refused with the command installing it."""
        if self.connect is None:
            raise ConfigError(f"--llm {config.spec} asks no model; it has no chat client")
        try:
            return self.connect(config, deadline)
        except ImportError as error:
            extra = self.extra
            if extra is None or (error.name or "").split(".")[0] != extra.module:
                raise
            raise ConfigError(
                f"--llm {self.usage} needs {extra.package}: "
                f"pip install 'actionreasoning[{extra.name}]'"
            ) from None


def _prepare_builtin(config: LLMConfig, deadline: float | None) -> LLMConfig:
    if config.server.base_url or config.record or config.fallback:
        raise ConfigError("--base-url, --record and --fallback need an --llm other than builtin")
    if config.sampling.changed():
        raise ConfigError(
            f"{', '.join(config.sampling.options())}: the built-in reasoner samples "
            "nothing; give an --llm other than builtin"
        )
    return config


def _prepare_openai(config: LLMConfig, deadline: float | None) -> LLMConfig:
    from actionreasoning.reasoners.openai_chat import OpenAIChat

    chat = OpenAIChat(config.argument, config.server, deadline=deadline, sampling=config.sampling)
    mode = chat.negotiate()
    return replace(config, mode=mode, label=chat.label, headers=chat.header_names)


def _connect_openai(config: LLMConfig, deadline: float | None) -> ChatBackend:
    from actionreasoning.reasoners.openai_chat import OpenAIChat

    mode = config.mode or StructuredMode.TEXT
    return OpenAIChat(config.argument, config.server, mode, deadline, config.sampling)


def _prepare_llamacpp(config: LLMConfig, deadline: float | None) -> LLMConfig:
    if config.sampling.reasoning_effort is not None:
        raise ConfigError(
            "--reasoning-effort is for --llm openai:MODEL: llama-cpp-python has no such setting"
        )
    return replace(config, mode=StructuredMode.JSON_OBJECT_SCHEMA, label=config.spec)


def _connect_llamacpp(config: LLMConfig, deadline: float | None) -> ChatBackend:
    from actionreasoning.reasoners.llamacpp_chat import LlamaCppChat

    return LlamaCppChat(config.argument, config.sampling)


def _prepare_replay(config: LLMConfig, deadline: float | None) -> LLMConfig:
    """The recording's mode, label and sampling settings."""
    from actionreasoning.reasoners.recording import ReplayChat

    if config.record:
        raise ConfigError("--record cannot record a replay")
    if not config.argument:
        raise ConfigError("--llm replay:FILE needs a --record file after 'replay:'")
    replay = ReplayChat(Path(config.argument))
    if config.sampling not in (Sampling(), replay.sampling):
        raise ConfigError(
            f"--llm {config.spec} serves answers sampled with {replay.sampling}: "
            f"drop {', '.join(config.sampling.options())}"
        )
    return replace(config, mode=replay.mode, label=replay.label, sampling=replay.sampling)


def _connect_replay(config: LLMConfig, deadline: float | None) -> ChatBackend:
    from actionreasoning.reasoners.recording import ReplayChat

    return ReplayChat(Path(config.argument))


BACKENDS: dict[str, BackendKind] = {
    kind.name: kind
    for kind in (
        BackendKind("builtin", None, "", _prepare_builtin),
        BackendKind(
            "openai",
            "MODEL",
            "any OpenAI-compatible server",
            _prepare_openai,
            _connect_openai,
            server=True,
        ),
        BackendKind(
            "llamacpp",
            "PATH",
            "a GGUF file, in process",
            _prepare_llamacpp,
            _connect_llamacpp,
            extra=Extra(name="local", package="llama-cpp-python", module="llama_cpp"),
        ),
        BackendKind("replay", "FILE", "a --record file, offline", _prepare_replay, _connect_replay),
    )
}


def backend_kind(spec: str) -> BackendKind:
    """The backend a ``--llm`` spec names; an unknown or malformed spec is refused."""
    name = spec.split(":", 1)[0]
    kind = BACKENDS.get(name)
    if kind is None or (kind.argument is None) != (spec == name):
        raise ConfigError(f"--llm {spec!r}: use {usage()}")
    return kind


def usage(model: bool = False) -> str:
    """The specs, "builtin, openai:MODEL, ... or replay:FILE"; ``model``: those asking a model."""
    return _either(k.usage for k in BACKENDS.values() if not model or k.asks_model)


def backend_help() -> str:
    """``--llm``'s help: every spec with its few words."""
    specs = (f"{k.usage} ({k.help})" if k.help else k.usage for k in BACKENDS.values())
    return f"Reasoning backend: {_either(specs)}."


def _either(items: Iterable[str]) -> str:
    """The items as "a, b or c"."""
    listed = list(items)
    return listed[0] if len(listed) == 1 else f"{', '.join(listed[:-1])} or {listed[-1]}"
