"""Liveliness tokens declared off the caller's thread (cheap entity creation).

Declaring a Zenoh liveliness token costs ~0.3 ms of the caller's time; a node's six
parameter services would add ~2 ms to every node's creation. Their tokens only tell
*other* processes that the services exist (this process's graph has them at once),
and other processes learn of tokens asynchronously anyway, so a background thread
declares them, in order.
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["DeferredToken", "TokenDeclarer"]


class DeferredToken:
    """A token that a :class:`TokenDeclarer` declares soon; undeclare it like a real one."""

    __slots__ = ("_handle", "_lock", "_undeclared", "key")

    def __init__(self, key: str) -> None:
        self.key = key
        self._handle: Any = None
        self._undeclared = False
        self._lock = threading.Lock()

    def _declare(self, declare: Callable[[str], Any]) -> None:
        with self._lock:
            if not self._undeclared:
                self._handle = declare(self.key)

    def undeclare(self) -> None:
        """Undeclare the token (or make sure it is never declared)."""
        with self._lock:
            self._undeclared = True
            handle, self._handle = self._handle, None
        if handle is not None:
            with contextlib.suppress(Exception):
                handle.undeclare()


class _Marker:
    """Queued after the tokens a :meth:`TokenDeclarer.flush` waits for."""

    def __init__(self, done: threading.Event) -> None:
        self._done = done

    def _declare(self, declare: Callable[[str], Any]) -> None:
        self._done.set()


class TokenDeclarer:
    """One thread that declares :class:`DeferredToken` s in submission order.

    Args:
        declare: declares a token key and returns its handle (``ZenohTransport.token``).
    """

    def __init__(self, declare: Callable[[str], Any]) -> None:
        self._declare = declare
        self._queue: queue.SimpleQueue[DeferredToken | None] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._closed = False

    def submit(self, key: str) -> DeferredToken:
        """Queue ``key`` for declaration; return its handle."""
        token = DeferredToken(key)
        with self._lock:
            if self._closed:
                return token
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="visnav-tokens", daemon=True)
                self._thread.start()
            self._queue.put(token)
        return token

    def _run(self) -> None:
        while True:
            token = self._queue.get()
            if token is None:
                return
            if self._closed and not isinstance(token, _Marker):
                continue  # closing: the session is about to go, skip what is left
            with contextlib.suppress(Exception):  # the session closed meanwhile
                token._declare(self._declare)

    def flush(self, timeout_s: float = 5.0) -> bool:
        """Wait until every token submitted so far is declared; False after ``timeout_s``."""
        done = threading.Event()
        with self._lock:
            if self._thread is None or self._closed:
                return True
            self._queue.put(_Marker(done))  # type: ignore[arg-type]
        return done.wait(timeout_s)

    def close(self) -> None:
        """Stop the thread after the queued tokens (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            thread = self._thread
            self._queue.put(None)
        if thread is not None:
            thread.join(timeout=5.0)
