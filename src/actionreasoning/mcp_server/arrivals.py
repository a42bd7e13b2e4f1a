"""The tools/call requests of one connection, run one at a time in the order they arrived.

The SDK handles each request in a task of its own, and tasks reach the door in no set order:
a read_state sent right after a start_trial could run first and find no trial. Here
:mod:`~actionreasoning.mcp_server.wire` notes each tools/call request as its line is read,
and a call waits for its :meth:`Arrivals.turn` until every call that arrived before it has
settled: run, answered without running (the SDK answers one it refuses, such as a call
before ``initialize``) or cancelled by the client. So no request, however it ends, holds up
those after it.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from typing import Any, TypeAlias

import anyio
from mcp.shared.dispatcher import coerce_request_id
from mcp_types import RequestId

#: A tools/call's tool name and arguments.
Sent: TypeAlias = tuple[str, dict[str, Any] | None]


@dataclass(eq=False)
class _Call:
    """A tools/call request noted: its id, its name and arguments as sent when the SDK reads
    them changed, and whether its handler has taken its turn."""

    key: RequestId | None
    sent: Sent | None
    claimed: bool = False
    settled: anyio.Event = field(default_factory=anyio.Event)


class Arrivals:
    """The tools/call requests not yet settled, in arrival order."""

    def __init__(self) -> None:
        self._calls: list[_Call] = []

    def arrived(self, request_id: RequestId, sent: Sent | None = None) -> None:
        """Note a tools/call request read (``sent``: its name and arguments as sent, if the
        SDK reads them changed)."""
        self._calls.append(_Call(coerce_request_id(request_id), sent))

    def settled(self, request_id: RequestId) -> None:
        """Request ``request_id`` was answered or cancelled: settle it, unless its handler has
        taken its turn (and settles it when done)."""
        call = self._unclaimed(coerce_request_id(request_id))
        if call is not None:
            self._settle(call)

    @asynccontextmanager
    async def turn(self, request_id: RequestId | None) -> AsyncIterator[Sent | None]:
        """Wait until every call that arrived before ``request_id``'s has settled; give its
        name and arguments as sent if the SDK read them changed (else None). A call not noted
        (or settled already by its cancellation) waits as if it arrived now."""
        key = None if request_id is None else coerce_request_id(request_id)
        call = self._unclaimed(key)
        if call is None:
            call = _Call(key, None)
            self._calls.append(call)
        call.claimed = True
        earlier = self._calls[: self._calls.index(call)]
        try:
            for before in earlier:
                await before.settled.wait()
            yield call.sent
        finally:
            self._settle(call)

    def _unclaimed(self, key: RequestId | None) -> _Call | None:
        return next((c for c in self._calls if c.key == key and not c.claimed), None)

    def _settle(self, call: _Call) -> None:
        call.settled.set()
        self._calls.remove(call)
