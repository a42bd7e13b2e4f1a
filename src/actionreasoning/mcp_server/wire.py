"""The server's stdin: JSON-RPC lines read in bounded memory, each checked before the SDK
sees it, so every request gets an answer.

The SDK drops a line it cannot parse or validate without a reply, which leaves a client
waiting forever for its request's answer. Here each line is read in chunks of at most
``CHUNK_BYTES``; a line longer than ``MAX_MESSAGE_BYTES`` is discarded up to its newline
as it arrives (never held whole) and answered with an Invalid Request error. A line that is
not JSON (or nested too deep to parse), a blank one too, is answered with a Parse error
whose id is null, as JSON-RPC 2.0 says; one that is JSON but not a JSON-RPC message with an
Invalid Request error carrying its id when it has a usable one (null otherwise). A request
whose id is null (which the SDK takes for a notification) or an integer of more than 4300
digits (Python's limit on converting one; read as 0 it would answer request 0) is an
Invalid Request with id null; one carrying such an integer elsewhere is read all the same
and answered under its own id with an Invalid params error. Only lines the SDK accepts
reach it; a line's trailing ``\r`` is whitespace, and the end of input after a last newline
no line.

JSON escapes a lone surrogate (``"\ud800"``), which is no Unicode character; the SDK's
parser refuses the whole line. Such a line reaches the SDK with each lone surrogate
replaced by U+FFFD, so it validates; a tools/call's name and arguments as sent go to the
door all the same (through :class:`~actionreasoning.mcp_server.arrivals.Arrivals`), which
refuses a string holding one as a tool result. A request whose id holds one is an Invalid
Request with id null (its answer could not name it).

Each tools/call request read, and each cancellation of one, is noted in ``Arrivals``, and
each answer written settles its request there: calls run in the order they arrived.
"""

from __future__ import annotations

import fcntl
import json
import os
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass
from types import TracebackType
from typing import Any, cast

import anyio
import anyio.to_thread
import mcp_types as types
from anyio.abc import ObjectSendStream
from mcp.server.stdio import stdio_server
from mcp.shared.jsonrpc_dispatcher import cancelled_request_id_from_params
from mcp.shared.message import SessionMessage
from pydantic import ValidationError

from actionreasoning.mcp_server.arrivals import Arrivals, Sent
from actionreasoning.mcp_server.door import LONE_SURROGATE

#: The longest message the server reads, newline excluded. The largest legitimate one is a
#: submit_answer carrying an answer's text (at most 20,000 characters, each at most 6 bytes
#: once JSON-escaped, about 120 kB with its envelope): 1 MiB leaves room to spare.
MAX_MESSAGE_BYTES = 1 << 20
#: How much is read from stdin at a time.
CHUNK_BYTES = 1 << 16


@dataclass(frozen=True)
class _TooLong:
    """An integer of more digits than Python converts."""

    digits: int


@dataclass(frozen=True)
class Message:
    """A line the SDK accepts: the text it is handed (the line, or the message with its lone
    surrogates ``replaced``) and the message as sent."""

    text: str
    sent: dict[str, Any]
    replaced: bool = False


def _request_id(message: dict[str, Any]) -> int | str | None:
    """The id of ``message`` if it carries one a reply can name, else None."""
    request_id = message.get("id")
    if isinstance(request_id, str) and not LONE_SURROGATE.search(request_id):
        return request_id
    if isinstance(request_id, int) and not isinstance(request_id, bool):
        return request_id
    return None


def check(line: str) -> Message | types.JSONRPCError:
    """The message the SDK accepts in ``line``, else the error to reply."""
    too_long: list[int] = []  # the digits of each integer Python would refuse to convert

    def integer(digits: str) -> int | _TooLong:
        if len(digits.lstrip("-")) > sys.get_int_max_str_digits():
            too_long.append(len(digits))
            return _TooLong(len(digits))
        return int(digits)

    if not line.strip():
        return _error(None, types.PARSE_ERROR, "Parse error: a blank line")
    try:  # NaN and Infinity too, as the SDK reads them
        message = json.loads(line, parse_int=integer)
    except (ValueError, RecursionError) as error:
        reason = str(error).splitlines()[0].split(";")[0][:200] or type(error).__name__
        return _error(None, types.PARSE_ERROR, f"Parse error: {reason}")
    if not isinstance(message, dict):
        detail = f"a message is a JSON object, not {type(message).__name__}"
        return _error(None, types.INVALID_REQUEST, f"Invalid Request: {detail}")
    request_id = _request_id(message)
    if "id" in message and request_id is None:
        if message["id"] is not None or "method" in message:  # a response's id may be null
            return _error(None, types.INVALID_REQUEST, f"Invalid Request: {_bad_id(message['id'])}")
    if too_long:  # the request is read, its id known: answer it
        detail = f"a number has {max(too_long)} digits, more than {sys.get_int_max_str_digits()}"
        return _error(request_id, types.INVALID_PARAMS, f"Invalid params: {detail}")
    if _valid(line):
        return Message(line, message)
    replaced = _without_lone_surrogates(message)
    if replaced is not None and _valid(replaced):
        return Message(replaced, message, replaced=True)
    detail = "not a JSON-RPC 2.0 request, notification or response"
    return _error(request_id, types.INVALID_REQUEST, f"Invalid Request: {detail}")


