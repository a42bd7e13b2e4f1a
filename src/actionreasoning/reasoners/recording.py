"""Record and replay: every exchange with a model server, stored to serve again offline.

A recording is JSON lines: a header ``{"kind": "header", "llm": ..., "mode": ...}`` (with
``"sampling": {...}``, the settings that differ from the defaults, if any) and one
``{"kind": "exchange", "key": ..., "request": ..., "content": ..., "usage": ...}`` per
completion, where ``key`` is a hash of the request. A picture a request carried (an image
part's ``data:`` URL) is stored once, as ``{"kind": "image", "sha256": ..., "url": ...}``
before the first exchange that sent it, and the exchanges' requests name it
``sha256:HASH``, the hash of its bytes (as transcripts do). Replay serves each key's answers in
the order they were recorded, with their recorded usage, so a replayed trial writes the
same results line as the recorded one, however the answers were sampled; a request that is
not in the file is an error.
"""

from __future__ import annotations

import hashlib
import json
from collections import defaultdict, deque
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

from pydantic import BaseModel, Field, TypeAdapter, ValidationError

from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.chat import (
    ChatBackend,
    ChatReply,
    ChatRequest,
    Message,
    StructuredMode,
)
from actionreasoning.reasoners.sampling import RecordedSampling, Sampling
from actionreasoning.records import LLMUsage
from actionreasoning.world.config_files import read_user_file
from actionreasoning.world.pictures import png_of


class ReplayMismatchError(ConfigError):
    """A replayed run asked for something the recording does not hold."""


class Header(BaseModel):
    """The first line of a recording: which backend, in which structured-output mode, with
    which sampling settings."""

    kind: Literal["header"]
    llm: str
    mode: StructuredMode
    sampling: RecordedSampling = Sampling()


class Exchange(BaseModel):
    """One recorded completion: the request's hash, the request, the answer, its usage."""

    kind: Literal["exchange"]
    key: str
    request: dict[str, Any]
    content: str
    usage: LLMUsage


class StoredImage(BaseModel):
    """A picture recorded requests carried, stored once: the hash of its bytes, its URL."""

    kind: Literal["image"]
    sha256: str
    url: str


Record = TypeVar("Record", Header, Exchange)
_Line = TypeAdapter(Annotated[Exchange | StoredImage, Field(discriminator="kind")])


def request_key(request: ChatRequest) -> str:
    """A stable hash of everything the model was sent."""
    data = {"messages": request.messages, "name": request.schema_name, "schema": request.schema}
    text = json.dumps(data, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


class RecordingChat:
    """Passes requests to a backend and appends every exchange to a recording file."""

    def __init__(
        self,
        backend: ChatBackend,
        path: Path,
        mode: StructuredMode,
        sampling: Sampling = Sampling(),
    ) -> None:
        self.backend = backend
        self.label = backend.label
        self.path = path
        if path.exists() and path.stat().st_size > 0:
            header = read_header(path)
            if header.llm != backend.label:
                raise ConfigError(
                    f"--record {path} holds a recording of {header.llm}, not {backend.label}"
                )
            if header.sampling != sampling:
                raise ConfigError(
                    f"--record {path} holds answers sampled with {header.sampling}, not "
                    f"{sampling}: record into another file"
                )
            self._stored = {image.sha256 for image in _read(path)[2]}
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._append(Header(kind="header", llm=backend.label, mode=mode, sampling=sampling))
            self._stored = set()

    def complete(self, request: ChatRequest) -> ChatReply:
        """The backend's reply, recorded."""
        reply = self.backend.complete(request)
        messages = [self._by_reference(message) for message in request.messages]
        self._append(
            Exchange(
                kind="exchange",
                key=request_key(request),
                request={"messages": messages, "name": request.schema_name},
                content=reply.content,
                usage=reply.usage,
            )
        )
        return reply

    def _by_reference(self, message: Message) -> Message:
        """``message`` with each image part's URL replaced by ``sha256:HASH``, the picture
        stored first if this recording does not hold it yet."""
        content = message.get("content")
        if not isinstance(content, list):
            return message
        parts = []
        for part in content:
            if part.get("type") == "image_url":
                url = part["image_url"]["url"]
                digest = image_hash(url)
                if digest not in self._stored:
                    self._append(StoredImage(kind="image", sha256=digest, url=url))
                    self._stored.add(digest)
                part = {"type": "image_url", "image_url": {"url": f"sha256:{digest}"}}
            parts.append(part)
        return {**message, "content": parts}

    def _append(self, record: Header | Exchange | StoredImage) -> None:
        with self.path.open("a", encoding="utf-8") as sink:
            sink.write(record.model_dump_json() + "\n")


class ReplayChat:
    """Serves a recording's answers offline."""

    def __init__(self, path: Path) -> None:
        header, exchanges, _ = _read(path)
        self.path = path
        self.label = header.llm
        self.mode = header.mode
        self.sampling = header.sampling
        self._answers: dict[str, deque[ChatReply]] = defaultdict(deque)
        for exchange in exchanges:
            reply = ChatReply(content=exchange.content, usage=exchange.usage)
            self._answers[exchange.key].append(reply)

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


def image_hash(url: str) -> str:
    """The SHA-256 of the picture behind an image URL: of its PNG's bytes for a PNG
    ``data:`` URL (as transcripts hash pictures), else of the URL's text."""
    return hashlib.sha256(png_of(url) or url.encode()).hexdigest()


def read_header(path: Path) -> Header:
    """The header of a recording; a file that is not one is a ConfigError."""
    return _read(path, header_only=True)[0]


def _read(
    path: Path, header_only: bool = False
) -> tuple[Header, list[Exchange], list[StoredImage]]:
    """A recording's header, exchanges and stored pictures; any line that is none of them
    is a ConfigError."""
    lines = read_user_file(path, "recording", limit=None).splitlines()
    if not lines:
        raise ConfigError(f"{path} is not a recording (no header line)")
    header = _parse(Header, path, lines[0], 1)
    if header_only:
        return header, [], []
    records = [_parse_line(path, line, n) for n, line in enumerate(lines[1:], start=2)]
    exchanges = [record for record in records if isinstance(record, Exchange)]
    images = [record for record in records if isinstance(record, StoredImage)]
    return header, exchanges, images


def _parse(model: type[Record], path: Path, line: bytes, number: int) -> Record:
    try:
        return model.model_validate_json(line)
    except ValidationError as error:
        raise _not_a(model.__name__.lower(), path, number, error) from None


def _parse_line(path: Path, line: bytes, number: int) -> Exchange | StoredImage:
    try:
        return _Line.validate_json(line)
    except ValidationError as error:
        raise _not_a("exchange or image", path, number, error) from None


def _not_a(what: str, path: Path, number: int, error: ValidationError) -> ConfigError:
    first = error.errors()[0]
    where = ".".join(str(part) for part in first["loc"])
    return ConfigError(
        f"{path} line {number} is not a recording {what} "
        f"({where + ': ' if where else ''}{first['msg']})"
    )
