"""Which of a context's timers are due: a cheap check first, the full one when it may matter.

The executor asks before every callback and after each one (:mod:`visnav.graph.context`), so
in a lock-step simulation with a dozen timers and a dozen callbacks per physics step the
question is asked hundreds of times per simulated millisecond. :class:`TimerPoll` answers
"none is due" by reading each distinct clock once and comparing it with two thresholds kept
per clock:

* ``ready_at``: the earliest deadline (``next_call_ns``) of the clock's timers that are not
  canceled: none of them is due while the clock reads less;
* ``back_below``: the latest ``next_call_ns - period`` of those timers: a clock reading below
  it is a jump back in time, which :meth:`~visnav.graph.timer.Timer.is_ready` handles.

Between the two nothing can change, so the timers themselves are not asked; a clock that
follows ``/clock`` is not even read while its sim time was not set again
(:attr:`~visnav.graph.clock.Clock.sim_changes`). Otherwise every
timer is asked as before (:meth:`~visnav.graph.timer.Timer.is_ready`, with its side effects)
and the thresholds are computed again, leaving out the timers waiting in the executor's ready
ring (they are not asked until taken). Deadlines only move later on their own (a timer taken
to run); the thresholds are computed again whenever the set of timers changes, a timer leaves
the ring, or a timer is reset (:meth:`TimerPoll.invalidate`), so a stale threshold is never
later than the true one and the answer is the one the full check gives.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Set

    from visnav.graph.clock import Clock
    from visnav.graph.timer import Timer

__all__ = ["TimerPoll"]

_NEVER = 2**63  # later than any deadline
_EVER = -(2**63)  # earlier than any jump back


class TimerPoll:
    """A context's timers, with a fast "is any of them due?" (module docstring).

    Attributes:
        timers: the timers, in creation order (the context adds and removes them).
    """

    def __init__(self) -> None:
        self.timers: list[Timer] = []
        self._members: set[Timer] = set()
        # per clock: [clock, ready_at, back_below, sim_changes when it last held (-1: wall)]
        self._groups: list[list[Any]] | None = None

    def add(self, timer: Timer) -> None:
        """Watch ``timer`` too."""
        self.timers.append(timer)
        self._members.add(timer)
        self._groups = None

    def remove(self, timer: Timer) -> None:
        """Stop watching ``timer`` (no error when it is not watched)."""
        if timer in self._members:
            self._members.discard(timer)
            self.timers.remove(timer)
            self._groups = None

    def invalidate(self) -> None:
        """A timer's deadline or cancelation changed from outside: compute the thresholds again."""
        self._groups = None

    def taken(self, entity: Any) -> None:
        """The executor took ``entity`` from its ready ring (a timer's deadline moves)."""
        if entity in self._members:
            self._groups = None

    def wall_wait_s(self) -> float | None:
        """Seconds until the first wall-clock timer is due (>= 0), None without one."""
        waits = [w for t in self.timers if (w := t.wall_wait_s()) is not None]
        return max(0.0, min(waits)) if waits else None

    def due(self, queued: Set[Any]) -> list[Timer]:
        """The timers due now that are not in ``queued``, in deadline order (ties: creation).

        Args:
            queued: entities already in the executor's ready ring.
        """
        groups = self._groups
        if groups is not None:
            for group in groups:
                clock, ready_at, back_below, seen = group
                if seen >= 0:  # sim time: unchanged since the thresholds held
                    changes = clock.sim_changes
                    if changes == seen:
                        continue
                now = clock.now_ns()
                if now >= ready_at or now < back_below:
                    break
                if seen >= 0:
                    group[3] = changes
            else:
                return []
        # sim time settings counted before the timers are asked: one made meanwhile is seen
        changes = {id(t.clock): t.clock.sim_changes for t in self.timers}
        due = [t for t in self.timers if t not in queued and t.is_ready()]
        self._groups = self._thresholds(queued, due, changes)
        if len(due) > 1:
            due.sort(key=lambda t: (t.next_call_ns, t.entity_id))
        return due

    def _thresholds(
        self, queued: Set[Any], due: list[Timer], changes: dict[int, int]
    ) -> list[list[Any]]:
        """Per clock: the thresholds of its timers, leaving out those in (or joining) the ring."""
        by_clock: dict[int, list[Any]] = {}
        for t in self.timers:
            if t.is_canceled() or t in queued or t in due:
                continue
            group = by_clock.get(id(t.clock))
            if group is None:
                clock: Clock = t.clock
                seen = changes[id(clock)] if clock.ros_time_is_active else -1
                group = by_clock[id(clock)] = [clock, _NEVER, _EVER, seen]
            nxt = t.next_call_ns
            group[1] = min(group[1], nxt)
            group[2] = max(group[2], nxt - t.timer_period_ns)
        return list(by_clock.values())
