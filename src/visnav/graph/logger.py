"""A node's logger: rclpy's ``RcutilsLogger`` surface over :mod:`logging`, with its filters.

``node.get_logger().warning(text, once=True)`` logs the first time this call site is
reached and never again; ``throttle_duration_sec=5.0`` logs at most once per five seconds
per call site; ``skip_first=True`` drops the first time. Filters may be combined; they run
in rclpy's order (throttle, then skip_first, then once) and stop at the first that drops
the message, so later filters only see messages the earlier ones let through. Every
method returns True when the message was logged.

A call site is the line that calls the logger (function, file, bytecode offset), as in
rclpy: a helper that logs on behalf of many callers is one call site, so its messages
share one throttle. A call site keeps the level, filters and filter parameters of its
first call; changing them later raises :class:`~visnav.graph.errors.LoggerError`, as
rclpy raises ``ValueError``.

Where visnav differs from rclpy:

* The throttle's default time source is a steady (monotonic) clock, as rcutils' C
  macros use; rclpy's Python default is the system clock, which jumps when the wall clock
  is set. Pass ``throttle_time_source_type=node.get_clock()`` to throttle in ROS time
  (sim time under ``use_sim_time``).
* The first message of a throttled call site is always logged. rclpy compares against a
  "last logged" time of 0, so under sim time starting at 0 it drops messages for the
  first ``throttle_duration_sec``.
* Levels come from :mod:`logging` (``logging.getLogger("visnav.node.<ns>.<name>")``),
  not rcutils' severity tree; ``error`` takes ``exc_info`` to log a traceback.
"""

from __future__ import annotations

import logging
import math
import sys
import threading
from dataclasses import dataclass
from types import CodeType, FrameType

from visnav.graph.clock import Clock, ClockType
from visnav.graph.errors import LoggerError

__all__ = ["NodeLogger"]

_THIS_FILE = __file__


@dataclass
class _Site:
    """The filter state of one call site (rclpy's logging context)."""

    level: int
    throttle_ns: int | None
    clock: Clock | None
    skip_first: bool
    once: bool
    last_logged_ns: int | None = None
    first_skipped: bool = False
    logged_once: bool = False


def _caller() -> tuple[CodeType, int]:
    """The code object and bytecode offset of the first frame outside this module."""
    frame: FrameType | None = sys._getframe(1)
    while frame is not None and frame.f_code.co_filename == _THIS_FILE:
        frame = frame.f_back
    if frame is None:  # pragma: no cover - a logger is always called from somewhere
        msg = "NodeLogger: no caller frame outside visnav.graph.logger"
        raise LoggerError(msg)
    return frame.f_code, frame.f_lasti


