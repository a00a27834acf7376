"""numba kernels of gmapping's maps: copy-on-write patch maps, hit registration, replay.

Cells live on one global grid: cell ``(gx, gy) = (floor(x / delta), floor(y / delta))``.
A particle's map is a table of patch ids ``tables[p, py, px]`` (``-1``: nothing seen
there) over a shared pool of ``PATCH x PATCH`` cell patches; the table's cell ``(0, 0)``
is global cell ``(cx0, cy0)``. A cell accumulates gmapping's ``PointAccumulator``: the
sum of the hit points (``accx``, ``accy``), the hit count ``hits`` and the ``visits``;
its value is ``hits / visits``, or ``-1`` when never visited. Particles share patches
after resampling (``refcount``); a write to a shared patch copies it first (gmapping's
``HierarchicalArray2D`` with reference-counted patches does the same).

Inputs shared by the functions: ``ranges`` (B,) float64 (inf: no return), ``angles`` (B,)
beam directions in the base frame, ``laser`` (3,) the laser's ``(x, y, yaw)`` in the base
frame, poses ``(x, y, theta)`` of the base in the map frame.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "FREE_RATIO",
    "FULLNESS",
    "PATCH",
    "PATCH_SHIFT",
    "cell",
    "count_new_patches",
    "hit_cell_bounds",
    "hit_points",
    "laser_origin",
    "register_hits",
    "replay_scans",
]

PATCH_SHIFT = 4
PATCH = 1 << PATCH_SHIFT
_MASK = PATCH - 1
FULLNESS = 0.1  # gmapping's fullnessThreshold
FREE_RATIO = math.sqrt(2.0)  # gmapping's freeCellRatio

F64 = NDArray[np.float64]
I32 = NDArray[np.int32]


@njit(cache=True, inline="always")
def cell(
    table: I32, accx: F64, accy: F64, hits: I32, visits: I32, ix: int, iy: int
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """(value, mean x, mean y) of table cell (ix, iy); value -1 when unknown or outside."""
    if ix < 0 or iy < 0:
        return -1.0, 0.0, 0.0
    px = ix >> PATCH_SHIFT
    py = iy >> PATCH_SHIFT
    if px >= table.shape[1] or py >= table.shape[0]:
        return -1.0, 0.0, 0.0
    pid = table[py, px]
    if pid < 0:
        return -1.0, 0.0, 0.0
    k = ((iy & _MASK) << PATCH_SHIFT) | (ix & _MASK)
    v = visits[pid, k]
    if v == 0:
        return -1.0, 0.0, 0.0
    n = hits[pid, k]
    if n == 0:
        return 0.0, 0.0, 0.0
    return n / v, accx[pid, k] / n, accy[pid, k] / n


@njit(cache=True, inline="always")
def laser_origin(pose: F64, laser: F64) -> tuple[float, float, float]:  # pragma: no cover
    c = math.cos(pose[2])
    s = math.sin(pose[2])
    return (
        pose[0] + c * laser[0] - s * laser[1],
        pose[1] + s * laser[0] + c * laser[1],
        pose[2] + laser[2],
    )


@njit(cache=True)
def hit_points(
    poses: F64, ranges: F64, angles: F64, laser: F64, limit: float
) -> F64:  # pragma: no cover - compiled
    """(P, B, 2) end points of each particle's beams; NaN for a beam beyond ``limit``, 0 or NaN."""
    out = np.full((poses.shape[0], ranges.shape[0], 2), np.nan)
    for p in range(poses.shape[0]):
        lx, ly, lt = laser_origin(poses[p], laser)
        for i in range(ranges.shape[0]):
            r = ranges[i]
            if not (r <= limit) or r == 0.0:
                continue
            out[p, i, 0] = lx + r * math.cos(lt + angles[i])
            out[p, i, 1] = ly + r * math.sin(lt + angles[i])
    return out


@njit(cache=True)
def hit_cell_bounds(
    poses: F64, points: F64, laser: F64, delta: float
) -> tuple[int, int, int, int, int]:  # pragma: no cover - compiled
    """Global cell bounds (min gx, min gy, max gx, max gy, count) of the lasers and end points.

    ``points``: :func:`hit_points` (NaN: not registered).
    """
    mnx = 1 << 40
    mny = 1 << 40
    mxx = -(1 << 40)
    mxy = -(1 << 40)
    n = 0
    inv = 1.0 / delta
    for p in range(poses.shape[0]):
        lx, ly, _ = laser_origin(poses[p], laser)
        gx0 = math.floor(lx * inv)
        gy0 = math.floor(ly * inv)
        mnx = min(mnx, gx0)
        mny = min(mny, gy0)
        mxx = max(mxx, gx0)
        mxy = max(mxy, gy0)
        for i in range(points.shape[1]):
            hx = points[p, i, 0]
            if math.isnan(hx):
                continue
            gx = math.floor(hx * inv)
            gy = math.floor(points[p, i, 1] * inv)
            mnx = min(mnx, gx)
            mny = min(mny, gy)
            mxx = max(mxx, gx)
            mxy = max(mxy, gy)
            n += 1
    return mnx, mny, mxx, mxy, n


