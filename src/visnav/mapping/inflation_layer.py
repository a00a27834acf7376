"""The inflation layer: costs falling off with obstacle distance (costmap_2d's ``InflationLayer``).

A cell at distance ``d`` (metres, between cell centres) from the nearest LETHAL
cell of the master grid gets (``computeCost``)::

    d == 0                   -> LETHAL_OBSTACLE (254)
    d <= inscribed_radius    -> INSCRIBED_INFLATED_OBSTACLE (253)
    otherwise                -> int(252 * exp(-cost_scaling_factor * (d - inscribed_radius)))

for cells within ``ceil(inflation_radius / resolution)`` cells of an obstacle; the
master keeps ``max(old, cost)``. An unknown (NO_INFORMATION) cell takes the cost only
when it is at least INSCRIBED (or any non-zero cost with ``inflate_unknown``).
Defaults: ``inflation_radius`` 0.55 m, ``cost_scaling_factor`` 10.0, the inscribed
radius from the footprint. Bounds grow by the inflation radius around the union of
this and the previous update's area, as costmap_2d.

Differences: distances come from an exact Euclidean distance transform of the update
window (OpenCV's ``DIST_MASK_PRECISE``) where costmap_2d propagates a 4-connected
wavefront that remembers the obstacle cell it started from (the same distance
almost everywhere; the wavefront can pick a farther obstacle behind a corner, giving
a slightly lower cost). Costs are written inside the requested window only (the
wavefront also writes a margin around it, which cannot lower any cost). The cell
radius tolerates the floating-point error of ``0.55 / 0.05`` (costmap_2d inflates 12
cells there, visnav 11).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.mapping.costmap_2d import (
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Bounds,
    Costmap2D,
)
from visnav.mapping.errors import CostmapError
from visnav.mapping.layer import Layer

__all__ = ["InflationLayer", "compute_cost"]


def compute_cost(
    distance_cells: NDArray[np.float64] | float,
    *,
    resolution: float,
    inscribed_radius: float,
    cost_scaling_factor: float,
) -> NDArray[np.uint8]:
    """costmap_2d's ``computeCost`` for distances in cells (vectorised)."""
    d = np.asarray(distance_cells, dtype=np.float64)
    metres = d * resolution
    factor = np.exp(-cost_scaling_factor * (metres - inscribed_radius))
    cost = np.floor((INSCRIBED_INFLATED_OBSTACLE - 1) * factor)
    cost = np.where(metres <= inscribed_radius, INSCRIBED_INFLATED_OBSTACLE, cost)
    cost = np.where(d == 0, LETHAL_OBSTACLE, cost)
    return np.clip(cost, 0, 255).astype(np.uint8)


