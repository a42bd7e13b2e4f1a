"""Record and replay: every exchange with a model server, stored to serve again offline.

A recording is JSON lines: a header ``{"kind": "header", "llm": ..., "mode": ...}`` and one
``{"kind": "exchange", "key": ..., "request": ..., "content": ..., "usage": ...}`` per
completion, where ``key`` is a hash of the request. Replay serves each key's answers in
the order they were recorded, with their recorded usage, so a replayed trial writes the
same results line as the recorded one; a request that is not in the file is an error.
"""

from __future__ import annotations

import hashlib
import json
from collections import defaultdict, deque
from pathlib import Path
from typing import Any

from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.chat import ChatBackend, ChatReply, ChatRequest, StructuredMode
from actionreasoning.records import LLMUsage


class ReplayMismatchError(ConfigError):
    """A replayed run asked for something the recording does not hold."""


def request_key(request: ChatRequest) -> str:
    """A stable hash of everything the model was sent."""
    data = {"messages": request.messages, "name": request.schema_name, "schema": request.schema}
    text = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


class RecordingChat:
    """Passes requests to a backend and appends every exchange to a recording file."""

    def __init__(self, backend: ChatBackend, path: Path, mode: StructuredMode) -> None:
        self.backend = backend
        self.label = backend.label
        self.path = path
        if path.exists() and path.stat().st_size > 0:
            header = read_header(path)
            if header["llm"] != backend.label:
                raise ConfigError(
                    f"--record {path} holds a recording of {header['llm']}, not {backend.label}"
                )
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._append({"kind": "header", "llm": backend.label, "mode": str(mode)})

    def complete(self, request: ChatRequest) -> ChatReply:
        """The backend's reply, recorded."""
        reply = self.backend.complete(request)
        self._append(
            {
                "kind": "exchange",
                "key": request_key(request),
                "request": {"messages": request.messages, "name": request.schema_name},
                "content": reply.content,
                "usage": reply.usage.model_dump(),
            }
        )
        return reply

    def _append(self, record: dict[str, Any]) -> None:
        with self.path.open("a", encoding="utf-8") as sink:
            sink.write(json.dumps(record) + "\n")


class ReplayChat:
    """Serves a recording's answers offline."""

    def __init__(self, path: Path) -> None:
        header = read_header(path)
        self.path = path
        self.label = str(header["llm"])
        self.mode = StructuredMode(header["mode"])
        self._answers: dict[str, deque[ChatReply]] = defaultdict(deque)
        for record in _records(path)[1:]:
            reply = ChatReply(content=record["content"], usage=LLMUsage(**record["usage"]))
            self._answers[record["key"]].append(reply)

    def complete(self, request: ChatRequest) -> ChatReply:
        """The recorded answer to this request; a request never recorded is an error."""
        key = request_key(request)
        answers = self._answers.get(key)
        if not answers:
            raise ReplayMismatchError(
                f"replay: the recording {self.path} has no (further) answer to this request of "
                f"agent {request.schema_name} (key {key[:12]}); was it recorded with the same "
                "pattern, seed and options?"
            )
        return answers.popleft()


def read_header(path: Path) -> dict[str, Any]:
    """The header of a recording; a file that is not one is a ConfigError."""
    records = _records(path, limit=1)
    if not records or records[0].get("kind") != "header" or "llm" not in records[0]:
        raise ConfigError(f"{path} is not a recording (no header line)")
    return records[0]


def _records(path: Path, limit: int | None = None) -> list[dict[str, Any]]:
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as error:
        raise ConfigError(f"cannot read recording {path}: {error.strerror}") from None
    records = []
    for number, line in enumerate(lines[:limit] if limit else lines, start=1):
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            raise ConfigError(f"{path}:{number}: not a JSON line") from None
        if not isinstance(record, dict):
            raise ConfigError(f"{path}:{number}: not a JSON object")
        records.append(record)
    return records
