"""Frontier search on a costmap, as explore_lite's ``FrontierSearch`` (m-explore, noetic).

The grid holds costmap_2d's cell costs (``uint8``: 0 free, 253 inscribed, 254 lethal,
255 unknown); :func:`occupancy_to_costs` turns a ``nav_msgs/OccupancyGrid``'s data into
them with explore_lite's table (-1 -> 255, 0 -> 0, 99 -> 253, 100 -> 254, 1..98 spread
linearly over 1..252).

:func:`search_frontiers` does what explore_lite's ``searchFrom`` does:

1. from the robot's cell, find the nearest cell of cost 0 (breadth first, 8-connected);
2. breadth first over the 4-connected neighbours, entering a cell whose cost is not
   higher than the current one's (from a free cell: free cells only);
3. a neighbour that is not entered and is a *frontier cell* (unknown, with a free
   4-neighbour, not yet in a frontier) starts a new frontier, grown over the
   8-connected frontier cells around it;
4. a frontier of ``size * resolution >= min_frontier_size`` is kept with its cost
   ``potential_scale * min_distance * resolution - gain_scale * size * resolution``
   (``min_distance``: metres from the centre of the robot's cell to the frontier's
   closest cell; explore_lite's formula, resolution factor on the distance included);
5. frontiers are returned cheapest first (a stable sort: equal costs keep search order).

Where visnav differs: a frontier's centroid and closest cell count every one of its
cells. explore_lite counts the first cell in ``size`` but leaves it out of the centroid
sum (so its centroid is pulled towards the map origin by ``1/size``) and out of
``min_distance``; here the centroid is the mean of the cells, which is the point the
goal is meant to be. A robot outside the grid raises :class:`FrontierSearchError`
(explore_lite returns no frontiers, which stops exploring).

The searches are compiled with numba (turtlebot3_world's 160 x 160 map: about 0.5 ms).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numba
import numpy as np

from visnav.planning.errors import PlanningError

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = [
    "FREE_SPACE",
    "INSCRIBED",
    "LETHAL",
    "NO_INFORMATION",
    "Frontier",
    "FrontierSearchError",
    "cost_translation_table",
    "frontier_cost",
    "occupancy_to_costs",
    "search_frontiers",
]

FREE_SPACE = 0
INSCRIBED = 253
LETHAL = 254
NO_INFORMATION = 255


class FrontierSearchError(PlanningError):
    """The frontier search cannot run (robot outside the grid, a malformed grid)."""


def cost_translation_table() -> NDArray[np.uint8]:
    """Occupancy value (as ``uint8``, so -1 is 255) -> costmap cost, explore_lite's table.

    Returns:
        A ``(256,)`` ``uint8`` array: 0 -> 0, 1..98 -> ``1 + 251 * (v - 1) // 97``,
        99 -> 253, 100 -> 254, 255 (-1) -> 255; values 101..254 (not valid occupancy)
        follow the linear formula modulo 256, as the C++ cast does.
    """
    v = np.arange(256, dtype=np.int64)
    table = (1 + (251 * (v - 1)) // 97) % 256
    table[0] = FREE_SPACE
    table[99] = INSCRIBED
    table[100] = LETHAL
    table[255] = NO_INFORMATION
    return table.astype(np.uint8)


_TABLE = cost_translation_table()


def occupancy_to_costs(data: NDArray[np.int8] | NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Translate ``OccupancyGrid.data`` values (-1, 0..100) into costmap costs.

    Args:
        data: Any shape of ``int8`` (or the same bytes as ``uint8``).

    Returns:
        ``uint8`` costs of the same shape.
    """
    return _TABLE[np.asarray(data).view(np.uint8)]


@dataclass(frozen=True)
class Frontier:
    """One frontier: 8-connected unknown cells that border free space.

    Attributes:
        size: Number of cells.
        min_distance: Metres from the robot's cell centre to the closest cell's centre.
        cost: ``potential_scale * min_distance * resolution - gain_scale * size * resolution``.
        initial: ``(x, y)`` of the cell where the search first met the frontier.
        centroid: ``(x, y)`` mean of the cells' centres: the exploration goal.
        middle: ``(x, y)`` of the cell closest to the robot.
        points: ``(size, 2)`` cell centres in the grid's frame, in search order.
    """

    size: int
    min_distance: float
    cost: float
    initial: tuple[float, float]
    centroid: tuple[float, float]
    middle: tuple[float, float]
    points: NDArray[np.float64] = field(repr=False, compare=False)


