"""The ``{p, v}`` pairs of EGO-Planner: where a trajectory hits obstacles and which way is out.

For each stretch of the control polygon that crosses the inflated map, an A*
path is searched around the obstacle between the free control points on both
sides. Every control point of the stretch then gets a pair: ``v`` points from
the control point to where the plane through it, normal to the polygon's local
direction (``q_{j+1} - q_{j-1}``), cuts the A* path; ``p`` is the obstacle
surface along ``v`` (the last occupied sample, one resolution back towards
free space). Control points of the stretch without an intersection copy the
pair of their neighbour. The collision cost then pushes every control point at
least ``dist0`` along ``v`` beyond ``p``.

* :func:`init_control_points` segments an initial trajectory (ego-planner's
  ``initControlPoints``): the polygon is sampled finely and a stretch begins and
  ends where the occupancy changes, ignoring flips shorter than two samples.
* :func:`detect_new_obstacle` is the cheap test run inside the cost function
  once the trajectory is smooth: a control point that is occupied although every
  pair says it is clear means an obstacle the pairs do not know.
* :func:`rebound` (``check_collision_and_rebound``) adds pairs for such obstacles.

All run in numba with the A* buffers of :class:`~visnav.planning.ego_planner.astar.AStar`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from visnav.mapping._grid_kernels import inflate_at
from visnav.planning.ego_planner.astar import astar_kernel

__all__ = ["detect_new_obstacle", "init_control_points", "rebound"]

_ENOUGH_INTERVAL = 2
NO_NEW_OBSTACLE = 0
NEW_OBSTACLE = 1
TERMINAL_IN_OBSTACLE = 2
NO_WAY_AROUND = 3


@numba.njit(cache=True)
def _occ(
    p: np.ndarray, inflate: np.ndarray, origin: np.ndarray, res: float, dims: np.ndarray
) -> bool:
    return inflate_at(p[0], p[1], p[2], inflate, origin, res, dims)


@numba.njit(cache=True)
def _push_pair(
    j: int, p: np.ndarray, v: np.ndarray, base: np.ndarray, dirs: np.ndarray, counts: np.ndarray
) -> None:
    k = counts[j]
    if k >= base.shape[1]:
        return  # full: the oldest pairs keep acting
    base[j, k] = p
    dirs[j, k] = v
    counts[j] = k + 1


@numba.njit(cache=True)
def _copy_last_pair(
    dst: int, src: int, base: np.ndarray, dirs: np.ndarray, counts: np.ndarray
) -> None:
    if counts[src] > 0:
        _push_pair(
            dst,
            base[src, counts[src] - 1].copy(),
            dirs[src, counts[src] - 1].copy(),
            base,
            dirs,
            counts,
        )


@numba.njit(cache=True)
def _plane_cut(path: np.ndarray, point: np.ndarray, normal: np.ndarray) -> tuple[bool, np.ndarray]:
    """Where the plane through ``point`` with ``normal`` cuts the polyline ``path``.

    Walks from the middle of the path in the direction that reduces the signed
    distance, until its sign changes.
    """
    out = np.zeros(3)
    m = path.shape[0]
    if m < 2:
        return False, out
    idx = m // 2
    first = np.dot(path[idx] - point, normal)
    val = first
    while 0 <= idx < m:
        last = idx
        idx = idx - 1 if val >= 0.0 else idx + 1
        if idx < 0 or idx >= m:
            break
        val = np.dot(path[idx] - point, normal)
        if val * first <= 0.0 and (abs(val) > 0.0 or abs(first) > 0.0):
            seg = path[idx] - path[last]
            den = np.dot(normal, seg)
            if den == 0.0:
                return False, out
            out = path[idx] + seg * (np.dot(normal, point - path[idx]) / den)
            return True, out
    return False, out


@numba.njit(cache=True)
def _assign_pairs(
    q: np.ndarray,
    path: np.ndarray,
    first: int,
    second: int,
    base: np.ndarray,
    dirs: np.ndarray,
    counts: np.ndarray,
    flag: np.ndarray,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
    initial: bool,
) -> bool:
    """Give the control points ``first .. second`` pairs from the A* ``path``; True if any."""
    for j in range(first, second + 1):
        flag[j] = False
    got = -1
    for j in range(first + 1, second):
        normal = q[j + 1] - q[j - 1]
        found, cut = _plane_cut(path, q[j], normal)
        if not found:
            continue
        got = j
        flag[j] = True
        ray = cut - q[j]
        length = math.sqrt(np.dot(ray, ray))
        if length <= 1e-5:
            if not initial:
                got = -1
            continue
        a = length
        while a >= 0.0:
            probe = q[j] + (a / length) * ray
            occ = _occ(probe, inflate, origin, res, dims)
            if occ or a < res:
                if occ:
                    a += res
                _push_pair(j, q[j] + (a / length) * ray, ray / length, base, dirs, counts)
                break
            a -= res
    if initial and second - first == 1:
        # two control points only: the planes through them may miss the A* path
        normal = q[second] - q[first]
        middle = (q[second] + q[first]) / 2.0
        found, cut = _plane_cut(path, middle, normal)
        if found:
            ray = cut - middle
            length = math.sqrt(np.dot(ray, ray))
            if length > 0.01:
                flag[first] = True
                _push_pair(first, q[first].copy(), ray / length, base, dirs, counts)
                got = first
    if got < 0:
        return False
    for j in range(got + 1, second + 1):
        if not flag[j]:
            _copy_last_pair(j, j - 1, base, dirs, counts)
    for j in range(got - 1, first - 1, -1):
        if not flag[j]:
            _copy_last_pair(j, j + 1, base, dirs, counts)
    return True


@numba.njit(cache=True)
def _search_segments(
    q: np.ndarray,
    segments: np.ndarray,
    n_seg: int,
    pool: np.ndarray,
    g_score: np.ndarray,
    parent: np.ndarray,
    seen: np.ndarray,
    closed: np.ndarray,
    round_id: int,
    max_expansions: int,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
    drop_last_on_failure: bool,
) -> tuple[list[np.ndarray], int, int]:
    """A* around each segment; a failed one merges with the next (its goal may be boxed in)."""
    paths = [np.empty((0, 3))]
    paths.pop()
    i = 0
    while i < n_seg:
        round_id += 1
        path = astar_kernel(
            q[segments[i, 0]],
            q[segments[i, 1]],
            res,
            pool,
            g_score,
            parent,
            seen,
            closed,
            round_id,
            inflate,
            origin,
            res,
            dims,
            max_expansions,
        )
        if path.shape[0] > 0:
            paths.append(path)
            i += 1
        elif i < n_seg - 1:
            segments[i, 1] = segments[i + 1, 1]
            for k in range(i + 1, n_seg - 1):
                segments[k] = segments[k + 1]
            n_seg -= 1
        elif drop_last_on_failure:
            n_seg -= 1
        else:
            return paths, 0, round_id
    return paths, n_seg, round_id


@numba.njit(cache=True)
def init_control_points(
    q: np.ndarray,
    order: int,
    base: np.ndarray,
    dirs: np.ndarray,
    counts: np.ndarray,
    flag: np.ndarray,
    pool: np.ndarray,
    g_score: np.ndarray,
    parent: np.ndarray,
    seen: np.ndarray,
    closed: np.ndarray,
    round_id: int,
    max_expansions: int,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
) -> tuple[int, int]:
    """Find the colliding stretches of ``q`` and add their pairs (``initControlPoints``).

    Only the first two thirds of the polygon are checked, as upstream.

    Returns:
        ``(stretches that got pairs, updated A* round id)``.
    """
    n = q.shape[0]
    span = math.sqrt(np.dot(q[0] - q[n - 1], q[0] - q[n - 1])) / (n - 1)
    step = res / span / 1.5 if span > 0.0 else 1.0
    segments = np.empty((n, 2), np.int64)
    n_seg = 0
    same_times = _ENOUGH_INTERVAL + 1
    last_occ = False
    got_start = False
    got_end = False
    end_maybe = False
    in_id = 0
    out_id = 0
    i_end = n - order - (n - 2 * order) // 3
    for i in range(order, i_end + 1):
        a = 1.0
        while a > 0.0:
            occ = _occ(a * q[i - 1] + (1.0 - a) * q[i], inflate, origin, res, dims)
            if occ and not last_occ:
                if same_times > _ENOUGH_INTERVAL or i == order:
                    in_id = i - 1
                    got_start = True
                same_times = 0
                end_maybe = False
            elif not occ and last_occ:
                out_id = i
                end_maybe = True
                same_times = 0
            else:
                same_times += 1
            if end_maybe and (same_times > _ENOUGH_INTERVAL or i == n - order):
                end_maybe = False
                got_end = True
            last_occ = occ
            if got_start and got_end:
                got_start = False
                got_end = False
                segments[n_seg, 0] = in_id
                segments[n_seg, 1] = out_id
                n_seg += 1
            a -= step
    if n_seg == 0:
        return 0, round_id
    paths, n_seg, round_id = _search_segments(
        q,
        segments,
        n_seg,
        pool,
        g_score,
        parent,
        seen,
        closed,
        round_id,
        max_expansions,
        inflate,
        origin,
        res,
        dims,
        False,
    )
    used = 0
    for s in range(n_seg):
        if _assign_pairs(
            q,
            paths[s],
            segments[s, 0],
            segments[s, 1],
            base,
            dirs,
            counts,
            flag,
            inflate,
            origin,
            res,
            dims,
            True,
        ):
            used += 1
    return used, round_id


@numba.njit(cache=True)
def _new_obstacle_at(
    q: np.ndarray,
    i: int,
    base: np.ndarray,
    dirs: np.ndarray,
    counts: np.ndarray,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
) -> bool:
    if not _occ(q[i], inflate, origin, res, dims):
        return False
    for k in range(counts[i]):  # noqa: SIM110  (numba has no all() over generators)
        if np.dot(q[i] - base[i, k], dirs[i, k]) < res:
            return False  # a known pair still holds it: not a new obstacle
    return True


@numba.njit(cache=True)
def detect_new_obstacle(
    q: np.ndarray,
    order: int,
    base: np.ndarray,
    dirs: np.ndarray,
    counts: np.ndarray,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
) -> int:
    """0: no unknown obstacle; 1: one to rebound from; 2: the trajectory ends inside one."""
    n = q.shape[0]
    end_idx = n - order
    i_end = end_idx - (end_idx - order) // 3
    for i in range(order - 1, i_end + 1):
        if _new_obstacle_at(q, i, base, dirs, counts, inflate, origin, res, dims):
            for j in range(i + 1, n):
                if not _occ(q[j], inflate, origin, res, dims):
                    return NEW_OBSTACLE
            return TERMINAL_IN_OBSTACLE
    return NO_NEW_OBSTACLE


@numba.njit(cache=True)
def rebound(
    q: np.ndarray,
    order: int,
    base: np.ndarray,
    dirs: np.ndarray,
    counts: np.ndarray,
    flag: np.ndarray,
    pool: np.ndarray,
    g_score: np.ndarray,
    parent: np.ndarray,
    seen: np.ndarray,
    closed: np.ndarray,
    round_id: int,
    max_expansions: int,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
) -> tuple[int, int]:
    """Add pairs for obstacles the pairs do not know (``check_collision_and_rebound``).

    Returns:
        ``(status, updated A* round id)``: status 0 nothing new, 1 pairs added,
        2 the trajectory ends inside an obstacle, 3 no A* path around any of the new
        obstacles (both give up this plan; upstream would rebound again, up to 20
        times, and fail the same way).
    """
    n = q.shape[0]
    end_idx = n - order
    i_end = end_idx - (end_idx - order) // 3
    segments = np.empty((n, 2), np.int64)
    n_seg = 0
    i = order - 1
    while i <= i_end:
        if _new_obstacle_at(q, i, base, dirs, counts, inflate, origin, res, dims):
            in_id = 0
            for j in range(i - 1, -1, -1):
                if not _occ(q[j], inflate, origin, res, dims):
                    in_id = j
                    break
            out_id = -1
            for j in range(i + 1, n):
                if not _occ(q[j], inflate, origin, res, dims):
                    out_id = j
                    break
            if out_id < 0:
                return TERMINAL_IN_OBSTACLE, round_id
            segments[n_seg, 0] = in_id
            segments[n_seg, 1] = out_id
            n_seg += 1
            i = out_id + 1
        else:
            i += 1
    if n_seg == 0:
        return NO_NEW_OBSTACLE, round_id
    paths, n_seg, round_id = _search_segments(
        q,
        segments,
        n_seg,
        pool,
        g_score,
        parent,
        seen,
        closed,
        round_id,
        max_expansions,
        inflate,
        origin,
        res,
        dims,
        True,
    )
    for s in range(1, n_seg):  # avoid overlapping stretches
        if segments[s - 1, 1] >= segments[s, 0]:
            middle = (segments[s - 1, 1] + segments[s, 0]) / 2.0
            segments[s - 1, 1] = int(middle - 0.1)
            segments[s, 0] = int(middle + 1.1)
    added = False
    for s in range(n_seg):
        got = _assign_pairs(
            q,
            paths[s],
            segments[s, 0],
            segments[s, 1],
            base,
            dirs,
            counts,
            flag,
            inflate,
            origin,
            res,
            dims,
            False,
        )
        added = added or got
    return (NEW_OBSTACLE if added else NO_WAY_AROUND), round_id
