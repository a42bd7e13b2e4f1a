"""The server's stdin: JSON-RPC lines read in bounded memory, each checked before the SDK
sees it, so every request gets an answer.

The SDK drops a line it cannot parse or validate without a reply, which leaves a client
waiting forever for its request's answer. Here each line is read in chunks of at most
``CHUNK_BYTES``; a line longer than ``MAX_MESSAGE_BYTES`` is discarded up to its newline
as it arrives (never held whole) and answered with an Invalid Request error. A line that is
not JSON (or nested too deep to parse) is answered with a Parse error whose id is null, as
JSON-RPC 2.0 says; one that is JSON but not a JSON-RPC message with an Invalid Request
error carrying its id when it has a usable one (null otherwise). A request carrying an
integer of more than 4300 digits (Python's limit on converting one) is read all the same
and answered under its own id with an Invalid params error. Only lines the SDK accepts
reach it.
"""

from __future__ import annotations

import fcntl
import json
import os
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any, cast

import anyio
import anyio.to_thread
import mcp_types as types
from anyio.abc import ObjectSendStream
from mcp.server.stdio import stdio_server
from mcp.shared.message import SessionMessage
from pydantic import ValidationError

#: The longest message the server reads, newline excluded. The largest legitimate one is a
#: submit_answer carrying an answer's text (at most 20,000 characters, each at most 6 bytes
#: once JSON-escaped, about 120 kB with its envelope): 1 MiB leaves room to spare.
MAX_MESSAGE_BYTES = 1 << 20
#: How much is read from stdin at a time.
CHUNK_BYTES = 1 << 16


def _request_id(message: object) -> int | str | None:
    """The id of ``message`` if it carries one a reply can name, else None."""
    if not isinstance(message, dict):
        return None
    request_id = message.get("id")
    if isinstance(request_id, str) or (
        isinstance(request_id, int) and not isinstance(request_id, bool)
    ):
        return request_id
    return None


def check(line: str) -> types.JSONRPCError | None:
    """None if the SDK accepts ``line`` as a JSON-RPC message, else the error to reply."""
    too_long: list[int] = []  # the digits of each integer Python would refuse to convert

    def integer(digits: str) -> int:
        if len(digits.lstrip("-")) > sys.get_int_max_str_digits():
            too_long.append(len(digits))
            return 0
        return int(digits)

    try:  # NaN and Infinity too, as the SDK reads them
        message = json.loads(line, parse_int=integer)
    except (ValueError, RecursionError) as error:
        reason = str(error).splitlines()[0].split(";")[0][:200] or type(error).__name__
        return _error(None, types.PARSE_ERROR, f"Parse error: {reason}")
    if not isinstance(message, dict):
        detail = f"a message is a JSON object, not {type(message).__name__}"
        return _error(None, types.INVALID_REQUEST, f"Invalid Request: {detail}")
    request_id = _request_id(message)
    if "id" in message and message["id"] is not None and request_id is None:
        detail = f"an id is a string or an integer, not {type(message['id']).__name__}"
        return _error(None, types.INVALID_REQUEST, f"Invalid Request: {detail}")
    if too_long:  # the request is read, its id known: answer it
        detail = f"a number has {max(too_long)} digits, more than {sys.get_int_max_str_digits()}"
        return _error(request_id, types.INVALID_PARAMS, f"Invalid params: {detail}")
    try:
        types.jsonrpc_message_adapter.validate_json(line, by_name=False)
    except (ValidationError, ValueError, RecursionError):
        detail = "not a JSON-RPC 2.0 request, notification or response"
        return _error(request_id, types.INVALID_REQUEST, f"Invalid Request: {detail}")
    return None


def _error(request_id: int | str | None, code: int, message: str) -> types.JSONRPCError:
    return types.JSONRPCError(
        jsonrpc="2.0", id=request_id, error=types.ErrorData(code=code, message=message)
    )


def too_large(limit: int = MAX_MESSAGE_BYTES) -> types.JSONRPCError:
    """The error for a line over ``limit`` bytes (its id is not read: null)."""
    detail = f"message over the limit of {limit} bytes; it was not read"
    return _error(None, types.INVALID_REQUEST, f"Invalid Request: {detail}")


class Lines:
    """The lines of file descriptor ``fd`` that the SDK accepts, as text; every other line is
    answered on ``replies`` (set once the transport's write stream exists)."""

    def __init__(self, fd: int, limit: int = MAX_MESSAGE_BYTES) -> None:
        self._fd = fd
        self._limit = limit
        self._pending = bytearray()
        self._eof = False
        self._replies: ObjectSendStream[SessionMessage] | None = None
        self._ready = anyio.Event()

    def answer_on(self, replies: ObjectSendStream[SessionMessage]) -> None:
        self._replies = replies
        self._ready.set()

    def __aiter__(self) -> Lines:
        return self

    async def __anext__(self) -> str:
        while True:
            raw = await self._line()
            if raw is None:
                raise StopAsyncIteration
            if isinstance(raw, types.JSONRPCError):
                await self._reply(raw)
                continue
            text = raw.decode("utf-8", errors="replace")
            if not text.strip():
                continue
            error = check(text)
            if error is None:
                return text
            await self._reply(error)

    async def _line(self) -> bytes | types.JSONRPCError | None:
        """The next line (newline stripped), the error for one over the limit, or None at
        the end of input."""
        discarding = False
        while True:
            end = self._pending.find(b"\n")
            if end >= 0:
                line = bytes(self._pending[:end])
                del self._pending[: end + 1]
                if discarding or len(line) > self._limit:
                    return too_large(self._limit)
                return line
            if len(self._pending) > self._limit:
                discarding = True
                self._pending.clear()
            if self._eof:
                if discarding:
                    return too_large(self._limit)
                if not self._pending:
                    return None
                line = bytes(self._pending)
                self._pending.clear()
                return line
            chunk = await anyio.to_thread.run_sync(os.read, self._fd, CHUNK_BYTES)
            if not chunk:
                self._eof = True
            self._pending += chunk

    async def _reply(self, error: types.JSONRPCError) -> None:
        await self._ready.wait()
        assert self._replies is not None
        try:
            await self._replies.send(SessionMessage(error))
        except (anyio.ClosedResourceError, anyio.BrokenResourceError):
            pass


@asynccontextmanager
async def stdio(
    limit: int = MAX_MESSAGE_BYTES,
) -> AsyncIterator[tuple[Any, ObjectSendStream[SessionMessage]]]:
    """The SDK's stdio transport, reading through :class:`Lines`. While it serves, fd 0
    points at the null device (as the SDK does), so nothing else reads the wire."""
    wire = fcntl.fcntl(0, fcntl.F_DUPFD_CLOEXEC, 3)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.close(null)
    lines = Lines(wire, limit)
    try:
        async with stdio_server(stdin=cast(Any, lines)) as (read_stream, write_stream):
            lines.answer_on(write_stream)
            yield read_stream, write_stream
    finally:
        os.dup2(wire, 0)
