"""``can_transform`` / ``can_transform_full`` of :class:`visnav.tf.buffer.Buffer` (internal).

tf2's answer to "would this lookup succeed?", now or after waiting (wall clock) for new
transforms: the lookup is retried on every insertion under the buffer's condition
variable. Never raises for frame problems; a malformed argument is answered at once.
"""

from __future__ import annotations

import threading
import time as _time
from collections.abc import Callable
from typing import Literal, overload

from visnav.msgs.types import Duration
from visnav.tf._buffer_io import TimeLike, timeout_s, to_ns
from visnav.tf._scalar import Pose7
from visnav.tf.errors import InvalidArgumentException, TransformException

__all__ = ["CanTransformMixin"]


class CanTransformMixin:
    """The ``can_transform`` family; the buffer provides the lock and the lookups."""

    _lock: threading.Lock
    _cond: threading.Condition
    _waiters: int = 0
    """Threads in :meth:`_wait_for` (changed with the lock held)."""

    def _lookup(self, target: str, source: str, t: int) -> tuple[Pose7, int]:
        raise NotImplementedError

    def _lookup_full(
        self, target: str, tt: int, source: str, ts: int, fixed: str
    ) -> tuple[Pose7, int]:
        raise NotImplementedError

    @overload
    def can_transform(
        self,
        target_frame: str,
        source_frame: str,
        time_ns: TimeLike = 0,
        *,
        timeout: float | Duration = 0.0,
        return_debug_tuple: Literal[False] = False,
    ) -> bool: ...

    @overload
    def can_transform(
        self,
        target_frame: str,
        source_frame: str,
        time_ns: TimeLike = 0,
        *,
        timeout: float | Duration = 0.0,
        return_debug_tuple: Literal[True],
    ) -> tuple[bool, str]: ...

    def can_transform(
        self,
        target_frame: str,
        source_frame: str,
        time_ns: TimeLike = 0,
        *,
        timeout: float | Duration = 0.0,
        return_debug_tuple: bool = False,
    ) -> bool | tuple[bool, str]:
        """Tell whether :meth:`lookup_transform` would succeed; never raises for frame problems.

        Args:
            target_frame: the frame to transform into.
            source_frame: the frame to transform from.
            time_ns: as in :meth:`lookup_transform`.
            timeout: wall-clock seconds to wait for the transform (0: answer now).
            return_debug_tuple: return ``(ok, reason)`` (reason is "" when ok), as rclpy.

        Returns:
            ``ok``, or ``(ok, reason)``.

        Raises:
            InvalidArgumentException: a malformed time or timeout.
        """
        t = to_ns(time_ns, "time")
        if timeout:
            ok, reason = self._wait(target_frame, source_frame, t, timeout_s(timeout))
        else:
            with self._lock:
                ok, reason = self._check(target_frame, source_frame, t)
        return (ok, reason) if return_debug_tuple else ok

    @overload
    def can_transform_full(
        self,
        target_frame: str,
        target_time: TimeLike,
        source_frame: str,
        source_time: TimeLike,
        fixed_frame: str,
        *,
        timeout: float | Duration = 0.0,
        return_debug_tuple: Literal[False] = False,
    ) -> bool: ...

    @overload
    def can_transform_full(
        self,
        target_frame: str,
        target_time: TimeLike,
        source_frame: str,
        source_time: TimeLike,
        fixed_frame: str,
        *,
        timeout: float | Duration = 0.0,
        return_debug_tuple: Literal[True],
    ) -> tuple[bool, str]: ...

    def can_transform_full(
        self,
        target_frame: str,
        target_time: TimeLike,
        source_frame: str,
        source_time: TimeLike,
        fixed_frame: str,
        *,
        timeout: float | Duration = 0.0,
        return_debug_tuple: bool = False,
    ) -> bool | tuple[bool, str]:
        """Tell whether :meth:`lookup_transform_full` would succeed (arguments as there)."""
        tt = to_ns(target_time, "target_time")
        ts = to_ns(source_time, "source_time")
        if timeout:
            ok, reason = self._wait_full(
                target_frame, tt, source_frame, ts, fixed_frame, timeout_s(timeout)
            )
        else:
            with self._lock:
                ok, reason = self._check_full(target_frame, tt, source_frame, ts, fixed_frame)
        return (ok, reason) if return_debug_tuple else ok

    def _check(self, target: str, source: str, t: int) -> tuple[bool, str]:
        return self._probe(lambda: self._lookup(target, source, t))

    def _check_full(
        self, target: str, tt: int, source: str, ts: int, fixed: str
    ) -> tuple[bool, str]:
        return self._probe(lambda: self._lookup_full(target, tt, source, ts, fixed))

    @staticmethod
    def _probe(lookup: Callable[[], object]) -> tuple[bool, str]:
        try:
            lookup()
        except TransformException as exc:
            return False, str(exc)
        return True, ""

    def _wait(self, target: str, source: str, t: int, timeout_s: float) -> tuple[bool, str]:
        return self._wait_for(lambda: self._lookup(target, source, t), timeout_s)

    def _wait_full(
        self, target: str, tt: int, source: str, ts: int, fixed: str, timeout_s: float
    ) -> tuple[bool, str]:
        return self._wait_for(lambda: self._lookup_full(target, tt, source, ts, fixed), timeout_s)

    def _wait_for(self, lookup: Callable[[], object], timeout_s: float) -> tuple[bool, str]:
        """Retry ``lookup`` on every insertion until it succeeds or ``timeout_s`` passes.

        A malformed argument (InvalidArgumentException) cannot be cured by new data:
        it is answered at once instead of after the whole timeout.
        """
        deadline = _time.monotonic() + timeout_s
        with self._cond:
            while True:
                try:
                    lookup()
                except InvalidArgumentException as exc:
                    return False, str(exc)
                except TransformException as exc:
                    remaining = deadline - _time.monotonic()
                    if remaining <= 0.0:
                        return False, str(exc)
                    self._waiters += 1  # set_transform notifies only while someone waits
                    try:
                        self._cond.wait(remaining)
                    finally:
                        self._waiters -= 1
                else:
                    return True, ""
