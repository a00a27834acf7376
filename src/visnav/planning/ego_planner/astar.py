"""ego-planner's A* (``path_searching/dyn_a_star.cpp``) on the inflated grid map, in numba.

The search runs on a cube of ``pool_size`` nodes spaced ``step_size`` apart and
centred midway between start and goal; a node is blocked when the map reports its
centre as inflated or outside the map. Moves go to the 26 neighbours at their
Euclidean length; the heuristic is the 3D diagonal distance times ``1 + 1e-4``
(ego-planner's tie breaker). A start or goal inside an obstacle is pushed away
from the other end, step by step, until it is free.

Differences from ego-planner: an improved node is pushed again (upstream changes
its key inside the heap, which breaks the heap order); the search stops after
``max_expansions`` nodes instead of 0.2 s of wall time, so results do not depend
on the machine's speed.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba
import numpy as np

from visnav.mapping._grid_kernels import inflate_at

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from visnav.mapping.grid_map import GridView

__all__ = ["AStar", "astar_kernel"]

_TIE_BREAKER = 1.0 + 1.0 / 10000.0
_SQRT2 = math.sqrt(2.0)
_SQRT3 = math.sqrt(3.0)


@numba.njit(cache=True)
def _diag(dx: int, dy: int, dz: int) -> float:
    dx, dy, dz = abs(dx), abs(dy), abs(dz)
    diag = min(dx, dy, dz)
    dx -= diag
    dy -= diag
    dz -= diag
    if dx == 0:
        return _SQRT3 * diag + _SQRT2 * min(dy, dz) + abs(dy - dz)
    if dy == 0:
        return _SQRT3 * diag + _SQRT2 * min(dx, dz) + abs(dx - dz)
    return _SQRT3 * diag + _SQRT2 * min(dx, dy) + abs(dx - dy)


@numba.njit(cache=True)
def _heap_push(
    keys: np.ndarray, vals: np.ndarray, size: int, key: float, val: int
) -> tuple[np.ndarray, np.ndarray, int]:
    if size == keys.shape[0]:
        nk = np.empty(2 * size)
        nv = np.empty(2 * size, np.int64)
        nk[:size] = keys
        nv[:size] = vals
        keys, vals = nk, nv
    i = size
    keys[i] = key
    vals[i] = val
    while i > 0:
        parent = (i - 1) // 2
        if keys[parent] <= keys[i]:
            break
        keys[parent], keys[i] = keys[i], keys[parent]
        vals[parent], vals[i] = vals[i], vals[parent]
        i = parent
    return keys, vals, size + 1


@numba.njit(cache=True)
def _heap_pop(keys: np.ndarray, vals: np.ndarray, size: int) -> tuple[int, int]:
    top = vals[0]
    size -= 1
    keys[0] = keys[size]
    vals[0] = vals[size]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        child = left
        if left + 1 < size and keys[left + 1] < keys[left]:
            child = left + 1
        if keys[i] <= keys[child]:
            break
        keys[child], keys[i] = keys[i], keys[child]
        vals[child], vals[i] = vals[i], vals[child]
        i = child
    return top, size


@numba.njit(cache=True)
def _to_index(pt: np.ndarray, center: np.ndarray, inv_step: float, pool: np.ndarray) -> np.ndarray:
    idx = np.empty(3, np.int64)
    for k in range(3):
        idx[k] = math.floor((pt[k] - center[k]) * inv_step + 0.5) + pool[k] // 2
    return idx


@numba.njit(cache=True)
def _inside(idx: np.ndarray, pool: np.ndarray) -> bool:
    return bool(0 <= idx[0] < pool[0] and 0 <= idx[1] < pool[1] and 0 <= idx[2] < pool[2])


@numba.njit(cache=True)
def _coord(
    ix: int, iy: int, iz: int, center: np.ndarray, step: float, pool: np.ndarray
) -> tuple[float, float, float]:
    return (
        (ix - pool[0] // 2) * step + center[0],
        (iy - pool[1] // 2) * step + center[1],
        (iz - pool[2] // 2) * step + center[2],
    )


@numba.njit(cache=True)
def _free_end(
    pt: np.ndarray,
    other: np.ndarray,
    center: np.ndarray,
    step: float,
    pool: np.ndarray,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
) -> np.ndarray:
    """Index of ``pt``'s node, pushed away from ``other`` until free; [-1, ...] when it leaves."""
    p = pt.copy()
    away = p - other
    norm = math.sqrt(away[0] ** 2 + away[1] ** 2 + away[2] ** 2)
    if norm > 0.0:
        away /= norm
    inv = 1.0 / step
    for _ in range(pool[0] + pool[1] + pool[2]):
        idx = _to_index(p, center, inv, pool)
        if not _inside(idx, pool):
            break
        c = _coord(idx[0], idx[1], idx[2], center, step, pool)
        if not inflate_at(c[0], c[1], c[2], inflate, origin, res, dims):
            return idx
        if norm == 0.0:
            break
        p += away * step
    out = np.empty(3, np.int64)
    out[:] = -1
    return out