class InflationLayer(Layer):
    """Inflates LETHAL cells of the master grid.

    Args:
        name: plugin name.
        inflation_radius: metres around obstacles that get a cost (0.55).
        cost_scaling_factor: exponential decay rate (10.0).
        inflate_unknown: NO_INFORMATION cells take any non-zero inflated cost (False).
        enabled: take part in updates.

    Raises:
        CostmapError: a negative radius or scaling factor.
    """

    def __init__(
        self,
        name: str = "inflation_layer",
        *,
        inflation_radius: float = 0.55,
        cost_scaling_factor: float = 10.0,
        inflate_unknown: bool = False,
        enabled: bool = True,
    ) -> None:
        super().__init__(name, enabled=enabled)
        if not (math.isfinite(inflation_radius) and inflation_radius >= 0):
            msg = f"{name}: inflation_radius is {inflation_radius}; expected metres >= 0"
            raise CostmapError(msg)
        if not (math.isfinite(cost_scaling_factor) and cost_scaling_factor >= 0):
            msg = f"{name}: cost_scaling_factor is {cost_scaling_factor}; expected >= 0"
            raise CostmapError(msg)
        self.inflation_radius = float(inflation_radius)
        self.cost_scaling_factor = float(cost_scaling_factor)
        self.inflate_unknown = inflate_unknown
        self.inscribed_radius = 0.0
        self.cell_inflation_radius = 0
        self._table = np.zeros(1, np.uint8)
        self._last = Bounds()
        self._need_reinflation = False

    def on_initialize(self) -> None:
        """Take the footprint's inscribed radius."""
        self.on_footprint_changed()

    def match_size(self) -> None:
        """Recompute the cost table for the master's resolution."""
        self._compute_table()

    def on_footprint_changed(self) -> None:
        """Follow the footprint's inscribed radius; re-inflate everything next update."""
        self.inscribed_radius = self.layered.footprint.inscribed_radius
        self._compute_table()
        self._need_reinflation = True

    def set_parameters(self, inflation_radius: float, cost_scaling_factor: float) -> None:
        """Change the radius / decay (re-inflates everything next update)."""
        self.inflation_radius = float(inflation_radius)
        self.cost_scaling_factor = float(cost_scaling_factor)
        self._compute_table()
        self._need_reinflation = True

    def _compute_table(self) -> None:
        if self._layered is None:
            return
        res = self.layered.costmap.resolution
        self.cell_inflation_radius = self.layered.costmap.cell_distance(self.inflation_radius)
        r = self.cell_inflation_radius
        # cost by squared integer cell distance; beyond the radius -> 0
        sq = np.arange((r + 1) ** 2 * 2 + 1, dtype=np.float64)
        d = np.sqrt(sq)
        table = compute_cost(
            d,
            resolution=res,
            inscribed_radius=self.inscribed_radius,
            cost_scaling_factor=self.cost_scaling_factor,
        )
        table[d > r] = FREE_SPACE
        self._table = table

    def cost_for_distance(self, distance_cells: float) -> int:
        """Cost at a distance in cells (0 beyond the inflation radius)."""
        if distance_cells > self.cell_inflation_radius:
            return FREE_SPACE
        return int(
            compute_cost(
                distance_cells,
                resolution=self.layered.costmap.resolution,
                inscribed_radius=self.inscribed_radius,
                cost_scaling_factor=self.cost_scaling_factor,
            )
        )

    def update_bounds(
        self, robot_x: float, robot_y: float, robot_yaw: float, bounds: Bounds
    ) -> None:
        """Grow by the inflation radius around this and the previous update's area."""
        if self._need_reinflation:
            self._last = bounds.copy()
            bounds.min_x = bounds.min_y = -1e30
            bounds.max_x = bounds.max_y = 1e30
            self._need_reinflation = False
            return
        previous = self._last
        self._last = bounds.copy()
        if previous.empty and bounds.empty:
            return
        merged = bounds.copy()
        merged.union(previous)
        r = self.inflation_radius
        bounds.min_x, bounds.min_y = merged.min_x - r, merged.min_y - r
        bounds.max_x, bounds.max_y = merged.max_x + r, merged.max_y + r

    def update_costs(self, master: Costmap2D, x0: int, y0: int, xn: int, yn: int) -> None:
        """Inflate the LETHAL cells within reach of the window ``[x0, xn) x [y0, yn)``."""
        r = self.cell_inflation_radius
        if not self.enabled or r == 0 or xn <= x0 or yn <= y0:
            return
        ex0, ey0 = max(0, x0 - r), max(0, y0 - r)
        exn, eyn = min(master.size_x, xn + r), min(master.size_y, yn + r)
        window = master.data[ey0:eyn, ex0:exn]
        free = (window != LETHAL_OBSTACLE).astype(np.uint8)
        if free.all():
            return
        dist = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        sub = dist[y0 - ey0 : yn - ey0, x0 - ex0 : xn - ex0]
        sq = np.rint(sub.astype(np.float64) ** 2).astype(np.int64)
        cost = self._table[np.minimum(sq, len(self._table) - 1)]
        old = master.data[y0:yn, x0:xn]
        new = np.maximum(old, cost)
        unknown = old == NO_INFORMATION
        if unknown.any():
            threshold = FREE_SPACE + 1 if self.inflate_unknown else INSCRIBED_INFLATED_OBSTACLE
            take = unknown & (cost >= threshold)
            new[unknown] = NO_INFORMATION
            new[take] = cost[take]
        master.data[y0:yn, x0:xn] = new

    def reset(self) -> None:
        """Re-inflate everything on the next update."""
        self._need_reinflation = True
