"""A small Future with rclpy's shape: the outcome of a service call (and later an action).

Its result is set from any thread (the transport's, or the executor's for an
in-process server); :meth:`Future.wait` blocks a thread until then. Done
callbacks run in the executor that owns the future's client (as rclpy runs them
in the node's executor), so they may touch node state without locks; a future
with no executor runs them in the thread that completes it.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Generic, TypeVar

__all__ = ["Future"]

T = TypeVar("T")


class Future(Generic[T]):
    """The outcome of an asynchronous operation (rclpy's ``Future``).

    Args:
        dispatch: Called with the future when it completes and has done callbacks,
            to run them in an executor (:meth:`run_callbacks`); None runs them at once.
    """

    # One future per service call: plain locks, not a threading.Condition (whose
    # constructor alone costs more than the rest of a call's bookkeeping). ``_lock``
    # guards the state; ``_gate`` (made by the first wait()) is held until completion
    # releases it, and each waiter passes it on by releasing it again.
    __slots__ = (
        "__weakref__",
        "_callbacks",
        "_cancelled",
        "_dispatch",
        "_done",
        "_exception",
        "_gate",
        "_internal",
        "_lock",
        "_result",
    )

    def __init__(self, dispatch: Callable[[Future[T]], None] | None = None) -> None:
        self._lock = threading.Lock()
        self._gate: threading.Lock | None = None
        self._done = False
        self._cancelled = False
        self._result: T | None = None
        self._exception: BaseException | None = None
        self._callbacks: list[Callable[[Future[T]], Any]] = []
        self._dispatch = dispatch
        self._internal: list[Callable[[], Any]] | None = None

    def done(self) -> bool:
        """Whether the future has a result, an exception, or was cancelled."""
        return self._done

    def cancelled(self) -> bool:
        """Whether :meth:`cancel` ended it."""
        return self._cancelled

    def result(self) -> T | None:
        """The result; None while pending. Raises the exception the operation failed with."""
        if self._exception is not None:
            raise self._exception
        return self._result

    def exception(self) -> BaseException | None:
        """The exception the operation failed with, or None."""
        return self._exception

    def set_result(self, result: T) -> None:
        """Complete with ``result`` (ignored once done)."""
        self._complete(result, None)

    def set_exception(self, exception: BaseException) -> None:
        """Fail with ``exception`` (ignored once done)."""
        self._complete(None, exception)

    def cancel(self) -> None:
        """Give up: the future is done and cancelled; a late result is ignored."""
        with self._lock:
            if self._done:
                return
            self._cancelled = True
        self._complete(None, None, cancelling=True)

    def _complete(
        self, result: T | None, exception: BaseException | None, *, cancelling: bool = False
    ) -> None:
        with self._lock:
            if self._done:
                return
            self._result = result
            self._exception = exception
            self._done = True
            gate = self._gate
            has_callbacks = bool(self._callbacks)
            internal, self._internal = self._internal, None
        if gate is not None:
            gate.release()  # wakes the first waiter, which passes it on
        if internal:
            for hook in internal:
                hook()
        if has_callbacks and not cancelling:
            if self._dispatch is not None:
                self._dispatch(self)
            else:
                self.run_callbacks()

    def add_done_callback(self, callback: Callable[[Future[T]], Any]) -> None:
        """Call ``callback(future)`` once done (in the executor; at once if already done)."""
        with self._lock:
            if not self._done:
                self._callbacks.append(callback)
                return
        if self._dispatch is not None and not self._cancelled:
            self._callbacks.append(callback)
            self._dispatch(self)
        else:
            callback(self)

    def on_complete(self, hook: Callable[[], Any]) -> None:
        """Call ``hook()`` in the completing thread once done (plumbing, e.g. timers)."""
        with self._lock:
            if not self._done:
                if self._internal is None:
                    self._internal = []
                self._internal.append(hook)
                return
        hook()

    def run_callbacks(self) -> None:
        """Run (and forget) the pending done callbacks; the executor calls this."""
        with self._lock:
            callbacks, self._callbacks = self._callbacks, []
        for cb in callbacks:
            cb(self)

    def wait(self, timeout_sec: float | None = None) -> bool:
        """Block until done or ``timeout_sec`` passes; return :meth:`done`."""
        if self._done:
            return True
        with self._lock:
            if self._done:
                return True
            gate = self._gate
            if gate is None:
                gate = self._gate = threading.Lock()
                gate.acquire()
        if timeout_sec is None:
            got = gate.acquire()
        elif timeout_sec > 0:
            got = gate.acquire(timeout=timeout_sec)
        else:
            got = gate.acquire(blocking=False)
        if got:
            gate.release()  # the next waiter (if any) wakes in turn
        return self._done

    def __repr__(self) -> str:
        state = "cancelled" if self._cancelled else "done" if self._done else "pending"
        return f"<Future {state}>"
