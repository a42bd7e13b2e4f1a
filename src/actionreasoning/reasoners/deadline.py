"""A total deadline on one request of an httpx client: connect, send, wait and read together.

httpx's timeouts bound each socket operation, not a request: a server that sends its answer a
byte at a time restarts the read timeout at every byte and never trips it. A
:class:`Watchdog` learns the socket of each connection from httpcore's ``trace`` extension
and shuts it down when the request's deadline passes, which ends a blocked read or write at
once; a connect in progress is bounded by the request's own connect timeout, which the caller
sets to the same time. Name resolution is not bounded (the system resolver has its own
limits).
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Protocol

#: httpcore's trace events that return a new network stream (a TLS one wraps a fresh socket).
_CONNECTED = (".connect_tcp.complete", ".connect_unix_socket.complete", ".start_tls.complete")


class _Request(Protocol):
    extensions: dict[str, Any]


class Watchdog:
    """Cuts an httpx client's request in flight when its time is up.

    Install :meth:`hook` as the client's ``request`` event hook and send each request inside
    :meth:`limit`. The client sends one request at a time, so the connection it opened last
    is the one in use: httpcore reuses it while idle, or opens another.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._socket: socket.socket | None = None
        self.expired = False

    def hook(self, request: _Request) -> None:
        """Have httpcore report the connections this request opens."""
        request.extensions["trace"] = self._trace

    @contextmanager
    def limit(self, seconds: float) -> Iterator[None]:
        """Cut the request sent in this block after ``seconds``; ``expired`` says if it was."""
        self.expired = False
        timer = threading.Timer(seconds, self._expire)
        timer.start()
        try:
            yield
        finally:
            timer.cancel()
            timer.join()

    def _trace(self, event: str, info: dict[str, Any]) -> None:
        if not event.endswith(_CONNECTED):
            return
        connection = info["return_value"].get_extra_info("socket")
        with self._lock:
            self._socket = connection
            late = self.expired
        if late:  # connected after the deadline: end the request at its first send
            _shut(connection)

    def _expire(self) -> None:
        with self._lock:
            self.expired = True
            connection = self._socket
        if connection is not None:
            _shut(connection)


def _shut(connection: socket.socket) -> None:
    """Shut a socket down both ways: a blocked read or write in another thread ends now."""
    try:
        connection.shutdown(socket.SHUT_RDWR)
    except OSError:  # closed already, or never connected
        pass
