"""An OpenAI-compatible chat server on loopback for the prompt-only reference model.

``POST /v1/chat/completions`` answers every conversation with
:func:`~actionreasoning.reasoners.reference_model.reply`, from the messages' text alone;
``response_format``, ``temperature``, ``seed``, ``max_tokens`` and any other field are
accepted and ignored, and any model name is echoed back. ``GET /v1/models`` lists the one
model, ``reference``. Failures are OpenAI error bodies: 400 for a malformed request or a
conversation the model cannot read (with its reason), 404 for an unknown path, 413 for a body
over :data:`MAX_BODY_BYTES`, 500 with one line for anything else (the traceback goes to
stderr only).

Clients that connect and then stall cost the server little. A new connection waits in a
waiting room (one thread watching every waiting socket) until its first bytes arrive; only
then does a handler thread take it. A connection silent for :data:`READ_TIMEOUT_S` (waiting
for its request, or mid-headers or mid-body) is closed; at most :data:`MAX_WAITING`
connections wait (the oldest is closed to make room for a new one) and at most
:data:`MAX_HANDLERS` are handled at once (a ready request over that bound gets 503 at once).
A client dropped on any of these grounds, or that hangs up mid-request, is one line on
stderr, never a traceback.

Token usage is an estimate (:func:`estimate_tokens`): there is no tokenizer behind the model.
The server binds a loopback address only and uses nothing but the standard library.
"""

from __future__ import annotations

import ipaddress
import json
import math
import re
import selectors
import socket
import sys
import threading
import time
import traceback
import uuid
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import urlsplit

from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.reference_model import Message, UnreadableConversation, reply

MODEL_ID = "reference"
#: A larger request body is refused with 413 before it is read.
MAX_BODY_BYTES = 8 * 1024 * 1024
#: Seconds a connection may stay silent (before its request, mid-headers, mid-body) before it
#: is closed. Our clients send each request whole at once on loopback, so a live one never
#: pauses this long; the openai client (httpx) drops its idle keep-alive connections after 5 s
#: itself, so the server never closes one it is about to reuse.
READ_TIMEOUT_S = 10.0
#: Requests handled at once (one thread each); a ready request over this gets 503 at once.
MAX_HANDLERS = 32
#: Connections held while waiting for their first bytes (a file descriptor each, no thread).
MAX_WAITING = 256
#: Tokens added per message for its role and framing, as chat formats do.
TOKENS_PER_MESSAGE = 4
_TOKEN = re.compile(r"[A-Za-z]+|[0-9]{1,3}|[^\sA-Za-z0-9]{1,3}")


def estimate_tokens(text: str) -> int:
    """An estimate of the BPE tokens in ``text``: one per run of letters, per run of up to
    three digits (as GPT tokenizers split numbers) and per run of up to three other
    non-space characters (``":[`` is one token there). On the agents' conversations of a
    nominal pyramid trial it is within 1 % of OpenAI's o200k_base tokenizer (14,352 against
    14,274 tokens per brick, 4 per message included)."""
    return sum(1 for _ in _TOKEN.finditer(text))