@njit(cache=True)
def count_new_patches(
    tables: I32, refcount: I32, points: F64, delta: float, cx0: int, cy0: int
) -> int:  # pragma: no cover - compiled
    """An upper bound of the patches :func:`register_hits` will allocate for ``points``."""
    ph = tables.shape[1]
    pw = tables.shape[2]
    mark = np.full(ph * pw, -1, np.int64)
    inv = 1.0 / delta
    need = 0
    for p in range(points.shape[0]):
        for i in range(points.shape[1]):
            hx = points[p, i, 0]
            if math.isnan(hx):
                continue
            ix = math.floor(hx * inv) - cx0
            iy = math.floor(points[p, i, 1] * inv) - cy0
            k = (iy >> PATCH_SHIFT) * pw + (ix >> PATCH_SHIFT)
            if mark[k] == p:
                continue
            mark[k] = p
            pid = tables[p, iy >> PATCH_SHIFT, ix >> PATCH_SHIFT]
            if pid < 0 or refcount[pid] > 1:
                need += 1
    return need


@njit(cache=True)
def register_hits(
    tables: I32,
    accx: F64,
    accy: F64,
    hits: I32,
    visits: I32,
    refcount: I32,
    free: I32,
    free_top: NDArray[np.int64],
    points: F64,
    delta: float,
    cx0: int,
    cy0: int,
) -> None:  # pragma: no cover - compiled
    """gmapping's ``registerScan`` without map generation: add each end point as a hit.

    ``points``: :func:`hit_points` (NaN: skipped). Every end point must be inside the
    tables and ``free`` must hold enough patch ids (:func:`hit_cell_bounds`,
    :func:`count_new_patches`).
    """
    inv = 1.0 / delta
    nc = PATCH * PATCH
    for p in range(points.shape[0]):
        for i in range(points.shape[1]):
            hx = points[p, i, 0]
            if math.isnan(hx):
                continue
            hy = points[p, i, 1]
            ix = math.floor(hx * inv) - cx0
            iy = math.floor(hy * inv) - cy0
            py = iy >> PATCH_SHIFT
            px = ix >> PATCH_SHIFT
            pid = tables[p, py, px]
            if pid < 0 or refcount[pid] > 1:
                free_top[0] -= 1
                new = free[free_top[0]]
                if pid < 0:
                    for k in range(nc):
                        accx[new, k] = 0.0
                        accy[new, k] = 0.0
                        hits[new, k] = 0
                        visits[new, k] = 0
                else:
                    for k in range(nc):
                        accx[new, k] = accx[pid, k]
                        accy[new, k] = accy[pid, k]
                        hits[new, k] = hits[pid, k]
                        visits[new, k] = visits[pid, k]
                    refcount[pid] -= 1
                refcount[new] = 1
                tables[p, py, px] = new
                pid = new
            k = ((iy & _MASK) << PATCH_SHIFT) | (ix & _MASK)
            accx[pid, k] += hx
            accy[pid, k] += hy
            hits[pid, k] += 1
            visits[pid, k] += 1


@njit(cache=True)
def replay_scans(
    hits: I32,
    visits: I32,
    poses: F64,
    readings: F64,
    reading_ids: NDArray[np.int64],
    angles: F64,
    laser: F64,
    max_range: float,
    usable: float,
    delta: float,
    gx0: int,
    gy0: int,
) -> None:  # pragma: no cover - compiled
    """gmapping's ``registerScan`` with map generation, into one dense grid ``[y, x]``.

    Per beam: skipped beyond ``max_range``, zero or NaN; clipped to ``usable``; the cells
    of the Bresenham line from the laser to the endpoint, the endpoint excluded, are
    visited (free); a beam shorter than ``usable`` also hits its endpoint cell. Cells
    outside the grid (origin global cell ``(gx0, gy0)``) are skipped.
    """
    h, w = hits.shape
    inv = 1.0 / delta
    for j in range(poses.shape[0]):
        ranges = readings[reading_ids[j]]
        lx, ly, lt = laser_origin(poses[j], laser)
        x0 = math.floor(lx * inv) - gx0
        y0 = math.floor(ly * inv) - gy0
        for i in range(ranges.shape[0]):
            d = ranges[i]
            if not (d <= max_range) or d == 0.0:
                continue
            d = min(d, usable)
            x1 = math.floor((lx + d * math.cos(lt + angles[i])) * inv) - gx0
            y1 = math.floor((ly + d * math.sin(lt + angles[i])) * inv) - gy0
            dx = x1 - x0
            dy = y1 - y0
            adx = abs(dx)
            ady = abs(dy)
            sx = 1 if dx > 0 else -1
            sy = 1 if dy > 0 else -1
            x = x0
            y = y0
            steps = max(adx, ady)
            err = steps // 2
            for _ in range(steps):
                if 0 <= x < w and 0 <= y < h:
                    visits[y, x] += 1
                if adx >= ady:
                    x += sx
                    err += ady
                    if err >= adx:
                        y += sy
                        err -= adx
                else:
                    y += sy
                    err += adx
                    if err >= ady:
                        x += sx
                        err -= ady
            if d < usable and 0 <= x1 < w and 0 <= y1 < h:
                hits[y1, x1] += 1
                visits[y1, x1] += 1
