"""Which frontier to pursue: explore_lite's blacklist and progress timeout, without a graph.

:class:`GoalSelector` holds what explore_lite's ``Explore`` keeps between planning
cycles and decides, from the frontiers of one cycle (cheapest first):

* no frontier, or every one blacklisted -> :attr:`Decision.STOP`;
* the goal is the cheapest frontier not on the blacklist (its centroid); a goal is on
  the blacklist when it lies within 5 cells in x *and* in y of a blacklisted point;
* the same goal as last cycle (within 1 cm) -> :attr:`Decision.KEEP` (nothing is sent),
  unless no progress was made for ``progress_timeout``: progress is a new goal or a
  frontier whose closest cell came nearer than ever for this goal; then the goal is
  blacklisted and the next frontier chosen in the same cycle;
* otherwise -> :attr:`Decision.SEND` with the new goal.

A goal that move_base aborts is blacklisted through :meth:`GoalSelector.goal_aborted`.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from visnav.planning.explore.frontier_search import Frontier

__all__ = ["BLACKLIST_TOLERANCE_CELLS", "Decision", "GoalSelector", "Selection"]

BLACKLIST_TOLERANCE_CELLS = 5
"""A goal closer than this many cells (in x and in y) to a blacklisted point is skipped."""

_SAME_GOAL_M = 0.01


class Decision(enum.Enum):
    """What the explorer does after a planning cycle."""

    STOP = "stop"
    KEEP = "keep"
    SEND = "send"


@dataclass(frozen=True)
class Selection:
    """The outcome of :meth:`GoalSelector.select`.

    Attributes:
        decision: Stop, keep the running goal, or send ``goal``.
        goal: The frontier centroid pursued (None when stopping).
        frontier: The frontier of ``goal``.
        blacklisted: Goals blacklisted for lack of progress in this cycle.
        reason: Why exploring stops (for the log).
    """

    decision: Decision
    goal: tuple[float, float] | None = None
    frontier: Frontier | None = None
    blacklisted: tuple[tuple[float, float], ...] = ()
    reason: str = ""


@dataclass
class GoalSelector:
    """explore_lite's goal state: blacklist, previous goal, progress timer.

    Args:
        progress_timeout_ns: A goal without progress for longer is blacklisted.
    """

    progress_timeout_ns: int
    blacklist: list[tuple[float, float]] = field(default_factory=list)
    prev_goal: tuple[float, float] | None = None
    prev_distance: float = 0.0
    last_progress_ns: int = 0

    def on_blacklist(self, goal: tuple[float, float], resolution: float) -> bool:
        """Whether ``goal`` is within the tolerance of a blacklisted point."""
        tol = BLACKLIST_TOLERANCE_CELLS * resolution
        return any(abs(goal[0] - bx) < tol and abs(goal[1] - by) < tol for bx, by in self.blacklist)

    def goal_aborted(self, goal: tuple[float, float]) -> None:
        """move_base gave the goal up: never pursue it (or a point near it) again."""
        self.blacklist.append(goal)

    def select(self, frontiers: Sequence[Frontier], now_ns: int, resolution: float) -> Selection:
        """Decide this cycle's goal from ``frontiers`` (sorted cheapest first)."""
        dropped: list[tuple[float, float]] = []
        while True:
            if not frontiers:
                return Selection(Decision.STOP, blacklisted=tuple(dropped), reason="no frontiers")
            frontier = next(
                (f for f in frontiers if not self.on_blacklist(f.centroid, resolution)), None
            )
            if frontier is None:
                return Selection(
                    Decision.STOP,
                    blacklisted=tuple(dropped),
                    reason=f"all {len(frontiers)} frontiers are blacklisted",
                )
            target = frontier.centroid
            same = self.prev_goal is not None and (
                math.hypot(target[0] - self.prev_goal[0], target[1] - self.prev_goal[1])
                < _SAME_GOAL_M
            )
            self.prev_goal = target
            if not same or self.prev_distance > frontier.min_distance:
                self.last_progress_ns = now_ns
                self.prev_distance = frontier.min_distance
            if now_ns - self.last_progress_ns > self.progress_timeout_ns:
                self.blacklist.append(target)
                dropped.append(target)
                continue
            decision = Decision.KEEP if same else Decision.SEND
            return Selection(decision, target, frontier, tuple(dropped))
