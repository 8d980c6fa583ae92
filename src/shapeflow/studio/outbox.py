"""What waits for one tab: a bounded, coalescing queue and the one task that sends it.

Every send to a socket goes through an :class:`Outbox`: two coroutines writing to one aiohttp
WebSocket at once (an edit's answer and the family's progress) could leave one of them waiting for
a drain that never came, and a slow tab must never hold up the others or the edits.

Bounded: a message that supersedes queued ones replaces them (a full ``POS0`` frame the
``POS0``/``PSUB`` frames before it, a ``mesh`` message everything but the ``done`` and ``error``
answers); when what waits still exceeds
``limit`` bytes, the queue is emptied and the tab gets one fresh snapshot of the whole session
instead (``resync()``, whose ``state`` message says ``"resync": true``: the page stops waiting for
the answers it lost).  ``state``, ``done`` and ``error`` messages (a few hundred bytes) are never coalesced: the page
counts one ``done`` or ``error`` per request.  A send that does not complete
within ``stall`` seconds (a tab that stopped reading) closes that socket: the server keeps no
memory for it.
"""

from __future__ import annotations

import asyncio
import collections
import json

__all__ = ["Outbox", "LIMIT", "STALL"]

#: bytes a tab may have waiting before its queue is replaced by a snapshot
LIMIT = 64 << 20
#: seconds one send may take before the tab counts as stalled and is closed
STALL = 30.0


def _kind(m) -> str:
    if isinstance(m, bytes):
        return m[:4].decode("ascii", "replace")
    return str(m.get("type", ""))


class Outbox:
    """The queue of one tab (``ws``: its aiohttp WebSocketResponse; ``resync``: a callable returning
    the messages that draw the session from scratch; ``abort``: closes the connection at once)."""

    def __init__(self, ws, resync, abort, *, limit: int = LIMIT, stall: float = STALL):
        self.ws, self.resync, self.abort = ws, resync, abort
        self.limit, self.stall = int(limit), float(stall)
        self.queue: collections.deque = collections.deque()
        self.bytes = 0
        self.peak = 0               #: the most bytes that ever waited
        self.dropped = 0            #: messages replaced or dropped (coalesced) so far
        self.stalled = False
        self._ready = asyncio.Event()
        self.task = asyncio.create_task(self._send())

    @staticmethod
    def size(m) -> int:
        return len(m) if isinstance(m, bytes) else 256

    def _drop(self, keep) -> None:
        before = len(self.queue)
        self.queue = collections.deque(m for m in self.queue if keep(m))
        self.bytes = sum(self.size(m) for m in self.queue)
        self.dropped += before - len(self.queue)

    def put(self, *messages) -> None:
        for m in messages:
            kind = _kind(m)
            if kind == "mesh":                  # answers to earlier requests still go: the page counts them
                self._drop(lambda q: _kind(q) in ("done", "error"))
            elif kind == "POS0":
                self._drop(lambda q: _kind(q) not in ("POS0", "PSUB"))
            self.queue.append(m)
            self.bytes += self.size(m)
        if self.bytes > self.limit:               # still too much: one snapshot replaces it all
            self._drop(lambda q: False)
            for m in self.resync():
                self.queue.append(m)
                self.bytes += self.size(m)
        self.peak = max(self.peak, self.bytes)
        self._ready.set()

    def close(self) -> None:
        """The socket closed: nothing more can reach the tab."""
        self.task.cancel()
        self.queue.clear()
        self.bytes = 0

    async def _send(self) -> None:
        while True:
            if not self.queue:
                self._ready.clear()
                await self._ready.wait()
                continue
            m = self.queue.popleft()
            self.bytes -= self.size(m)
            send = self.ws.send_bytes(m) if isinstance(m, bytes) else self.ws.send_str(json.dumps(m))
            try:
                await asyncio.wait_for(send, self.stall)
            except asyncio.TimeoutError:           # the tab stopped reading: close it
                self.stalled = True
                self.queue.clear()
                self.bytes = 0
                self.abort()
                return
            except (ConnectionError, RuntimeError):      # the tab went away: drop what is left
                self.queue.clear()
                self.bytes = 0
                return