class NodeLogger:
    """A node's logger (rclpy's ``RcutilsLogger`` surface over :mod:`logging`).

    Args:
        name: the node's fully qualified name, shown in brackets before every message.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self._log = logging.getLogger(f"visnav.node.{name.strip('/').replace('/', '.')}")
        self._sites: dict[tuple[CodeType, int], _Site] = {}
        self._lock = threading.Lock()
        self._steady = Clock(ClockType.STEADY_TIME)

    def is_enabled_for(self, level: int) -> bool:
        """True when a message at ``level`` (a :mod:`logging` level) would be logged."""
        return self._log.isEnabledFor(level)

    def log(
        self,
        message: str,
        level: int,
        *,
        throttle_duration_sec: float | None = None,
        throttle_time_source_type: Clock | None = None,
        skip_first: bool = False,
        once: bool = False,
        exc_info: BaseException | None = None,
    ) -> bool:
        """Log ``message`` at ``level`` (a :mod:`logging` level) through the filters.

        Args:
            message: the text.
            level: ``logging.DEBUG`` ... ``logging.CRITICAL``.
            throttle_duration_sec: log at most once per this many seconds from this call
                site (> 0).
            throttle_time_source_type: the clock of the throttle (default a steady clock).
            skip_first: drop the first message from this call site.
            once: log only the first message from this call site.
            exc_info: an exception whose traceback is logged with the message.

        Returns:
            True if the message was logged; False if the level is disabled or a filter
            dropped it (as rclpy).

        Raises:
            LoggerError: ``throttle_duration_sec`` is not a positive finite number, or this
                call site was first called with another level, filters or parameters.
        """
        if not self._log.isEnabledFor(level):
            return False
        if throttle_duration_sec is None and not skip_first and not once:
            if throttle_time_source_type is not None:
                msg = (
                    f"logger {self.name!r}: throttle_time_source_type given without "
                    "throttle_duration_sec; pass throttle_duration_sec=<seconds> too"
                )
                raise LoggerError(msg)
            self._log.log(level, "[%s] %s", self.name, message, exc_info=exc_info)
            return True
        throttle_ns = _throttle_ns(self.name, throttle_duration_sec)
        key = _caller()
        with self._lock:
            site = self._sites.get(key)
            if site is None:
                site = _Site(level, throttle_ns, throttle_time_source_type, skip_first, once)
                self._sites[key] = site
            elif (site.level, site.throttle_ns, site.clock, site.skip_first, site.once) != (
                level,
                throttle_ns,
                throttle_time_source_type,
                skip_first,
                once,
            ):
                code, _ = key
                msg = (
                    f"logger {self.name!r}: the call at {code.co_filename}:{code.co_name} "
                    "changed its level, filters or filter parameters since its first call; "
                    "a call site keeps them (as rclpy): use another call site for other ones"
                )
                raise LoggerError(msg)
            if not self._passes(site):
                return False
        self._log.log(level, "[%s] %s", self.name, message, exc_info=exc_info)
        return True

    def _passes(self, site: _Site) -> bool:
        if site.throttle_ns is not None:
            now = (site.clock or self._steady).now_ns()
            if site.last_logged_ns is not None and now < site.last_logged_ns + site.throttle_ns:
                return False
            site.last_logged_ns = now
        if site.skip_first and not site.first_skipped:
            site.first_skipped = True
            return False
        if site.once:
            if site.logged_once:
                return False
            site.logged_once = True
        return True

    def debug(
        self,
        message: str,
        *,
        throttle_duration_sec: float | None = None,
        throttle_time_source_type: Clock | None = None,
        skip_first: bool = False,
        once: bool = False,
    ) -> bool:
        """Log at debug level (filters as :meth:`log`)."""
        return self.log(
            message,
            logging.DEBUG,
            throttle_duration_sec=throttle_duration_sec,
            throttle_time_source_type=throttle_time_source_type,
            skip_first=skip_first,
            once=once,
        )

    def info(
        self,
        message: str,
        *,
        throttle_duration_sec: float | None = None,
        throttle_time_source_type: Clock | None = None,
        skip_first: bool = False,
        once: bool = False,
    ) -> bool:
        """Log at info level (filters as :meth:`log`)."""
        return self.log(
            message,
            logging.INFO,
            throttle_duration_sec=throttle_duration_sec,
            throttle_time_source_type=throttle_time_source_type,
            skip_first=skip_first,
            once=once,
        )

    def warning(
        self,
        message: str,
        *,
        throttle_duration_sec: float | None = None,
        throttle_time_source_type: Clock | None = None,
        skip_first: bool = False,
        once: bool = False,
    ) -> bool:
        """Log at warning level (filters as :meth:`log`)."""
        return self.log(
            message,
            logging.WARNING,
            throttle_duration_sec=throttle_duration_sec,
            throttle_time_source_type=throttle_time_source_type,
            skip_first=skip_first,
            once=once,
        )

    warn = warning

    def error(
        self,
        message: str,
        *,
        exc_info: BaseException | None = None,
        throttle_duration_sec: float | None = None,
        throttle_time_source_type: Clock | None = None,
        skip_first: bool = False,
        once: bool = False,
    ) -> bool:
        """Log at error level, with ``exc_info``'s traceback if given (filters: :meth:`log`)."""
        return self.log(
            message,
            logging.ERROR,
            throttle_duration_sec=throttle_duration_sec,
            throttle_time_source_type=throttle_time_source_type,
            skip_first=skip_first,
            once=once,
            exc_info=exc_info,
        )

    def fatal(
        self,
        message: str,
        *,
        throttle_duration_sec: float | None = None,
        throttle_time_source_type: Clock | None = None,
        skip_first: bool = False,
        once: bool = False,
    ) -> bool:
        """Log at critical level (filters as :meth:`log`)."""
        return self.log(
            message,
            logging.CRITICAL,
            throttle_duration_sec=throttle_duration_sec,
            throttle_time_source_type=throttle_time_source_type,
            skip_first=skip_first,
            once=once,
        )


def _throttle_ns(name: str, seconds: float | None) -> int | None:
    if seconds is None:
        return None
    value = float(seconds)
    if not (math.isfinite(value) and value > 0.0):
        msg = (
            f"logger {name!r}: throttle_duration_sec is {seconds!r}: expected a positive "
            "number of seconds (or leave it out to log every time)"
        )
        raise LoggerError(msg)
    return round(value * 1e9)