def _bad_id(request_id: object) -> str:
    if isinstance(request_id, _TooLong):
        return f"the id has {request_id.digits} digits, more than {sys.get_int_max_str_digits()}"
    if isinstance(request_id, str):
        return "the id is not valid Unicode (it holds a lone surrogate)"
    kind = "null" if request_id is None else type(request_id).__name__
    return f"an id is a string or an integer, not {kind}"


def _valid(text: str) -> bool:
    """Whether the SDK reads ``text`` as a JSON-RPC message."""
    try:
        types.jsonrpc_message_adapter.validate_json(text, by_name=False)
    except (ValidationError, ValueError, RecursionError):
        return False
    return True


def _without_lone_surrogates(message: dict[str, Any]) -> str | None:
    """``message`` as JSON with each lone surrogate replaced by U+FFFD, if it holds one."""
    try:
        text = json.dumps(message, ensure_ascii=False)
    except (ValueError, RecursionError):
        return None
    return LONE_SURROGATE.sub("\ufffd", text) if LONE_SURROGATE.search(text) else None


def _error(request_id: int | str | None, code: int, message: str) -> types.JSONRPCError:
    return types.JSONRPCError(
        jsonrpc="2.0", id=request_id, error=types.ErrorData(code=code, message=message)
    )


def too_large(limit: int = MAX_MESSAGE_BYTES) -> types.JSONRPCError:
    """The error for a line over ``limit`` bytes (its id is not read: null)."""
    detail = f"message over the limit of {limit} bytes; it was not read"
    return _error(None, types.INVALID_REQUEST, f"Invalid Request: {detail}")


def _sent_call(message: Message) -> Sent | None:
    """A tools/call's name and arguments as sent, if the SDK is handed them changed."""
    params = message.sent.get("params")
    if not message.replaced or not isinstance(params, dict):
        return None
    name, arguments = params.get("name"), params.get("arguments")
    if isinstance(name, str) and (arguments is None or isinstance(arguments, dict)):
        return name, arguments
    return None


class Lines:
    """The lines of file descriptor ``fd`` that the SDK accepts, as text (tools/call requests
    and their cancellations noted in ``arrivals``); every other line is answered on
    ``replies`` (set once the transport's write stream exists)."""

    def __init__(self, fd: int, arrivals: Arrivals, limit: int = MAX_MESSAGE_BYTES) -> None:
        self._fd = fd
        self._arrivals = arrivals
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
            message = check(raw.decode("utf-8", errors="replace"))
            if isinstance(message, types.JSONRPCError):
                await self._reply(message)
                continue
            self._note(message)
            return message.text

    def _note(self, message: Message) -> None:
        """Note a tools/call request, or a cancellation of one, in the arrivals."""
        sent = message.sent
        request_id = _request_id(sent)
        if sent.get("method") == "tools/call" and request_id is not None:
            self._arrivals.arrived(request_id, _sent_call(message))
        elif sent.get("method") == "notifications/cancelled" and "id" not in sent:
            cancelled = cancelled_request_id_from_params(sent.get("params"))
            if cancelled is not None:
                self._arrivals.settled(cancelled)

    async def _line(self) -> bytes | types.JSONRPCError | None:
        """The next line (newline stripped), the error for one over the limit, or None at
        the end of input (blanks after the last newline are no line)."""
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
                line = bytes(self._pending)
                self._pending.clear()
                return line if line.strip() else None
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


class _Answers:
    """The SDK's write stream, settling in ``arrivals`` each request answered on it."""

    def __init__(self, stream: Any, arrivals: Arrivals) -> None:
        self._stream = stream
        self._arrivals = arrivals

    async def send(self, item: SessionMessage, /) -> None:
        try:
            await self._stream.send(item)
        finally:
            message = item.message
            if isinstance(message, types.JSONRPCResponse | types.JSONRPCError) and (
                message.id is not None
            ):
                self._arrivals.settled(message.id)

    async def aclose(self) -> None:
        await self._stream.aclose()

    async def __aenter__(self) -> _Answers:
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc_val: BaseException | None,
        exc_tb: TracebackType | None,
    ) -> None:
        await self.aclose()


@asynccontextmanager
async def stdio(
    arrivals: Arrivals, limit: int = MAX_MESSAGE_BYTES
) -> AsyncIterator[tuple[Any, Any]]:
    """The SDK's stdio transport, reading through :class:`Lines` and noting in ``arrivals``
    the tools/call requests read and each request answered. While it serves, fd 0 points at
    the null device (as the SDK does), so nothing else reads the wire."""
    wire = fcntl.fcntl(0, fcntl.F_DUPFD_CLOEXEC, 3)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.close(null)
    lines = Lines(wire, arrivals, limit)
    try:
        async with stdio_server(stdin=cast(Any, lines)) as (read_stream, write_stream):
            lines.answer_on(write_stream)
            yield read_stream, _Answers(write_stream, arrivals)
    finally:
        os.dup2(wire, 0)
