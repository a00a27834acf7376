"""``Cache``: the last ``cache_size`` messages of an input, queryable by stamp."""

from __future__ import annotations

import bisect
import threading
from collections.abc import Callable
from typing import Any

from visnav.message_filters._common import (
    BackJumpDetector,
    FilterLike,
    LoggerLike,
    default_logger,
    message_stamp_ns,
    resolve_clock,
    to_ns,
)
from visnav.message_filters.errors import MessageFilterError
from visnav.message_filters.simple_filter import SimpleFilter
from visnav.msgs.types import Time

__all__ = ["Cache"]


class Cache(SimpleFilter):
    """Stores a time history of messages and answers queries by stamp.

    Keeps the ``cache_size`` messages with the latest stamps, sorted by
    ``header.stamp`` (as roscpp's ``Cache``; rospy's appends in arrival order,
    which differs only when stamps arrive out of order). Every message added is
    passed on to the registered callbacks. Times are integer nanoseconds;
    queries also accept a ``builtin_interfaces/Time``.

    Args:
        f: the input filter (a :class:`~visnav.message_filters.Subscriber` ...),
            or None to feed the cache with :meth:`add`.
        cache_size: how many messages to keep (>= 1).
        allow_headerless: store messages without ``header.stamp`` under the
            current time of ``clock`` instead of dropping them with a warning.
        clock: int nanoseconds ROS time: stamps headerless messages, and when it
            goes backwards (a bag loop, a simulator reset) the cache is emptied
            before the new message is stored, as tf2_ros and rospy's synchronizers
            do with their buffers (rospy's Cache keeps old messages). Default: the
            input Subscriber's node clock, else wall-clock ``time.time_ns``.
        logger: where warnings go (default the ``visnav.message_filters`` logger).

    Raises:
        MessageFilterError: ``cache_size`` is not an int >= 1.
    """

    def __init__(
        self,
        f: FilterLike | None,
        cache_size: int = 1,
        allow_headerless: bool = False,
        *,
        clock: Callable[[], int] | None = None,
        logger: LoggerLike | None = None,
    ) -> None:
        super().__init__()
        if isinstance(cache_size, bool) or not isinstance(cache_size, int) or cache_size < 1:
            text = f"cache_size is {cache_size!r}: expected an int >= 1 (messages to keep)"
            raise MessageFilterError(text)
        self.cache_size = cache_size
        self.allow_headerless = allow_headerless
        self._clock = resolve_clock(clock, [f] if f is not None else [])
        self._jump = BackJumpDetector(self._clock)
        self._logger: LoggerLike = logger if logger is not None else default_logger()
        self._lock = threading.Lock()
        self._times: list[int] = []
        self._msgs: list[Any] = []
        self.incoming_connection: int | None = None
        if f is not None:
            self.connect_input(f)

    def connect_input(self, f: FilterLike) -> None:
        """Take input from filter ``f`` (its output messages are added to the cache)."""
        self.incoming_connection = f.register_callback(self.add)

    def add(self, msg: Any) -> None:
        """Store ``msg`` (dropping the oldest beyond ``cache_size``) and signal it.

        A message without ``header.stamp`` is dropped with a warning unless
        ``allow_headerless`` is set.
        """
        stamp = message_stamp_ns(msg)
        if stamp is None:
            if not self.allow_headerless:
                self._logger.warning(
                    f"Cache: dropped a {type(msg).__name__} without header.stamp; pass "
                    "allow_headerless=True to store headerless messages at the current time"
                )
                return
            stamp = int(self._clock())
        with self._lock:
            back = self._jump.jumped_back()
            if back:
                self._logger.info(
                    f"Cache: Detected jump back in time of {back / 1e9:.3f} s. Clearing "
                    f"{len(self._times)} cached messages."
                )
                self._times.clear()
                self._msgs.clear()
            if len(self._times) >= self.cache_size:
                del self._times[0]
                del self._msgs[0]
            index = bisect.bisect_right(self._times, stamp)
            self._times.insert(index, stamp)
            self._msgs.insert(index, msg)
        self.signal_message(msg)

    def get_interval(self, from_stamp: int | Time, to_stamp: int | Time) -> list[Any]:
        """Return the cached messages with ``from_stamp <= stamp <= to_stamp``, oldest first.

        Raises:
            MessageFilterError: ``from_stamp`` is after ``to_stamp``, or a time is malformed.
        """
        start, end = to_ns(from_stamp, "from_stamp"), to_ns(to_stamp, "to_stamp")
        if start > end:
            text = (
                f"get_interval: from_stamp {start} ns is after to_stamp {end} ns: "
                "expected from_stamp <= to_stamp"
            )
            raise MessageFilterError(text)
        with self._lock:
            lo = bisect.bisect_left(self._times, start)
            hi = bisect.bisect_right(self._times, end)
            return self._msgs[lo:hi]

    def get_surrounding_interval(self, from_stamp: int | Time, to_stamp: int | Time) -> list[Any]:
        """Return the interval plus the newest message before it and the oldest after it.

        As roscpp's ``getSurroundingInterval``: the smallest run of cached messages
        covering [from_stamp, to_stamp] (extending to the nearest message at or before
        ``from_stamp`` and at or after ``to_stamp`` when there is one).

        Raises:
            MessageFilterError: ``from_stamp`` is after ``to_stamp``, or a time is malformed.
        """
        start, end = to_ns(from_stamp, "from_stamp"), to_ns(to_stamp, "to_stamp")
        if start > end:
            text = (
                f"get_surrounding_interval: from_stamp {start} ns is after to_stamp {end} ns: "
                "expected from_stamp <= to_stamp"
            )
            raise MessageFilterError(text)
        with self._lock:
            lo = max(bisect.bisect_right(self._times, start) - 1, 0)
            hi = min(bisect.bisect_left(self._times, end) + 1, len(self._times))
            return self._msgs[lo:hi]

    def get_elem_after_time(self, stamp: int | Time) -> Any | None:
        """Return the oldest message with stamp at or after ``stamp``, or None."""
        t = to_ns(stamp)
        with self._lock:
            i = bisect.bisect_left(self._times, t)
            return self._msgs[i] if i < len(self._msgs) else None

    def get_elem_before_time(self, stamp: int | Time) -> Any | None:
        """Return the newest message with stamp at or before ``stamp``, or None."""
        t = to_ns(stamp)
        with self._lock:
            i = bisect.bisect_right(self._times, t)
            return self._msgs[i - 1] if i > 0 else None

    def get_latest_time(self) -> int | None:
        """Return the newest cached stamp in nanoseconds, or None when empty."""
        with self._lock:
            return self._times[-1] if self._times else None

    def get_oldest_time(self) -> int | None:
        """Return the oldest cached stamp in nanoseconds, or None when empty."""
        with self._lock:
            return self._times[0] if self._times else None

    def get_last(self) -> Any | None:
        """Return the message with the newest stamp, or None when empty."""
        with self._lock:
            return self._msgs[-1] if self._msgs else None

    def __len__(self) -> int:
        return len(self._msgs)
