"""explore_lite's goal choice: blacklist tolerance, progress timeout, stop."""

from __future__ import annotations

import numpy as np

from visnav.planning.explore import Decision, Frontier, GoalSelector

S = 1_000_000_000
RES = 0.05


def _frontier(x: float, y: float, *, distance: float = 1.0, cost: float = -1.0) -> Frontier:
    return Frontier(
        size=10,
        min_distance=distance,
        cost=cost,
        initial=(x, y),
        centroid=(x, y),
        middle=(x, y),
        points=np.array([[x, y]]),
    )


def test_send_then_keep_then_new_goal() -> None:
    sel = GoalSelector(30 * S)
    a, b = _frontier(1.0, 0.0), _frontier(5.0, 0.0)
    first = sel.select([a, b], 0, RES)
    assert first.decision is Decision.SEND
    assert first.goal == (1.0, 0.0)
    again = sel.select([_frontier(1.005, 0.0), b], 1 * S, RES)  # within 1 cm: same goal
    assert again.decision is Decision.KEEP
    moved = sel.select([_frontier(1.5, 0.0), b], 2 * S, RES)
    assert moved.decision is Decision.SEND
    assert moved.goal == (1.5, 0.0)


def test_no_progress_for_progress_timeout_blacklists_and_picks_the_next() -> None:
    sel = GoalSelector(30 * S)
    a, b = _frontier(1.0, 0.0, distance=2.0), _frontier(5.0, 0.0)
    assert sel.select([a, b], 0, RES).decision is Decision.SEND
    # getting closer is progress: the timer restarts
    assert sel.select([_frontier(1.0, 0.0, distance=1.5), b], 20 * S, RES).decision is Decision.KEEP
    assert sel.select([_frontier(1.0, 0.0, distance=1.5), b], 49 * S, RES).decision is Decision.KEEP
    late = sel.select([_frontier(1.0, 0.0, distance=1.5), b], 51 * S, RES)
    assert late.decision is Decision.SEND
    assert late.goal == (5.0, 0.0)
    assert late.blacklisted == ((1.0, 0.0),)
    assert sel.on_blacklist((1.0, 0.0), RES)


def test_blacklist_tolerance_is_five_cells_in_x_and_y() -> None:
    sel = GoalSelector(30 * S)
    sel.goal_aborted((2.0, 3.0))
    assert sel.on_blacklist((2.0 + 4.9 * RES, 3.0 - 4.9 * RES), RES)
    assert not sel.on_blacklist((2.0 + 5.1 * RES, 3.0), RES)
    assert not sel.on_blacklist((2.0, 3.0 + 5.1 * RES), RES)
    near = _frontier(2.1, 3.1, cost=-5.0)  # 2 cells away: blacklisted
    far = _frontier(4.0, 3.0, cost=-1.0)
    choice = sel.select([near, far], 0, RES)
    assert choice.decision is Decision.SEND
    assert choice.goal == (4.0, 3.0)


def test_stop_when_none_or_all_blacklisted() -> None:
    sel = GoalSelector(30 * S)
    assert sel.select([], 0, RES).decision is Decision.STOP
    sel.goal_aborted((1.0, 1.0))
    stop = sel.select([_frontier(1.0, 1.0)], 0, RES)
    assert stop.decision is Decision.STOP
    assert "blacklisted" in stop.reason


def test_zero_timeout_blacklists_a_kept_goal_at_once() -> None:
    sel = GoalSelector(0)
    a = _frontier(1.0, 0.0)
    assert sel.select([a], 0, RES).decision is Decision.SEND
    assert sel.select([a], 1, RES).decision is Decision.STOP