class ReferenceServer(ThreadingHTTPServer):
    """The reference model's chat server on ``host`` (loopback only) and ``port`` (0: a free
    one); run it with :meth:`serve_forever`, stop it with :meth:`shutdown` and
    :meth:`server_close`. ``verbose`` logs one line per request to stderr.
    ``read_timeout_s``, ``max_handlers`` and ``max_waiting`` bound what stalled clients may
    hold (see the module's text)."""

    daemon_threads = True
    #: The listen backlog: a burst of connections waits here to be accepted, not in SYN
    #: retries of a second or more (the standard library's default is 5).
    request_queue_size = 128

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 0,
        verbose: bool = False,
        *,
        read_timeout_s: float = READ_TIMEOUT_S,
        max_handlers: int = MAX_HANDLERS,
        max_waiting: int = MAX_WAITING,
    ) -> None:
        _check_loopback(host)
        if not (math.isfinite(read_timeout_s) and read_timeout_s > 0):
            raise ConfigError(f"read_timeout_s must be a positive number, not {read_timeout_s}")
        for name, bound in (("max_handlers", max_handlers), ("max_waiting", max_waiting)):
            if bound < 1:
                raise ConfigError(f"{name} must be at least 1, not {bound}")
        self.address_family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.verbose = verbose
        self.read_timeout_s = read_timeout_s
        self._handlers = threading.BoundedSemaphore(max_handlers)
        self._max_waiting = max_waiting
        #: Each waiting socket's address and deadline, oldest first.
        self._waiting: dict[socket.socket, tuple[Any, float]] = {}
        self._selector = selectors.DefaultSelector()
        self._lock = threading.Lock()
        self._closing = threading.Event()
        self._room: threading.Thread | None = None
        try:
            super().__init__((host, port), _Handler)
        except OSError as error:
            self._selector.close()
            raise ConfigError(f"cannot listen on {host} port {port}: {error.strerror}") from None

    @property
    def url(self) -> str:
        """The base URL clients are given, ``http://HOST:PORT/v1``."""
        host, port = str(self.server_address[0]), self.server_address[1]
        shown = f"[{host}]" if self.address_family == socket.AF_INET6 else host
        return f"http://{shown}:{port}/v1"

    def process_request(self, request: Any, client_address: Any) -> None:
        """A new connection waits in the waiting room, with no thread, for its first bytes."""
        with self._lock:
            if self._room is None:
                self._room = threading.Thread(target=self._watch, name="waiting-room", daemon=True)
                self._room.start()
            if len(self._waiting) >= self._max_waiting:
                oldest = next(iter(self._waiting))
                self._forget(oldest)
                self._drop(oldest, f"closed: {self._max_waiting} connections sent nothing yet")
            self._waiting[request] = (client_address, time.monotonic() + self.read_timeout_s)
            self._selector.register(request, selectors.EVENT_READ)

    def _watch(self) -> None:
        """The waiting room: a socket with bytes to read goes to a handler thread, one silent
        past its deadline is closed."""
        while not self._closing.is_set():
            ready = self._selector.select(timeout=0.05)
            now = time.monotonic()
            with self._lock:
                for key, _ in ready:
                    request = key.fileobj
                    if request in self._waiting:  # not closed meanwhile
                        self._dispatch(request, self._forget(request))
                for request, (_, deadline) in list(self._waiting.items()):
                    if deadline <= now:
                        self._forget(request)
                        self._drop(request, f"sent nothing for {self.read_timeout_s:g} s")

    def _forget(self, request: Any) -> Any:
        """Take ``request`` out of the waiting room; its client address."""
        self._selector.unregister(request)
        return self._waiting.pop(request)[0]

    def _dispatch(self, request: Any, client_address: Any) -> None:
        """Hand a ready connection to a thread of its own, if one is free."""
        if not self._handlers.acquire(blocking=False):
            self._refuse(request, client_address)
            return
        try:
            threading.Thread(
                target=self._handle, args=(request, client_address), daemon=True
            ).start()
        except RuntimeError as error:  # the system has no thread to give
            self._handlers.release()
            self._refuse(request, client_address, f" ({error})")

    def _handle(self, request: Any, client_address: Any) -> None:
        try:
            self.process_request_thread(request, client_address)
        finally:
            self._handlers.release()

    def _refuse(self, request: Any, client_address: Any, why: str = "") -> None:
        """503 at once, without a thread, and close."""
        message = "the reference server is busy: try again"
        body = json.dumps({"error": {"message": message, "type": "server_error", "code": None}})
        head = (
            "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
            f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
        )
        try:
            request.setblocking(False)
            request.send((head + body).encode())
            request.recv(65536)  # what has come of the request: a close with it unread resets
        except OSError:
            pass
        self._drop(request, f"refused with 503: all handlers busy{why}", client_address)

    def _drop(self, request: Any, reason: str, client_address: Any = None) -> None:
        """Close ``request`` with one line on stderr."""
        if client_address is None:
            try:
                client_address = request.getpeername()
            except OSError:
                client_address = ("?", 0)
        _dropped(client_address, reason)
        self.shutdown_request(request)

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client that timed out or hung up mid-request is one line; anything else (a bug)
        keeps its traceback."""
        error = sys.exc_info()[1]
        if isinstance(error, TimeoutError):
            _dropped(client_address, f"silent for {self.read_timeout_s:g} s mid-request")
        elif isinstance(error, OSError):
            _dropped(client_address, f"hung up mid-request ({type(error).__name__})")
        else:
            super().handle_error(request, client_address)

    def server_close(self) -> None:
        self._closing.set()
        if self._room is not None:
            self._room.join()
        with self._lock:
            for request in list(self._waiting):
                self._forget(request)
                self.shutdown_request(request)
        self._selector.close()
        super().server_close()


def _dropped(client_address: Any, reason: str) -> None:
    """The one stderr line for a dropped client."""
    host, port = client_address[:2]
    sys.stderr.write(f"reference server: dropped {host}:{port}: {reason}\n")  # one write
    sys.stderr.flush()


def _check_loopback(host: str) -> None:
    """Refuse any host but ``localhost`` or a loopback address."""
    try:
        loopback = host == "localhost" or ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if not loopback:
        raise ConfigError(
            f"--host {host} is not a loopback address: the reference server listens on this "
            "machine only (127.0.0.1, ::1 or localhost)"
        )


class _RequestError(Exception):
    """A request answered with an OpenAI error body."""

    def __init__(self, status: int, message: str, kind: str = "invalid_request_error") -> None:
        super().__init__(message)
        self.status = status
        self.kind = kind


class _Handler(BaseHTTPRequestHandler):
    server: ReferenceServer
    protocol_version = "HTTP/1.1"  # keep-alive, as the openai client expects
    server_version = "actionreasoning-reference"

    #: Whether the connection is between requests, its last one answered.
    _idle = False

    def setup(self) -> None:
        super().setup()
        self.connection.settimeout(self.server.read_timeout_s)  # each read of the connection

    def parse_request(self) -> bool:
        self._idle = False
        return super().parse_request()

    def log_error(self, format: str, *args: Any) -> None:
        """The base class reports a read that timed out here: mid-request, that drops the
        client (one line); between requests, it closes a kept-alive connection (quiet)."""
        if format.startswith("Request timed out") and not self._idle:
            _dropped(
                self.client_address, f"silent for {self.server.read_timeout_s:g} s mid-request"
            )
        else:
            self.log_message(format, *args)

    def do_GET(self) -> None:
        if self._path() == "/v1/models":
            models = [{"id": MODEL_ID, "object": "model", "created": 0, "owned_by": "local"}]
            self._send(HTTPStatus.OK, {"object": "list", "data": models})
        else:
            self._unknown_path()

    def do_POST(self) -> None:
        if self._path() != "/v1/chat/completions":
            self.close_connection = True  # the body is left unread
            self._unknown_path()
            return
        try:
            payload = _completion(self._body())
        except _RequestError as error:
            self._error(error.status, str(error), error.kind)
            return
        self._send(HTTPStatus.OK, payload)

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """The base class's own errors (a bad request line, an unknown method) as JSON."""
        self.close_connection = True
        self._error(code, message or HTTPStatus(code).phrase)

    def log_message(self, format: str, *args: Any) -> None:
        if self.server.verbose:
            super().log_message(format, *args)

    def _path(self) -> str:
        return urlsplit(self.path).path.rstrip("/")

    def _unknown_path(self) -> None:
        self._error(404, f"Unknown request URL: {self.command} {self._path()}")

    def _body(self) -> dict[str, Any]:
        """The request body as a JSON object; the connection is closed after a body that
        could not be read whole."""
        if "chunked" in self.headers.get("Transfer-Encoding", "").lower():
            self.close_connection = True
            raise _RequestError(411, "send the body with a Content-Length, not chunked")
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError:
            length = -1
        if length < 0:
            self.close_connection = True
            raise _RequestError(411, "the request needs a Content-Length byte count")
        if length > MAX_BODY_BYTES:
            self.close_connection = True
            raise _RequestError(
                413, f"the body has {length} bytes; at most {MAX_BODY_BYTES} are accepted"
            )
        raw = self.rfile.read(length)
        if len(raw) < length:  # the client closed its side mid-body
            self.close_connection = True
            raise ConnectionAbortedError(f"sent {len(raw)} of {length} body bytes")
        try:
            body = json.loads(raw)
        except (ValueError, RecursionError) as error:  # not UTF-8, not JSON, nested too deep
            raise _RequestError(400, f"the body is not valid JSON ({error})"[:300]) from None
        if not isinstance(body, dict):
            raise _RequestError(400, "the body must be a JSON object")
        return body

    def _error(self, status: int, message: str, kind: str = "invalid_request_error") -> None:
        self._send(status, {"error": {"message": message, "type": kind, "code": None}})

    def _send(self, status: int, payload: dict[str, Any]) -> None:
        data = json.dumps(payload).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        if self.close_connection:
            self.send_header("Connection", "close")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(data)
        self._idle = True