@numba.njit(cache=True)
def astar_kernel(
    start: np.ndarray,
    goal: np.ndarray,
    step: float,
    pool: np.ndarray,
    g_score: np.ndarray,
    parent: np.ndarray,
    seen: np.ndarray,
    closed: np.ndarray,
    round_id: int,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
    max_expansions: int,
) -> np.ndarray:
    """A* from ``start`` to ``goal``; returns the ``(M, 3)`` node centres, empty on failure.

    ``g_score``, ``parent``, ``seen`` and ``closed`` are flat per-node scratch
    buffers reused across calls: a node counts as seen (or closed) in this search
    when its entry equals ``round_id``.
    """
    center = (start + goal) / 2.0
    s_idx = _free_end(start, goal, center, step, pool, inflate, origin, res, dims)
    e_idx = _free_end(goal, start, center, step, pool, inflate, origin, res, dims)
    if s_idx[0] < 0 or e_idx[0] < 0:
        return np.empty((0, 3))
    py, pz = pool[1], pool[2]
    s_node = (s_idx[0] * py + s_idx[1]) * pz + s_idx[2]
    e_node = (e_idx[0] * py + e_idx[1]) * pz + e_idx[2]
    keys = np.empty(4096)
    vals = np.empty(4096, np.int64)
    size = 0
    g_score[s_node] = 0.0
    parent[s_node] = -1
    seen[s_node] = round_id
    h0 = _TIE_BREAKER * _diag(s_idx[0] - e_idx[0], s_idx[1] - e_idx[1], s_idx[2] - e_idx[2])
    keys, vals, size = _heap_push(keys, vals, size, h0, s_node)
    expansions = 0
    found = False
    while size > 0:
        node, size = _heap_pop(keys, vals, size)
        if closed[node] == round_id:
            continue
        if node == e_node:
            found = True
            break
        closed[node] = round_id
        expansions += 1
        if expansions > max_expansions:
            break
        cx = node // (py * pz)
        cy = (node // pz) % py
        cz = node % pz
        for dx in range(-1, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    if dx == 0 and dy == 0 and dz == 0:
                        continue
                    nx, ny, nz = cx + dx, cy + dy, cz + dz
                    if (
                        nx < 1
                        or nx >= pool[0] - 1
                        or ny < 1
                        or ny >= pool[1] - 1
                        or nz < 1
                        or nz >= pool[2] - 1
                    ):
                        continue
                    nb = (nx * py + ny) * pz + nz
                    if closed[nb] == round_id:
                        continue
                    tentative = g_score[node] + math.sqrt(dx * dx + dy * dy + dz * dz)
                    if seen[nb] != round_id:
                        seen[nb] = round_id
                        c = _coord(nx, ny, nz, center, step, pool)
                        if inflate_at(c[0], c[1], c[2], inflate, origin, res, dims):
                            closed[nb] = round_id  # never open a blocked node
                            continue
                    elif tentative >= g_score[nb]:
                        continue
                    g_score[nb] = tentative
                    parent[nb] = node
                    f = tentative + _TIE_BREAKER * _diag(
                        nx - e_idx[0], ny - e_idx[1], nz - e_idx[2]
                    )
                    keys, vals, size = _heap_push(keys, vals, size, f, nb)
    if not found:
        return np.empty((0, 3))
    count = 1
    node = e_node
    while parent[node] >= 0:
        node = parent[node]
        count += 1
    path = np.empty((count, 3))
    node = e_node
    for i in range(count - 1, -1, -1):
        c = _coord(node // (py * pz), (node // pz) % py, node % pz, center, step, pool)
        path[i, 0], path[i, 1], path[i, 2] = c
        node = parent[node]
    return path


class AStar:
    """A* with reusable node buffers (ego-planner's ``AStar`` with ``initGridMap``).

    Args:
        pool_size: Nodes along x, y, z (ego-planner uses 100 each).
        max_expansions: Nodes expanded before the search gives up.

    Attributes:
        pool: Nodes along x, y, z.
        g_score: Per-node cost-to-come scratch buffer.
        parent: Per-node parent scratch buffer.
        seen: Per-node round in which the node was discovered.
        closed: Per-node round in which the node was closed.
        round_id: The current search round (advance it before each search).
        max_expansions: Nodes expanded before a search gives up.
    """

    def __init__(
        self, pool_size: tuple[int, int, int] = (100, 100, 100), *, max_expansions: int = 200_000
    ) -> None:
        self.pool = np.asarray(pool_size, dtype=np.int64)
        n = int(np.prod(self.pool))
        self.g_score = np.zeros(n)
        self.parent = np.zeros(n, dtype=np.int64)
        self.seen = np.zeros(n, dtype=np.int64)
        self.closed = np.zeros(n, dtype=np.int64)
        self.round_id = 0
        self.max_expansions = int(max_expansions)

    def search(
        self, view: GridView, start: ArrayLike, goal: ArrayLike, step_size: float = 0.1
    ) -> NDArray[np.float64]:
        """Search from ``start`` to ``goal`` on ``view``.

        Returns:
            ``(M, 3)`` node centres from start to goal; empty ``(0, 3)`` when none.
        """
        self.round_id += 1
        path: NDArray[np.float64] = astar_kernel(
            np.asarray(start, dtype=np.float64).reshape(3),
            np.asarray(goal, dtype=np.float64).reshape(3),
            float(step_size),
            self.pool,
            self.g_score,
            self.parent,
            self.seen,
            self.closed,
            self.round_id,
            view.inflate,
            view.origin,
            view.resolution,
            view.dims,
            self.max_expansions,
        )
        return path
