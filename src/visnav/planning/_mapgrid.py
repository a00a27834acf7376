"""numba breadth-first distances on the local costmap (base_local_planner's ``MapGrid``).

Distances are 4-connected steps (cells) from a set of target cells; cells whose cost
is LETHAL, INSCRIBED or NO_INFORMATION are obstacles (they get ``obstacle`` and do not
propagate, as ``MapGrid::updatePathCell``); cells never reached get ``unreachable``.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["grid_distances"]


@njit(cache=True)
def grid_distances(
    costs: NDArray[np.uint8],
    targets: NDArray[np.int64],
    obstacle: int,
    unreachable: int,
) -> NDArray[np.int32]:  # pragma: no cover - compiled
    """Steps from the nearest target (``targets`` (K, 2) cells ``(x, y)`` inside the grid)."""
    h, w = costs.shape
    dist = np.full((h, w), unreachable, np.int32)
    queue = np.empty(h * w, np.int64)
    head = 0
    tail = 0
    for k in range(targets.shape[0]):
        x = targets[k, 0]
        y = targets[k, 1]
        if dist[y, x] != 0:
            dist[y, x] = 0
            queue[tail] = y * w + x
            tail += 1
    dxs = (1, -1, 0, 0)
    dys = (0, 0, 1, -1)
    while head < tail:
        idx = queue[head]
        head += 1
        cy = idx // w
        cx = idx - cy * w
        nd = dist[cy, cx] + 1
        for k in range(4):
            nx = cx + dxs[k]
            ny = cy + dys[k]
            if nx < 0 or ny < 0 or nx >= w or ny >= h:
                continue
            if dist[ny, nx] <= nd and dist[ny, nx] != obstacle:
                continue
            c = costs[ny, nx]
            if c >= 253:
                dist[ny, nx] = obstacle
                continue
            if dist[ny, nx] > nd:
                dist[ny, nx] = nd
                queue[tail] = ny * w + nx
                tail += 1
    return dist
