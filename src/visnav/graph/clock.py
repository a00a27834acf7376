"""Clocks: system time, steady time, and ROS time that follows ``/clock`` under ``use_sim_time``.

Times are integer nanoseconds. :class:`TimePoint` mirrors ``rclpy.time.Time`` for
code written against rclpy (``now().nanoseconds``, ``now().to_msg()``).
"""

from __future__ import annotations

import dataclasses
import enum
import threading
import time

from visnav.msgs.time import NS_PER_S, ns_to_time
from visnav.msgs.types import Time

__all__ = ["Clock", "ClockType", "TimePoint"]


class ClockType(enum.Enum):
    """Which time a clock reports (rcl's clock types)."""

    ROS_TIME = "ros_time"
    SYSTEM_TIME = "system_time"
    STEADY_TIME = "steady_time"


@dataclasses.dataclass(frozen=True, order=True)
class TimePoint:
    """A point in time of a given clock type, in integer nanoseconds."""

    nanoseconds: int
    clock_type: ClockType = dataclasses.field(default=ClockType.ROS_TIME, compare=False)

    def to_msg(self) -> Time:
        """Return the time as a ``builtin_interfaces/Time`` message."""
        return ns_to_time(self.nanoseconds)

    def seconds_nanoseconds(self) -> tuple[int, int]:
        """Return ``(sec, nanosec)`` as rclpy does."""
        return divmod(self.nanoseconds, NS_PER_S)

    @property
    def seconds(self) -> float:
        """The time in float seconds."""
        return self.nanoseconds / NS_PER_S


class Clock:
    """A node's clock.

    A ROS_TIME clock reports system time until sim time is enabled; then it reports
    the last ``/clock`` value received (0 before the first one), as rclpy does.
    """

    def __init__(self, clock_type: ClockType = ClockType.ROS_TIME) -> None:
        self._type = clock_type
        self._sim_enabled = False
        self._sim_ns = 0
        self._lock = threading.Lock()
        self.sim_changes = 0
        """Counts sim time settings and switches (a cheap "has sim time moved?" for executors)."""

    @property
    def clock_type(self) -> ClockType:
        """The clock's type."""
        return self._type

    @property
    def ros_time_is_active(self) -> bool:
        """True when this ROS_TIME clock follows ``/clock``."""
        return self._sim_enabled

    def enable_sim_time(self, *, enabled: bool = True) -> None:
        """Make a ROS_TIME clock follow ``/clock`` (``use_sim_time``)."""
        if self._type is ClockType.ROS_TIME:
            self._sim_enabled = enabled
            self.sim_changes += 1

    def set_sim_time_ns(self, ns: int) -> None:
        """Set the sim time (called by the ``/clock`` subscription). Time may jump backwards."""
        with self._lock:
            self._sim_ns = int(ns)
            self.sim_changes += 1

    def now_ns(self) -> int:
        """Return the current time in integer nanoseconds."""
        if self._type is ClockType.STEADY_TIME:
            return time.monotonic_ns()
        if self._sim_enabled:
            return self._sim_ns
        return time.time_ns()

    def now(self) -> TimePoint:
        """Return the current time (rclpy's ``Clock.now()``)."""
        return TimePoint(self.now_ns(), self._type)
