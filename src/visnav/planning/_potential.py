"""numba kernels of the global planner: potential propagation and path extraction.

Grids are (H, W) and indexed ``[y, x]``; cell ``(x, y)`` has its centre at the
continuous cell coordinate ``(x, y)``. Weights are the cost of crossing one cell
(``inf`` = blocked).

* :func:`propagate` runs Dijkstra (or A*) from the start cell with a bucket queue
  (Dial's algorithm on keys quantised to 1/64 of the smallest weight: every edge costs
  more than a quantum, so graph potentials stay exact; the order inside one bucket is
  arbitrary).
  ``quadratic`` uses the 4-neighbour eikonal update (the potential of a wave front:
  ``(a + b + sqrt(2 h^2 - (a - b)^2)) / 2`` when ``|a - b| < h``, else ``min(a, b) + h``),
  which global_planner approximates with a polynomial; otherwise the potential is the
  exact shortest-path cost on the 8-connected grid graph whose edge into cell ``m``
  costs ``weight[m]`` times the step length (1 or sqrt(2)), diagonals not cutting
  blocked corners.
* :func:`grid_path` walks from the goal to the start over 8-neighbours (the graph
  predecessor for graph potentials, the lowest neighbour for eikonal ones).
* :func:`gradient_path` descends the interpolated potential gradient in half-cell
  steps (navfn's path), taking grid steps where the potential is not finite around
  the current point.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["gradient_path", "grid_path", "propagate"]

_SQRT2 = math.sqrt(2.0)


@njit(cache=True)
def _eikonal(pot: NDArray[np.float32], w: int, h: int, x: int, y: int, cost: float) -> float:
    inf = np.inf
    a = inf
    b = inf
    if x > 0:
        a = pot[y, x - 1]
    if x < w - 1 and pot[y, x + 1] < a:
        a = pot[y, x + 1]
    if y > 0:
        b = pot[y - 1, x]
    if y < h - 1 and pot[y + 1, x] < b:
        b = pot[y + 1, x]
    if a > b:
        a, b = b, a
    if b - a >= cost:
        return a + cost
    return 0.5 * (a + b + math.sqrt(2.0 * cost * cost - (b - a) * (b - a)))


@njit(cache=True)
def propagate(
    weights: NDArray[np.float32],
    sx: int,
    sy: int,
    gx: int,
    gy: int,
    quadratic: bool,
    astar: bool,
    stop_at_goal: bool,
    heuristic_scale: float,
    min_weight: float,
) -> tuple[NDArray[np.float32], int]:  # pragma: no cover - compiled
    """Potential of every reached cell from the start ``(sx, sy)``; ``(potential, expanded)``.

    Stops when the goal ``(gx, gy)`` is expanded if ``stop_at_goal``. A* orders the
    queue by potential + ``heuristic_scale`` * Euclidean distance to the goal.
    ``min_weight`` is the smallest finite weight (sets the key quantum).
    """
    h, w = weights.shape
    pot = np.full((h, w), np.inf, np.float32)
    done = np.zeros((h, w), np.bool_)
    n_dirs = 4 if quadratic else 8
    # bucket queue (Dial): keys quantised to 1/64 of the smallest weight, circular over
    # the largest possible key increment of one relaxation
    qscale = 64.0 / min_weight
    max_w = min_weight
    for yy in range(h):
        for xx in range(w):
            c = weights[yy, xx]
            if c < np.inf and c > max_w:
                max_w = c
    n_buckets = int(_SQRT2 * (max_w + heuristic_scale) * qscale) + 4
    head = np.full(n_buckets, -1, np.int64)
    cap = n_dirs * h * w + 1
    nxt = np.empty(cap, np.int64)
    item = np.empty(cap, np.int64)
    used = 0
    size = 0
    pot[sy, sx] = 0.0
    prio = 0.0
    if astar:
        prio = heuristic_scale * math.hypot(sx - gx, sy - gy)
    cur = int(prio * qscale)
    b = cur % n_buckets
    item[used] = sy * w + sx
    nxt[used] = head[b]
    head[b] = used
    used += 1
    size += 1
    expanded = 0
    dxs = (1, -1, 0, 0, 1, 1, -1, -1)
    dys = (0, 0, 1, -1, 1, -1, 1, -1)
    while size > 0:
        b = cur % n_buckets
        while head[b] < 0:
            cur += 1
            b = cur % n_buckets
        e = head[b]
        head[b] = nxt[e]
        size -= 1
        idx = item[e]
        cy = idx // w
        cx = idx - cy * w
        if done[cy, cx]:
            continue
        done[cy, cx] = True
        expanded += 1
        if stop_at_goal and cx == gx and cy == gy:
            break
        base = pot[cy, cx]
        for k in range(n_dirs):
            nx = cx + dxs[k]
            ny = cy + dys[k]
            if nx < 0 or ny < 0 or nx >= w or ny >= h or done[ny, nx]:
                continue
            c = weights[ny, nx]
            if not c < np.inf:
                continue
            if quadratic:
                new = _eikonal(pot, w, h, nx, ny, c)
            elif k < 4:
                new = base + c
            else:
                if not (weights[cy, nx] < np.inf and weights[ny, cx] < np.inf):
                    continue
                new = base + _SQRT2 * c
            if new < pot[ny, nx]:
                pot[ny, nx] = new
                prio = new
                if astar:
                    prio = new + heuristic_scale * math.hypot(nx - gx, ny - gy)
                q = max(int(prio * qscale), cur)
                b = q % n_buckets
                item[used] = ny * w + nx
                nxt[used] = head[b]
                head[b] = used
                used += 1
                size += 1
    return pot, expanded


@njit(cache=True)
def grid_path(
    pot: NDArray[np.float32],
    weights: NDArray[np.float32],
    sx: int,
    sy: int,
    gx: int,
    gy: int,
    quadratic: bool,
) -> NDArray[np.float64]:  # pragma: no cover - compiled
    """Cells from the goal back to the start, (N, 2) ``(x, y)``; empty on failure."""
    h, w = pot.shape
    out = np.empty((h * w + 1, 2), np.float64)
    n = 0
    x = gx
    y = gy
    out[0, 0] = x
    out[0, 1] = y
    n = 1
    for _ in range(h * w):
        if x == sx and y == sy:
            return out[:n]
        best = np.inf
        bx = -1
        by = -1
        for dy in range(-1, 2):
            for dx in range(-1, 2):
                if dx == 0 and dy == 0:
                    continue
                nx = x + dx
                ny = y + dy
                if nx < 0 or ny < 0 or nx >= w or ny >= h:
                    continue
                p = pot[ny, nx]
                if not p < np.inf:
                    continue
                if quadratic:
                    score = p
                elif dx != 0 and dy != 0:
                    if not (weights[y, nx] < np.inf and weights[ny, x] < np.inf):
                        continue
                    score = p + _SQRT2 * weights[y, x]
                else:
                    score = p + weights[y, x]
                if score < best:
                    best = score
                    bx = nx
                    by = ny
        if bx < 0 or pot[by, bx] >= pot[y, x]:
            return out[:0]
        x = bx
        y = by
        out[n, 0] = x
        out[n, 1] = y
        n += 1
    return out[:0]


@njit(cache=True)
def _finite_block(pot: NDArray[np.float32], x0: int, y0: int) -> bool:
    h, w = pot.shape
    if x0 < 1 or y0 < 1 or x0 + 2 >= w or y0 + 2 >= h:
        return False
    for yy in range(y0 - 1, y0 + 3):
        for xx in range(x0 - 1, x0 + 3):
            if not pot[yy, xx] < np.inf:
                return False
    return True


@njit(cache=True)
def gradient_path(
    pot: NDArray[np.float32],
    sx: int,
    sy: int,
    gx: int,
    gy: int,
    step: float,
    max_iter: int,
) -> NDArray[np.float64]:  # pragma: no cover - compiled
    """Continuous cell coordinates from the goal down to the start; empty on failure."""
    h, w = pot.shape
    out = np.empty((max_iter + 2, 2), np.float64)
    px = float(gx)
    py = float(gy)
    out[0, 0] = px
    out[0, 1] = py
    n = 1
    for _ in range(max_iter):
        if abs(px - sx) <= 1.0 and abs(py - sy) <= 1.0:
            out[n, 0] = sx
            out[n, 1] = sy
            return out[: n + 1]
        ix = math.floor(px)
        iy = math.floor(py)
        moved = False
        if _finite_block(pot, ix, iy):
            fx = px - ix
            fy = py - iy
            gxs = 0.0
            gys = 0.0
            for cy in range(2):
                for cx in range(2):
                    wgt = (fx if cx else 1.0 - fx) * (fy if cy else 1.0 - fy)
                    xx = ix + cx
                    yy = iy + cy
                    gxs += wgt * 0.5 * (pot[yy, xx + 1] - pot[yy, xx - 1])
                    gys += wgt * 0.5 * (pot[yy + 1, xx] - pot[yy - 1, xx])
            norm = math.hypot(gxs, gys)
            if norm > 1e-9:
                px -= step * gxs / norm
                py -= step * gys / norm
                moved = True
        if not moved:
            cx = round(px)
            cy = round(py)
            cx = min(max(cx, 0), w - 1)
            cy = min(max(cy, 0), h - 1)
            best = pot[cy, cx]
            bx = -1
            by = -1
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    nx = cx + dx
                    ny = cy + dy
                    if (dx == 0 and dy == 0) or nx < 0 or ny < 0 or nx >= w or ny >= h:
                        continue
                    if pot[ny, nx] < best:
                        best = pot[ny, nx]
                        bx = nx
                        by = ny
            if bx < 0:
                return out[:0]
            px = float(bx)
            py = float(by)
        out[n, 0] = px
        out[n, 1] = py
        n += 1
    return out[:0]