def frontier_cost(
    size: int,
    min_distance: float,
    resolution: float,
    *,
    potential_scale: float,
    gain_scale: float,
) -> float:
    """explore_lite's frontier cost (lower is better).

    Args:
        size: Cells in the frontier.
        min_distance: Metres from the robot to the frontier's closest cell.
        resolution: Metres per cell.
        potential_scale: Weight of the distance.
        gain_scale: Weight of the size.

    Returns:
        ``potential_scale * min_distance * resolution - gain_scale * size * resolution``.
    """
    return potential_scale * min_distance * resolution - gain_scale * size * resolution


@numba.njit(cache=True)
def _neighbours(
    idx: int, width: int, height: int, out: NDArray[np.int64], eight: bool
) -> int:  # pragma: no cover - compiled
    """Write the 4- (or 8-) neighbours of ``idx`` into ``out`` in costmap_tools' order."""
    x = idx % width
    n = 0
    left, right = x > 0, x < width - 1
    up, down = idx >= width, idx < width * (height - 1)
    if left:
        out[n] = idx - 1
        n += 1
    if right:
        out[n] = idx + 1
        n += 1
    if up:
        out[n] = idx - width
        n += 1
    if down:
        out[n] = idx + width
        n += 1
    if eight:
        if left and up:
            out[n] = idx - 1 - width
            n += 1
        if left and down:
            out[n] = idx - 1 + width
            n += 1
        if right and up:
            out[n] = idx + 1 - width
            n += 1
        if right and down:
            out[n] = idx + 1 + width
            n += 1
    return n


@numba.njit(cache=True)
def _nearest_cell(
    costs: NDArray[np.uint8], width: int, height: int, start: int, value: int
) -> int:  # pragma: no cover - compiled
    """Index of the nearest cell of cost ``value`` (8-connected BFS), or -1."""
    total = width * height
    visited = np.zeros(total, dtype=np.bool_)
    queue = np.empty(total, dtype=np.int64)
    nbrs = np.empty(8, dtype=np.int64)
    head, tail = 0, 1
    queue[0] = start
    visited[start] = True
    while head < tail:
        idx = queue[head]
        head += 1
        if costs[idx] == value:
            return int(idx)
        for k in range(_neighbours(idx, width, height, nbrs, True)):
            nbr = nbrs[k]
            if not visited[nbr]:
                visited[nbr] = True
                queue[tail] = nbr
                tail += 1
    return -1


@numba.njit(cache=True)
def _is_new_frontier_cell(
    costs: NDArray[np.uint8],
    width: int,
    height: int,
    idx: int,
    flag: NDArray[np.bool_],
    nbrs: NDArray[np.int64],
) -> bool:  # pragma: no cover - compiled
    if costs[idx] != 255 or flag[idx]:
        return False
    for k in range(_neighbours(idx, width, height, nbrs, False)):  # noqa: SIM110 - numba
        if costs[nbrs[k]] == 0:
            return True
    return False


