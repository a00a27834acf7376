"""Timers: a callback every period of a clock (wall or sim time)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from visnav.graph.clock import Clock
from visnav.graph.errors import GraphError

if TYPE_CHECKING:
    from visnav.graph.node import Node

__all__ = ["Timer"]


class Timer:
    """Calls a callback every period of its clock (sim time when ``use_sim_time``).

    Missed periods are skipped, as rcl does: after a stall or a clock jump the
    timer fires once and keeps its phase.
    """

    def __init__(
        self, node: Node, period_ns: int, callback: Callable[[], Any], clock: Clock
    ) -> None:
        if period_ns <= 0:
            msg = f"timer period is {period_ns} ns: expected a positive period"
            raise GraphError(msg)
        self.node = node
        self.timer_period_ns = period_ns
        self.callback = callback
        self.clock = clock
        self.entity_id = node.context.next_id()
        self.next_call_ns = clock.now_ns() + period_ns
        self._canceled = False

    def is_ready(self) -> bool:
        """True when the timer is due."""
        if self._canceled:
            return False
        now = self.clock.now_ns()
        if now < self.next_call_ns - self.timer_period_ns:  # time jumped backwards
            self.next_call_ns = now + self.timer_period_ns
        return now >= self.next_call_ns

    def wall_wait_s(self) -> float | None:
        """Seconds until due for wall-clock timers; None for sim-time or canceled timers."""
        if self._canceled or self.clock.ros_time_is_active:
            return None
        return (self.next_call_ns - self.clock.now_ns()) / 1e9

    def prepare_call(self) -> Callable[[], None]:
        """Advance the deadline and return the callback to run."""
        now = self.clock.now_ns()
        nxt = self.next_call_ns + self.timer_period_ns
        if nxt <= now:
            missed = (now - nxt) // self.timer_period_ns + 1
            nxt += missed * self.timer_period_ns
        self.next_call_ns = nxt
        return self.callback

    def take_call(self) -> Callable[[], None] | None:
        """The callback to run now if the timer is due (deadline advanced), else None."""
        if not self.is_ready():
            return None
        return self.prepare_call()

    def pending(self) -> bool:
        """Always False: the executor polls timers for being due (:meth:`is_ready`)."""
        return False

    def describe(self) -> str:
        """``timer (every 0.5 s)`` (for logs)."""
        return f"timer (every {self.timer_period_ns / 1e9:g} s)"

    def time_until_next_call(self) -> int:
        """Nanoseconds until the next call (negative when overdue)."""
        return self.next_call_ns - self.clock.now_ns()

    def cancel(self) -> None:
        """Stop the timer."""
        self._canceled = True

    def is_canceled(self) -> bool:
        """Whether the timer is canceled."""
        return self._canceled

    def reset(self) -> None:
        """Restart: next call one period from now."""
        self._canceled = False
        self.next_call_ns = self.clock.now_ns() + self.timer_period_ns
        self.node.context.wake(timers=True)

    def destroy(self) -> None:
        """Remove the timer."""
        self.node.destroy_timer(self)
