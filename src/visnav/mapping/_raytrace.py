"""numba kernels for grid ray tracing (costmap_2d's ``raytraceLine`` / ``bresenham2D``).

A ray from cell ``(x0, y0)`` to ``(x1, y1)`` visits the cells of a Bresenham line,
both ends included; with a length limit of ``max_length`` cells the walk along the
dominant axis stops after ``int(min(1, max_length / hypot(dx, dy)) * |d_major|)``
steps and the cell reached there is the last one visited (costmap_2d's rule).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["raytrace_set", "trace_scan_cells"]


@njit(cache=True)
def _line_length(dx: int, dy: int, max_length: float) -> tuple[int, int, int]:
    adx = abs(dx)
    ady = abs(dy)
    dist = np.hypot(dx, dy)
    scale = 1.0 if dist == 0.0 else min(1.0, max_length / dist)
    major = max(adx, ady)
    return adx, ady, int(scale * major)


@njit(cache=True)
def raytrace_set(
    grid: NDArray[np.uint8],
    x0: int,
    y0: int,
    ends: NDArray[np.int64],
    max_length: float,
    value: int,
) -> None:  # pragma: no cover - compiled
    """Set every cell on the rays from ``(x0, y0)`` to each ``ends[i]`` to ``value``.

    Args:
        grid: (H, W) uint8 grid, indexed ``[y, x]``; every cell touched must be inside.
        x0: origin column.
        y0: origin row.
        ends: (N, 2) end cells ``(x, y)``, inside the grid.
        max_length: ray length limit in cells.
        value: the value to write.
    """
    for i in range(ends.shape[0]):
        dx = ends[i, 0] - x0
        dy = ends[i, 1] - y0
        adx, ady, length = _line_length(dx, dy, max_length)
        sx = 1 if dx > 0 else -1
        sy = 1 if dy > 0 else -1
        x = x0
        y = y0
        if adx >= ady:
            err = adx // 2
            n = min(length, adx)
            for _ in range(n):
                grid[y, x] = value
                x += sx
                err += ady
                if err >= adx:
                    y += sy
                    err -= adx
        else:
            err = ady // 2
            n = min(length, ady)
            for _ in range(n):
                grid[y, x] = value
                y += sy
                err += adx
                if err >= ady:
                    x += sx
                    err -= ady
        grid[y, x] = value


@njit(cache=True)
def trace_scan_cells(
    stamp: NDArray[np.int32],
    stamp_value: int,
    x0: int,
    y0: int,
    ends: NDArray[np.int64],
    hits: NDArray[np.bool_],
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:  # pragma: no cover - compiled
    """Cells a scan saw free and occupied, each once (flat indices).

    A ray's cells before its end are free; its end cell is occupied when ``hits[i]``
    and free otherwise. A cell is occupied when any ray ends there with a hit
    (occupied wins), else free. ``stamp`` (H, W) is scratch space: cells equal to
    ``stamp_value`` (free) or ``stamp_value + 1`` (occupied) were seen by this scan;
    pass a new even ``stamp_value`` per scan so it never needs clearing.
    """
    h, w = stamp.shape
    flat = stamp.reshape(-1)
    free = np.empty(64, np.int64)
    occ = np.empty(64, np.int64)
    nf = 0
    no = 0
    for i in range(ends.shape[0]):
        dx = ends[i, 0] - x0
        dy = ends[i, 1] - y0
        adx = abs(dx)
        ady = abs(dy)
        sx = 1 if dx > 0 else -1
        sy = 1 if dy > 0 else -1
        x = x0
        y = y0
        if adx >= ady:
            err = adx // 2
            steps = adx
        else:
            err = ady // 2
            steps = ady
        for _ in range(steps):
            if 0 <= x < w and 0 <= y < h:
                k = y * w + x
                if flat[k] != stamp_value and flat[k] != stamp_value + 1:
                    flat[k] = stamp_value
                    if nf == free.shape[0]:
                        grown = np.empty(2 * nf, np.int64)
                        grown[:nf] = free
                        free = grown
                    free[nf] = k
                    nf += 1
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
        if 0 <= x < w and 0 <= y < h:
            k = y * w + x
            if hits[i]:
                if flat[k] != stamp_value + 1:
                    flat[k] = stamp_value + 1
                    if no == occ.shape[0]:
                        grown = np.empty(2 * no, np.int64)
                        grown[:no] = occ
                        occ = grown
                    occ[no] = k
                    no += 1
            elif flat[k] != stamp_value and flat[k] != stamp_value + 1:
                flat[k] = stamp_value
                if nf == free.shape[0]:
                    grown = np.empty(2 * nf, np.int64)
                    grown[:nf] = free
                    free = grown
                free[nf] = k
                nf += 1
    return free[:nf], occ[:no]
