"""Which reasoning backend a run asks and how: the ``--llm`` spec and its options.

Plain values, apart from the clients that use them (``factory.py``, ``openai_chat.py``), so a
run's configuration names its backend without loading a model client.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from actionreasoning.reasoners.chat import StructuredMode
from actionreasoning.reasoners.credentials import check_base_url
from actionreasoning.reasoners.llm import LLMLimits
from actionreasoning.reasoners.sampling import Sampling


@dataclass(frozen=True)
class ServerOptions:
    """Where the server is and how patiently to ask it: ``timeout_s`` for each try, all of
    it. An empty or malformed base URL is refused here."""

    base_url: str | None = None
    timeout_s: float = 60.0
    max_retries: int = 2

    def __post_init__(self) -> None:
        if self.base_url is not None:
            check_base_url(self.base_url, "--base-url")


@dataclass(frozen=True)
class LLMConfig:
    """The reasoning backend of a run and its options. ``headers`` names the extra headers
    sent to an OpenAI-compatible server (their values stay in the environment)."""

    spec: str = "builtin"
    server: ServerOptions = ServerOptions()
    limits: LLMLimits = LLMLimits()
    fallback: bool = False
    record: Path | None = None
    sampling: Sampling = Sampling()  # a replay's: the recording's, set by prepare()
    headers: tuple[str, ...] = ()  # set by prepare() for servers
    mode: StructuredMode | None = None  # set by prepare() for servers
    label: str = "builtin"  # what results.jsonl calls the backend (a replay: the recorded one)

    @property
    def kind(self) -> str:
        """The backend's name, a key of :data:`~actionreasoning.reasoners.registry.BACKENDS`."""
        return self.spec.split(":", 1)[0]

    @property
    def argument(self) -> str:
        """What follows the kind: a model name or a path."""
        return self.spec.split(":", 1)[1] if ":" in self.spec else ""