@numba.njit(cache=True)
def _frontier_cells(
    costs: NDArray[np.uint8], width: int, height: int, start: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:  # pragma: no cover - compiled
    """Frontier cells in search order and the start offset of each frontier in them."""
    total = width * height
    visited = np.zeros(total, dtype=np.bool_)
    flag = np.zeros(total, dtype=np.bool_)
    queue = np.empty(total, dtype=np.int64)
    cells = np.empty(total, dtype=np.int64)
    starts = np.empty(total + 1, dtype=np.int64)
    inner = np.empty(total, dtype=np.int64)
    nbrs = np.empty(8, dtype=np.int64)
    nbrs2 = np.empty(8, dtype=np.int64)
    nbrs3 = np.empty(8, dtype=np.int64)
    head, tail = 0, 1
    queue[0] = start
    visited[start] = True
    n_cells = 0
    n_groups = 0
    while head < tail:
        idx = queue[head]
        head += 1
        for k in range(_neighbours(idx, width, height, nbrs, False)):
            nbr = nbrs[k]
            if costs[nbr] <= costs[idx] and not visited[nbr]:
                visited[nbr] = True
                queue[tail] = nbr
                tail += 1
            elif _is_new_frontier_cell(costs, width, height, nbr, flag, nbrs2):
                flag[nbr] = True
                starts[n_groups] = n_cells
                n_groups += 1
                cells[n_cells] = nbr
                n_cells += 1
                ihead, itail = 0, 1
                inner[0] = nbr
                while ihead < itail:
                    cell = inner[ihead]
                    ihead += 1
                    for j in range(_neighbours(cell, width, height, nbrs3, True)):
                        other = nbrs3[j]
                        if _is_new_frontier_cell(costs, width, height, other, flag, nbrs2):
                            flag[other] = True
                            cells[n_cells] = other
                            n_cells += 1
                            inner[itail] = other
                            itail += 1
    starts[n_groups] = n_cells
    return cells[:n_cells].copy(), starts[: n_groups + 1].copy()


def _check_grid(costs: NDArray[np.uint8], resolution: float) -> None:
    if costs.ndim != 2 or costs.size == 0 or costs.dtype != np.uint8:
        msg = (
            f"frontier search: the costmap is a {costs.dtype} array of shape {costs.shape}: "
            "expected a non-empty (height, width) uint8 array of costmap_2d costs"
        )
        raise FrontierSearchError(msg)
    if not (np.isfinite(resolution) and resolution > 0.0):
        msg = f"frontier search: resolution is {resolution!r}: expected a positive number of metres"
        raise FrontierSearchError(msg)


def search_frontiers(
    costs: NDArray[np.uint8],
    robot_xy: tuple[float, float],
    *,
    resolution: float,
    origin: tuple[float, float] = (0.0, 0.0),
    potential_scale: float = 1e-3,
    gain_scale: float = 1.0,
    min_frontier_size: float = 0.5,
) -> list[Frontier]:
    """Find the frontiers reachable from the robot, cheapest first (module docstring).

    Args:
        costs: ``(height, width)`` ``uint8`` costmap_2d costs, row ``y``, column ``x``.
        robot_xy: Robot position in the grid's frame (metres).
        resolution: Metres per cell.
        origin: ``(x, y)`` of the grid's corner (cell ``(0, 0)``'s lower-left corner).
        potential_scale: Weight of the distance in the cost.
        gain_scale: Weight of the size in the cost.
        min_frontier_size: Frontiers shorter than this (metres: cells * resolution) are
            dropped.

    Returns:
        The frontiers sorted by cost (stable).

    Raises:
        FrontierSearchError: The grid is malformed or the robot is outside it.
    """
    costs = np.asarray(costs)
    _check_grid(costs, resolution)
    height, width = costs.shape
    ox, oy = float(origin[0]), float(origin[1])
    rx, ry = float(robot_xy[0]), float(robot_xy[1])
    mx = int(np.floor((rx - ox) / resolution)) if np.isfinite(rx) else -1
    my = int(np.floor((ry - oy) / resolution)) if np.isfinite(ry) else -1
    if not (0 <= mx < width and 0 <= my < height):
        msg = (
            f"frontier search: the robot at ({rx:.3f}, {ry:.3f}) is outside the costmap "
            f"({width} x {height} cells of {resolution:g} m from ({ox:.3f}, {oy:.3f})); "
            "check robot_base_frame and that the map covers the robot"
        )
        raise FrontierSearchError(msg)
    flat = np.ascontiguousarray(costs).reshape(-1)
    pos = my * width + mx
    start = int(_nearest_cell(flat, width, height, pos, FREE_SPACE))
    if start < 0:
        start = pos
    cells, starts = _frontier_cells(flat, width, height, start)
    ref_x = ox + (mx + 0.5) * resolution
    ref_y = oy + (my + 0.5) * resolution
    xs = ox + (cells % width + 0.5) * resolution
    ys = oy + (cells // width + 0.5) * resolution
    dist = np.hypot(xs - ref_x, ys - ref_y)
    frontiers: list[Frontier] = []
    for a, b in zip(starts[:-1].tolist(), starts[1:].tolist(), strict=True):
        size = b - a
        if size * resolution < min_frontier_size:
            continue
        closest = a + int(np.argmin(dist[a:b]))
        min_distance = float(dist[closest])
        frontiers.append(
            Frontier(
                size=size,
                min_distance=min_distance,
                cost=frontier_cost(
                    size,
                    min_distance,
                    resolution,
                    potential_scale=potential_scale,
                    gain_scale=gain_scale,
                ),
                initial=(float(xs[a]), float(ys[a])),
                centroid=(float(xs[a:b].mean()), float(ys[a:b].mean())),
                middle=(float(xs[closest]), float(ys[closest])),
                points=np.column_stack((xs[a:b], ys[a:b])),
            )
        )
    frontiers.sort(key=lambda f: f.cost)
    return frontiers
