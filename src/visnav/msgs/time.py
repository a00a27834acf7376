"""``builtin_interfaces`` Time/Duration <-> integer nanoseconds.

Inside visnav times are integer nanoseconds; floats appear only at the edges
(user-facing seconds). These helpers convert at the message boundary.
"""

from __future__ import annotations

from visnav.msgs.errors import MessageError
from visnav.msgs.types import Duration, Time

__all__ = [
    "NS_PER_S",
    "duration_to_ns",
    "ns_to_duration",
    "ns_to_sec",
    "ns_to_time",
    "sec_to_ns",
    "time_to_ns",
]

NS_PER_S = 1_000_000_000
_UINT32_MAX = 2**32 - 1
_INT32_MIN = -(2**31)
_INT32_MAX = 2**31 - 1


def time_to_ns(stamp: Time) -> int:
    """Return a ``builtin_interfaces/Time`` as integer nanoseconds.

    Args:
        stamp: the time message.

    Returns:
        ``sec * 1e9 + nanosec`` as an int.

    Raises:
        MessageError: ``nanosec`` is not in [0, 1e9).
    """
    if not 0 <= stamp.nanosec < NS_PER_S:
        msg = f"Time.nanosec is {stamp.nanosec}: expected 0 <= nanosec < 1000000000"
        raise MessageError(msg)
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def ns_to_time(ns: int) -> Time:
    """Return integer nanoseconds as a ``builtin_interfaces/Time``.

    Args:
        ns: nanoseconds since the epoch (or since sim start); must fit Time's int32 seconds.

    Returns:
        The time message with ``0 <= nanosec < 1e9``.

    Raises:
        MessageError: the seconds do not fit an int32.
    """
    sec, nanosec = divmod(int(ns), NS_PER_S)
    if not _INT32_MIN <= sec <= _INT32_MAX:
        msg = f"time {ns} ns has sec={sec}, outside Time.sec's int32 range"
        raise MessageError(msg)
    return Time(sec=sec, nanosec=nanosec)


def duration_to_ns(duration: Duration) -> int:
    """Return a ``builtin_interfaces/Duration`` as integer nanoseconds."""
    if not 0 <= duration.nanosec < NS_PER_S:
        msg = f"Duration.nanosec is {duration.nanosec}: expected 0 <= nanosec < 1000000000"
        raise MessageError(msg)
    return int(duration.sec) * NS_PER_S + int(duration.nanosec)


def ns_to_duration(ns: int) -> Duration:
    """Return integer nanoseconds as a ``builtin_interfaces/Duration`` (nanosec normalised)."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    if not _INT32_MIN <= sec <= _INT32_MAX:
        msg = f"duration {ns} ns has sec={sec}, outside Duration.sec's int32 range"
        raise MessageError(msg)
    return Duration(sec=sec, nanosec=nanosec)


def sec_to_ns(seconds: float) -> int:
    """Return float seconds as integer nanoseconds (rounded to the nearest)."""
    return round(seconds * NS_PER_S)


def ns_to_sec(ns: int) -> float:
    """Return integer nanoseconds as float seconds."""
    return ns / NS_PER_S
