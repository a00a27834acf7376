"""Shared helpers of :mod:`visnav.message_filters`: stamps, loggers, input protocols."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from visnav.message_filters.errors import MessageFilterError
from visnav.msgs.time import NS_PER_S
from visnav.msgs.types import Time

__all__ = [
    "BackJumpDetector",
    "FilterLike",
    "LoggerLike",
    "StampedLike",
    "check_queue_size",
    "default_logger",
    "input_names",
    "message_stamp_ns",
    "resolve_clock",
    "rospy_duration_ns",
    "seconds_to_ns",
    "to_ns",
]

_LOGGER_NAME = "visnav.message_filters"


class LoggerLike(Protocol):
    """What the filters need from a logger (``logging.Logger`` and node loggers fit)."""

    def warning(self, msg: str, /) -> None:
        """Log a warning."""

    def info(self, msg: str, /) -> None:
        """Log an informational message."""

    def debug(self, msg: str, /) -> None:
        """Log a debug message."""


class FilterLike(Protocol):
    """An input of a filter: anything with ``register_callback`` (every SimpleFilter)."""

    def register_callback(self, cb: Callable[..., object], /, *args: Any) -> int:
        """Register ``cb``; it is called with the filter's output followed by ``args``."""


class _HeaderLike(Protocol):
    stamp: Time


class StampedLike(Protocol):
    """A message with ``header.stamp`` (``builtin_interfaces/Time``)."""

    header: _HeaderLike


def default_logger() -> logging.Logger:
    """Return the ``visnav.message_filters`` standard-library logger."""
    return logging.getLogger(_LOGGER_NAME)


def message_stamp_ns(msg: Any) -> int | None:
    """Return ``msg.header.stamp`` as integer nanoseconds, or None if there is none.

    Args:
        msg: any message.

    Returns:
        ``sec * 1e9 + nanosec``, or None when the message has no ``header.stamp``
        (or the stamp is not a Time with an in-range ``nanosec``).
    """
    header = getattr(msg, "header", None)
    stamp = getattr(header, "stamp", None)
    sec = getattr(stamp, "sec", None)
    nanosec = getattr(stamp, "nanosec", None)
    if not isinstance(sec, int) or not isinstance(nanosec, int) or not 0 <= nanosec < NS_PER_S:
        return None
    return sec * NS_PER_S + nanosec


def to_ns(stamp: int | Time, field: str = "stamp") -> int:
    """Return a query time (int nanoseconds or a ``Time`` message) as int nanoseconds.

    Raises:
        MessageFilterError: ``stamp`` is neither.
    """
    if isinstance(stamp, bool):
        pass
    elif isinstance(stamp, int):
        return stamp
    elif isinstance(stamp, Time) and 0 <= stamp.nanosec < NS_PER_S:
        return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)
    text = (
        f"{field} is {stamp!r}: expected integer nanoseconds or a builtin_interfaces/Time "
        "with 0 <= nanosec < 1e9"
    )
    raise MessageFilterError(text)


def seconds_to_ns(value: float, field: str, *, allow_zero: bool = True) -> int:
    """Return a non-negative duration in float seconds as int nanoseconds (rounded).

    Raises:
        MessageFilterError: negative, NaN, infinite or not a number.
    """
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if ok and value == value and abs(value) != float("inf"):  # noqa: PLR0124 - NaN test
        ns = round(float(value) * NS_PER_S)
        if ns > 0 or (allow_zero and ns == 0):
            return ns
    want = ">= 0" if allow_zero else "> 0"
    text = f"{field} is {value!r}: expected a finite duration in seconds {want}"
    raise MessageFilterError(text)


def rospy_duration_ns(seconds: float, field: str) -> int:
    """Return seconds as nanoseconds the way ``rospy.Duration.from_sec`` does (truncating).

    ROS 1's Python synchronizers convert ``slop`` with ``from_sec``, which keeps
    ``int(seconds)`` and truncates the fractional part to whole nanoseconds, so
    ``2.3`` s becomes 2,299,999,999 ns. Matching this keeps visnav's outputs equal
    to ROS 1's on stamps that sit exactly at the slop.

    Raises:
        MessageFilterError: negative, NaN, infinite or not a number.
    """
    seconds_to_ns(seconds, field)  # validation only
    secs = int(seconds)
    nsecs = int((float(seconds) - secs) * NS_PER_S)
    return secs * NS_PER_S + nsecs


def check_queue_size(queue_size: int) -> int:
    """Return ``queue_size`` if it is an int >= 1.

    Raises:
        MessageFilterError: otherwise.
    """
    if isinstance(queue_size, bool) or not isinstance(queue_size, int) or queue_size < 1:
        text = f"queue_size is {queue_size!r}: expected an int >= 1 (messages kept per input)"
        raise MessageFilterError(text)
    return queue_size


def input_names(fs: Sequence[object]) -> list[str]:
    """Return a name per input for log messages: its topic when it has one, else ``input i``."""
    names = []
    for i, f in enumerate(fs):
        topic = getattr(f, "topic", None)
        names.append(f"input {i} ({topic})" if isinstance(topic, str) else f"input {i}")
    return names


def resolve_clock(
    clock: Callable[[], int] | None, inputs: Sequence[object] = ()
) -> Callable[[], int]:
    """Return the "now" in int nanoseconds a filter uses (ROS time, as rospy's ``Time.now()``).

    ``clock`` when given; else the clock of the node of the first input that has one
    (a :class:`~visnav.message_filters.Subscriber` knows its node, whose clock follows
    ``/clock`` under ``use_sim_time``); else wall-clock ``time.time_ns``.
    """
    if clock is not None:
        return clock
    for f in inputs:
        get_clock = getattr(getattr(f, "node", None), "get_clock", None)
        if callable(get_clock):
            now_ns = getattr(get_clock(), "now_ns", None)
            if callable(now_ns):
                return now_ns  # type: ignore[no-any-return]
    return time.time_ns


class BackJumpDetector:
    """Tells when the clock went backwards since the previous call (a bag loop, a sim reset).

    Args:
        clock: int nanoseconds "now".
    """

    __slots__ = ("_clock", "_last")

    def __init__(self, clock: Callable[[], int]) -> None:
        self._clock = clock
        self._last: int | None = None

    def jumped_back(self) -> int:
        """Read the clock; return by how many ns it went back since the last call (0: not)."""
        now = int(self._clock())
        last = self._last
        self._last = now
        return last - now if last is not None and now < last else 0
