"""An HTTP server that clients who connect and then stall cannot exhaust.

Clients that connect and then stall cost the server little. A new connection waits in a
waiting room (one thread watching every waiting socket) until its first bytes arrive; only
then does a handler thread take it. A connection silent for :data:`READ_TIMEOUT_S` (waiting
for its request, or mid-headers or mid-body) is closed; at most :data:`MAX_WAITING`
connections wait (the oldest is closed to make room for a new one) and at most
:data:`MAX_HANDLERS` are handled at once (a ready request over that bound gets 503 at once).
A client dropped on any of these grounds, or that hangs up mid-request, is one line on
stderr, never a traceback.
"""

from __future__ import annotations

import io
import json
import math
import selectors
import socket
import sys
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from actionreasoning.errors import ConfigError

#: Seconds a connection may stay silent (before its request, mid-headers, mid-body) before it
#: is closed. Our clients send each request whole at once on loopback, so a live one never
#: pauses this long; the openai client (httpx) drops its idle keep-alive connections after 5 s
#: itself, so the server never closes one it is about to reuse.
READ_TIMEOUT_S = 10.0
#: Seconds a request may take from the moment its handler starts reading it (a kept-alive
#: connection's wait for it included) to its last body byte. Reads are each bounded by
#: READ_TIMEOUT_S too, so this only stops clients that trickle bytes to stay alive: ours
#: send a request whole at once on loopback, so 30 s (three silent reads) is ample.
REQUEST_DEADLINE_S = 30.0
#: The most bytes a request's line and headers may take (the body is bounded by its own
#: Content-Length limit): an OpenAI-compatible request's headers are well under 4 KiB.
MAX_HEADER_BYTES = 64 * 1024
#: Requests handled at once (one thread each); a ready request over this gets 503 at once.
MAX_HANDLERS = 32
#: Connections held while waiting for their first bytes (a file descriptor each, no thread).
MAX_WAITING = 256


class GuardedHTTPServer(ThreadingHTTPServer):
    """A threading HTTP server whose stalled clients are bounded (see the module's text);
    ``name`` starts the stderr line of each dropped client."""

    daemon_threads = True
    #: The listen backlog: a burst of connections waits here to be accepted, not in SYN
    #: retries of a second or more (the standard library's default is 5).
    request_queue_size = 128
    name = "server"

    def __init__(
        self,
        address: tuple[str, int],
        handler: type[GuardedHandler],
        *,
        read_timeout_s: float = READ_TIMEOUT_S,
        max_handlers: int = MAX_HANDLERS,
        max_waiting: int = MAX_WAITING,
    ) -> None:
        if not (math.isfinite(read_timeout_s) and read_timeout_s > 0):
            raise ConfigError(f"read_timeout_s must be a positive number, not {read_timeout_s}")
        for name, bound in (("max_handlers", max_handlers), ("max_waiting", max_waiting)):
            if bound < 1:
                raise ConfigError(f"{name} must be at least 1, not {bound}")
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
            super().__init__(address, handler)
        except OSError:
            self._selector.close()
            raise

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
        _dropped(self, client_address, reason)
        self.shutdown_request(request)

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client that timed out or hung up mid-request is one line; anything else (a bug)
        keeps its traceback."""
        error = sys.exc_info()[1]
        if isinstance(error, TimeoutError):
            _dropped(self, client_address, f"silent for {self.read_timeout_s:g} s mid-request")
        elif isinstance(error, OSError):
            _dropped(self, client_address, f"hung up mid-request ({type(error).__name__})")
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


def _dropped(server: GuardedHTTPServer, client_address: Any, reason: str) -> None:
    """The one stderr line for a dropped client."""
    host, port = client_address[:2]
    sys.stderr.write(f"{server.name}: dropped {host}:{port}: {reason}\n")  # one write
    sys.stderr.flush()


class RequestOverrun(TimeoutError):
    """A request that outlasted REQUEST_DEADLINE_S, or whose headers outgrew
    MAX_HEADER_BYTES: its client is dropped with this reason."""


class _RequestReads(io.RawIOBase):
    """A connection's reads, each bounded by the server's ``read_timeout_s`` and by what is
    left of the request's deadline; the bytes of a request's line and headers are counted
    against MAX_HEADER_BYTES."""

    def __init__(self, connection: socket.socket, read_timeout_s: float) -> None:
        self.connection = connection
        self.read_timeout_s = read_timeout_s
        self.deadline = math.inf
        self.head_bytes: int | None = None  # None once the headers are read

    def readable(self) -> bool:
        return True

    def start(self) -> None:
        """A new request: its deadline runs from now, its headers are counted."""
        self.deadline = time.monotonic() + REQUEST_DEADLINE_S
        self.head_bytes = 0

    def readinto(self, buffer: Any) -> int:
        overrun = RequestOverrun(f"the request took longer than {REQUEST_DEADLINE_S:g} s")
        left = self.deadline - time.monotonic()
        if left <= 0:
            raise overrun
        self.connection.settimeout(min(self.read_timeout_s, left))
        try:
            count = self.connection.recv_into(buffer)
        except TimeoutError:
            if left < self.read_timeout_s:  # it was the deadline that ran out
                raise overrun from None
            raise
        if self.head_bytes is not None:
            self.head_bytes += count
            if self.head_bytes > MAX_HEADER_BYTES + len(buffer):  # a read may hold body too
                raise RequestOverrun(f"its headers are over {MAX_HEADER_BYTES} bytes")
        return count


class GuardedHandler(BaseHTTPRequestHandler):
    """A request handler whose reads time out after the server's ``read_timeout_s``, whose
    requests have REQUEST_DEADLINE_S each and headers of at most MAX_HEADER_BYTES; a
    subclass calls :meth:`answered` once it has sent a response."""

    server: GuardedHTTPServer

    #: Whether the connection is between requests, its last one answered.
    _idle = False

    def setup(self) -> None:
        super().setup()
        self.rfile.close()  # the socket's own reader, replaced by one that keeps the deadline
        self._reads = _RequestReads(self.connection, self.server.read_timeout_s)
        self.rfile = io.BufferedReader(self._reads)

    def handle_one_request(self) -> None:
        self._reads.start()
        super().handle_one_request()

    def parse_request(self) -> bool:
        self._idle = False
        parsed = super().parse_request()
        self._reads.head_bytes = None  # the body is bounded by its Content-Length
        return parsed

    def log_error(self, format: str, *args: Any) -> None:
        """The base class reports a read that timed out here: mid-request, that drops the
        client (one line); between requests, it closes a kept-alive connection (quiet)."""
        overrun = next((a for a in args if isinstance(a, RequestOverrun)), None)
        if overrun is not None:
            _dropped(self.server, self.client_address, str(overrun))
        elif format.startswith("Request timed out") and not self._idle:
            _dropped(
                self.server,
                self.client_address,
                f"silent for {self.server.read_timeout_s:g} s mid-request",
            )
        else:
            self.log_message(format, *args)

    def answered(self) -> None:
        """The request is answered: a timeout from now on closes an idle connection."""
        self._idle = True