def _completion(body: dict[str, Any]) -> dict[str, Any]:
    """The ``chat.completion`` answering a request body."""
    model = body.get("model", MODEL_ID)
    if not isinstance(model, str):
        raise _RequestError(400, "'model' must be a string")
    if body.get("stream"):
        raise _RequestError(400, "'stream' is not supported: ask without it")
    messages = _messages(body.get("messages"))
    try:
        content = reply(messages)
    except UnreadableConversation as error:
        raise _RequestError(400, f"the reference model cannot answer: {error}") from None
    except Exception as error:  # a bug in the model: one line to the client, all to stderr
        print("reference server: reply() failed:", file=sys.stderr)
        traceback.print_exc(file=sys.stderr)
        line = f"{type(error).__name__}: {error}".splitlines()[0][:300]
        raise _RequestError(500, f"the reference model failed ({line})", "server_error") from None
    prompt_tokens = sum(estimate_tokens(m["content"] or "") + TOKENS_PER_MESSAGE for m in messages)
    completion_tokens = estimate_tokens(content)
    return {
        "id": f"chatcmpl-{uuid.uuid4().hex}",
        "object": "chat.completion",
        "created": int(time.time()),
        "model": model,
        "choices": [
            {
                "index": 0,
                "message": {"role": "assistant", "content": content},
                "finish_reason": "stop",
            }
        ],
        "usage": {
            "prompt_tokens": prompt_tokens,
            "completion_tokens": completion_tokens,
            "total_tokens": prompt_tokens + completion_tokens,
        },
    }


def _messages(value: object) -> list[Message]:
    """``messages`` checked: a list of objects with a string role and a string (or null)
    content."""
    if not isinstance(value, list):
        raise _RequestError(400, "'messages' must be a list of {role, content} objects")
    for index, message in enumerate(value):
        if not isinstance(message, dict) or not isinstance(message.get("role"), str):
            raise _RequestError(400, f"messages[{index}] must be an object with a string 'role'")
        if not isinstance(message.get("content"), str | None):
            raise _RequestError(400, f"messages[{index}].content must be a string")
    return value
