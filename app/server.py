"""The HTTP server's connection timeouts: a slow client cannot hold a connection forever.

uvicorn closes a keep-alive connection that stays idle between requests, but waits without
limit for a request head that arrives a byte at a time, or for a body that stops half-way
("slowloris"): a few hundred such connections exhaust the service. ``GuardedH11Protocol``
adds two timers to uvicorn's h11 protocol:

* **header timeout**: a request head must be complete within ``header_timeout`` seconds of
  its first byte (or of the connection's opening);
* **idle timeout**: while a request body is being received, the client may not stay silent
  for more than ``idle_timeout`` seconds.

Either closes the connection. Nothing changes once a request has been read: a long
computation or a large answer is not cut short.
"""

from __future__ import annotations

import asyncio
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

__all__ = ["GuardedH11Protocol", "guarded_protocol"]


class GuardedH11Protocol(H11Protocol):
    """uvicorn's h11 protocol with a header timeout and a body idle timeout."""

    header_timeout: float = 10.0
    idle_timeout: float = 30.0

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        self._head_timer: asyncio.TimerHandle | None = None
        self._idle_timer: asyncio.TimerHandle | None = None
        super().connection_made(transport)
        self._watch()

    def data_received(self, data: bytes) -> None:
        super().data_received(data)
        self._watch(data_arrived=True)

    def on_response_complete(self) -> None:
        super().on_response_complete()
        self._watch()

    def connection_lost(self, exc: Exception | None) -> None:
        self._cancel("_head_timer")
        self._cancel("_idle_timer")
        super().connection_lost(exc)

    # ---- timers ---------------------------------------------------------------------------
    def _watch(self, data_arrived: bool = False) -> None:
        """Arm or clear the timers for what the client is sending now."""
        state = self.conn.their_state
        between_requests = self.cycle is None or self.cycle.response_complete
        if state is h11.IDLE and between_requests:
            # Waiting for a request head. Between requests uvicorn's keep-alive timer runs;
            # the head timer starts with the head's first byte (or the connection).
            if self._head_timer is None and (data_arrived or self.cycle is None):
                self._head_timer = self.loop.call_later(self.header_timeout, self._expire)
            self._cancel("_idle_timer")
        elif state is h11.SEND_BODY:
            self._cancel("_head_timer")
            self._cancel("_idle_timer")
            self._idle_timer = self.loop.call_later(self.idle_timeout, self._expire)
        else:  # the request has been read: the answer is ours to take time over
            self._cancel("_head_timer")
            self._cancel("_idle_timer")

    def _cancel(self, name: str) -> None:
        timer = getattr(self, name, None)
        if timer is not None:
            timer.cancel()
            setattr(self, name, None)

    def _expire(self) -> None:
        self._head_timer = self._idle_timer = None
        if not self.transport.is_closing():
            self.transport.close()


def guarded_protocol(header_timeout: float, idle_timeout: float) -> type[GuardedH11Protocol]:
    """A ``GuardedH11Protocol`` class with these timeouts (uvicorn takes a class)."""
    attrs: dict[str, Any] = {"header_timeout": float(header_timeout),
                             "idle_timeout": float(idle_timeout)}
    return type("KinoplanH11Protocol", (GuardedH11Protocol,), attrs)
