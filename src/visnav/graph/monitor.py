"""Topic statistics as ``ros2 topic hz | bw | delay`` compute them.

Each meter takes arrival events (times in integer nanoseconds) and reports over a
sliding window of the last ``window`` messages:

* :class:`RateMeter`: average rate = (n - 1) / (t_last - t_first), and the min,
  max and standard deviation of the periods (ros2 topic hz).
* :class:`BandwidthMeter`: bytes per second over the window and message sizes
  (ros2 topic bw).
* :class:`DelayMeter`: receive time minus ``header.stamp`` (ros2 topic delay).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections import deque

__all__ = ["BandwidthMeter", "BandwidthStats", "DelayMeter", "DelayStats", "RateMeter", "RateStats"]


@dataclasses.dataclass(frozen=True)
class RateStats:
    """Rate over a window: ``rate_hz`` and period statistics in seconds."""

    rate_hz: float
    min_s: float
    max_s: float
    std_s: float
    window: int

    def format(self) -> str:
        """Return ros2 topic hz's text."""
        return (
            f"average rate: {self.rate_hz:.3f}\n"
            f"\tmin: {self.min_s:.3f}s max: {self.max_s:.3f}s std dev: {self.std_s:.5f}s "
            f"window: {self.window}"
        )


class RateMeter:
    """Message rate from arrival times (a sliding window of ``window`` messages)."""

    def __init__(self, window: int = 10000) -> None:
        self._times: deque[int] = deque(maxlen=max(2, window))

    def add(self, t_ns: int) -> None:
        """Record one arrival; a time earlier than the last resets the window (clock jump)."""
        if self._times and t_ns < self._times[-1]:
            self._times.clear()
        self._times.append(t_ns)

    @property
    def count(self) -> int:
        """Arrivals in the window."""
        return len(self._times)

    def stats(self) -> RateStats | None:
        """Return the window's statistics, or None with fewer than two arrivals."""
        n = len(self._times)
        if n < 2:
            return None
        times = list(self._times)
        span = times[-1] - times[0]
        if span <= 0:
            return None
        periods = [(b - a) / 1e9 for a, b in itertools.pairwise(times)]
        mean = sum(periods) / len(periods)
        var = sum((p - mean) ** 2 for p in periods) / len(periods)
        return RateStats(
            rate_hz=(n - 1) / (span / 1e9),
            min_s=min(periods),
            max_s=max(periods),
            std_s=math.sqrt(var),
            window=n,
        )


def _human(nbytes: float) -> str:
    for unit, scale in (("MB", 1e6), ("KB", 1e3)):
        if nbytes >= scale:
            return f"{nbytes / scale:.2f} {unit}"
    return f"{nbytes:.0f} B"


@dataclasses.dataclass(frozen=True)
class BandwidthStats:
    """Bandwidth over a window."""

    bytes_per_s: float
    count: int
    mean_size: float
    min_size: int
    max_size: int

    def format(self) -> str:
        """Return ros2 topic bw's text."""
        return (
            f"{_human(self.bytes_per_s)}/s from {self.count} messages\n"
            f"\tMessage size mean: {_human(self.mean_size)} min: {_human(self.min_size)} "
            f"max: {_human(self.max_size)}"
        )


class BandwidthMeter:
    """Bytes per second from (arrival time, size) events."""

    def __init__(self, window: int = 100) -> None:
        self._events: deque[tuple[int, int]] = deque(maxlen=max(2, window))

    def add(self, t_ns: int, size: int) -> None:
        """Record one message of ``size`` bytes."""
        self._events.append((t_ns, size))

    def stats(self) -> BandwidthStats | None:
        """Return the window's statistics, or None with fewer than two messages."""
        if len(self._events) < 2:
            return None
        span = (self._events[-1][0] - self._events[0][0]) / 1e9
        if span <= 0:
            return None
        sizes = [s for _, s in self._events]
        return BandwidthStats(
            bytes_per_s=sum(sizes[1:]) / span,
            count=len(sizes),
            mean_size=sum(sizes) / len(sizes),
            min_size=min(sizes),
            max_size=max(sizes),
        )


@dataclasses.dataclass(frozen=True)
class DelayStats:
    """Delay between header stamps and arrival, in seconds."""

    mean_s: float
    min_s: float
    max_s: float
    std_s: float
    window: int

    def format(self) -> str:
        """Return ros2 topic delay's text."""
        return (
            f"average delay: {self.mean_s:.3f}\n"
            f"\tmin: {self.min_s:.3f}s max: {self.max_s:.3f}s std dev: {self.std_s:.5f}s "
            f"window: {self.window}"
        )


class DelayMeter:
    """Receive time minus the message's header stamp."""

    def __init__(self, window: int = 10000) -> None:
        self._delays: deque[float] = deque(maxlen=max(1, window))

    def add(self, receive_ns: int, stamp_ns: int) -> None:
        """Record one message."""
        self._delays.append((receive_ns - stamp_ns) / 1e9)

    def stats(self) -> DelayStats | None:
        """Return the window's statistics, or None with no message."""
        if not self._delays:
            return None
        d = list(self._delays)
        mean = sum(d) / len(d)
        var = sum((x - mean) ** 2 for x in d) / len(d)
        return DelayStats(mean, min(d), max(d), math.sqrt(var), len(d))
