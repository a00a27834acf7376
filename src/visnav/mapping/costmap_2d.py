"""A 2D cost grid with costmap_2d's cost values, geometry and OccupancyGrid translation.

:class:`Costmap2D` is costmap_2d's ``Costmap2D``: a ``uint8`` grid of ``size_x`` by
``size_y`` cells of ``resolution`` metres whose cell ``(0, 0)`` has its lower-left
corner at ``(origin_x, origin_y)`` in the costmap's global frame. The array is
indexed ``data[my, mx]`` (row = y), the row-major order of ``nav_msgs/OccupancyGrid``.

Cost values (``costmap_2d/cost_values.h``): :data:`FREE_SPACE` 0,
:data:`INSCRIBED_INFLATED_OBSTACLE` 253, :data:`LETHAL_OBSTACLE` 254,
:data:`NO_INFORMATION` 255; 1..252 are inflated costs.

Semantics follow costmap_2d:

* ``world_to_map`` refuses points left of / below the origin or beyond the far edge;
  a cell's world position is its centre;
* ``update_origin`` (rolling windows) moves the origin by whole cells, keeps the
  overlapping cells and fills the rest with the default value;
* ``to_occupancy_grid`` uses ``Costmap2DPublisher``'s translation table: 0 -> 0,
  1..252 -> ``1 + 97 * (c - 1) // 251`` (1..98), 253 -> 99, 254 -> 100, 255 -> -1.

Differences: ``update_origin`` rounds the shift down (``floor``) where costmap_2d
truncates toward zero, so a window moving to negative coordinates keeps whole-cell
alignment the same way in both directions; ``resize_map`` can keep the overlapping
cells (costmap_2d always clears), which lets a global costmap grow with an
exploration map without forgetting its obstacle layer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.mapping.errors import CostmapError
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, MapMetaData, OccupancyGrid, Point, Pose, Quaternion

__all__ = [
    "FREE_SPACE",
    "INSCRIBED_INFLATED_OBSTACLE",
    "LETHAL_OBSTACLE",
    "NO_INFORMATION",
    "Bounds",
    "Costmap2D",
    "cost_translation_table",
    "costmap_to_occupancy_grid",
]

FREE_SPACE = 0
INSCRIBED_INFLATED_OBSTACLE = 253
LETHAL_OBSTACLE = 254
NO_INFORMATION = 255

_BIG = 1e30


def cost_translation_table() -> NDArray[np.int8]:
    """Return costmap_2d's cost (0..255) -> OccupancyGrid value (-1..100) table."""
    table = np.empty(256, dtype=np.int8)
    i = np.arange(1, 253)
    table[1:253] = 1 + (97 * (i - 1)) // 251
    table[0] = 0
    table[INSCRIBED_INFLATED_OBSTACLE] = 99
    table[LETHAL_OBSTACLE] = 100
    table[NO_INFORMATION] = -1
    return table


_TRANSLATION = cost_translation_table()


@dataclass
class Bounds:
    """An axis-aligned world rectangle that layers grow (costmap_2d's min/max x/y).

    An empty bounds has ``min > max`` (as costmap_2d starts from +-1e30).
    """

    min_x: float = _BIG
    min_y: float = _BIG
    max_x: float = -_BIG
    max_y: float = -_BIG

    def touch(self, x: float, y: float) -> None:
        """Grow to include the point ``(x, y)``."""
        self.min_x = min(self.min_x, x)
        self.min_y = min(self.min_y, y)
        self.max_x = max(self.max_x, x)
        self.max_y = max(self.max_y, y)

    def union(self, other: Bounds) -> None:
        """Grow to include ``other``."""
        self.min_x = min(self.min_x, other.min_x)
        self.min_y = min(self.min_y, other.min_y)
        self.max_x = max(self.max_x, other.max_x)
        self.max_y = max(self.max_y, other.max_y)

    @property
    def empty(self) -> bool:
        """True when nothing was touched."""
        return self.min_x > self.max_x or self.min_y > self.max_y

    def copy(self) -> Bounds:
        """Return a copy."""
        return Bounds(self.min_x, self.min_y, self.max_x, self.max_y)


def _check_geometry(size_x: int, size_y: int, resolution: float, ox: float, oy: float) -> None:
    if size_x < 0 or size_y < 0:
        msg = f"costmap size is {size_x} x {size_y} cells: expected sizes >= 0"
        raise CostmapError(msg)
    if not (math.isfinite(resolution) and resolution > 0):
        msg = f"costmap resolution is {resolution}: expected a finite value > 0 (metres per cell)"
        raise CostmapError(msg)
    if not (math.isfinite(ox) and math.isfinite(oy)):
        msg = f"costmap origin is ({ox}, {oy}): expected finite metres"
        raise CostmapError(msg)


class Costmap2D:
    """A grid of ``uint8`` costs (costmap_2d's ``Costmap2D``).

    Args:
        size_x: cells along x (columns).
        size_y: cells along y (rows).
        resolution: metres per cell.
        origin_x: world x of the grid's lower-left corner.
        origin_y: world y of the grid's lower-left corner.
        default_value: the value of new and reset cells.

    Raises:
        CostmapError: a negative size, a non-positive resolution or a non-finite origin.
    """

    def __init__(
        self,
        size_x: int,
        size_y: int,
        resolution: float,
        origin_x: float = 0.0,
        origin_y: float = 0.0,
        *,
        default_value: int = FREE_SPACE,
    ) -> None:
        _check_geometry(size_x, size_y, resolution, origin_x, origin_y)
        self.resolution = float(resolution)
        self.origin_x = float(origin_x)
        self.origin_y = float(origin_y)
        self.default_value = int(default_value)
        self.data: NDArray[np.uint8] = np.full((size_y, size_x), default_value, dtype=np.uint8)

    # ------------------------------------------------------------------ geometry
    @property
    def size_x(self) -> int:
        """Cells along x."""
        return int(self.data.shape[1])

    @property
    def size_y(self) -> int:
        """Cells along y."""
        return int(self.data.shape[0])

    @property
    def size_in_meters_x(self) -> float:
        """Width in metres (costmap_2d's ``(size_x - 1 + 0.5) * resolution`` is not used)."""
        return self.size_x * self.resolution

    @property
    def size_in_meters_y(self) -> float:
        """Height in metres."""
        return self.size_y * self.resolution

    def same_geometry(self, other: Costmap2D) -> bool:
        """Whether ``other`` has this grid's size, resolution and origin."""
        return (
            self.data.shape == other.data.shape
            and self.resolution == other.resolution
            and self.origin_x == other.origin_x
            and self.origin_y == other.origin_y
        )

    def cell_distance(self, world_dist: float) -> int:
        """Metres -> whole cells, rounded up (costmap_2d's ``cellDistance``).

        A relative tolerance of 1e-9 keeps ``0.55 / 0.05`` at 11 cells (costmap_2d's
        double division gives 11.000000000000002 and rounds it up to 12).
        """
        return max(0, math.ceil(world_dist / self.resolution - 1e-9))

    def map_to_world(self, mx: float, my: float) -> tuple[float, float]:
        """World coordinates of the centre of cell ``(mx, my)``."""
        return (
            self.origin_x + (mx + 0.5) * self.resolution,
            self.origin_y + (my + 0.5) * self.resolution,
        )

    def world_to_map(self, wx: float, wy: float) -> tuple[int, int] | None:
        """The cell holding ``(wx, wy)``, or None outside the grid."""
        if wx < self.origin_x or wy < self.origin_y:
            return None
        mx = int((wx - self.origin_x) / self.resolution)
        my = int((wy - self.origin_y) / self.resolution)
        if mx < self.size_x and my < self.size_y:
            return mx, my
        return None

    def world_to_map_no_bounds(self, wx: float, wy: float) -> tuple[int, int]:
        """The (possibly outside) cell of ``(wx, wy)`` (floor division)."""
        return (
            math.floor((wx - self.origin_x) / self.resolution),
            math.floor((wy - self.origin_y) / self.resolution),
        )

    def world_to_map_enforce_bounds(self, wx: float, wy: float) -> tuple[int, int]:
        """The cell of ``(wx, wy)`` clamped into the grid."""
        mx, my = self.world_to_map_no_bounds(wx, wy)
        return (
            min(max(mx, 0), max(self.size_x - 1, 0)),
            min(max(my, 0), max(self.size_y - 1, 0)),
        )

    def world_to_map_array(
        self, xy: ArrayLike
    ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
        """Vectorised ``world_to_map``: ``(mx, my, inside)`` for (N, 2) world points."""
        pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        fx = np.floor((pts[:, 0] - self.origin_x) / self.resolution)
        fy = np.floor((pts[:, 1] - self.origin_y) / self.resolution)
        inside = (fx >= 0) & (fy >= 0) & (fx < self.size_x) & (fy < self.size_y)
        fx = np.where(np.isfinite(fx), fx, -1)
        fy = np.where(np.isfinite(fy), fy, -1)
        return fx.astype(np.int64), fy.astype(np.int64), inside & np.isfinite(pts).all(axis=1)

    def costs_at(self, xy: ArrayLike, *, outside: int = NO_INFORMATION) -> NDArray[np.uint8]:
        """Costs at world points (N, 2); points outside the grid get ``outside``."""
        mx, my, inside = self.world_to_map_array(xy)
        out = np.full(mx.shape, outside, dtype=np.uint8)
        out[inside] = self.data[my[inside], mx[inside]]
        return out

    def lethal_centres(
        self, x_min: float, y_min: float, x_max: float, y_max: float
    ) -> NDArray[np.float64]:
        """World centres ``(N, 2)`` of the LETHAL cells that overlap a world box.

        The box ``[x_min, x_max] x [y_min, y_max]`` is cut to the grid; a box that
        misses the grid (or an empty grid) gives no cells. A cell counts when the box
        touches any part of it, so a centre may lie up to half a cell outside the box.
        Cells come in row-major order (``my``, then ``mx``).
        """
        empty = np.empty((0, 2), np.float64)
        if self.size_x == 0 or self.size_y == 0 or x_max < x_min or y_max < y_min:
            return empty
        x0, y0 = self.world_to_map_no_bounds(x_min, y_min)
        x1, y1 = self.world_to_map_no_bounds(x_max, y_max)
        if x1 < 0 or y1 < 0 or x0 >= self.size_x or y0 >= self.size_y:
            return empty
        x0, y0 = max(x0, 0), max(y0, 0)
        x1, y1 = min(x1, self.size_x - 1), min(y1, self.size_y - 1)
        jj, ii = np.nonzero(self.data[y0 : y1 + 1, x0 : x1 + 1] == LETHAL_OBSTACLE)
        res = self.resolution
        return np.stack(
            [self.origin_x + (ii + x0 + 0.5) * res, self.origin_y + (jj + y0 + 0.5) * res],
            axis=1,
        )

    # ------------------------------------------------------------------ cells
    def get_cost(self, mx: int, my: int) -> int:
        """Cost of cell ``(mx, my)``."""
        return int(self.data[my, mx])

    def set_cost(self, mx: int, my: int, cost: int) -> None:
        """Set the cost of cell ``(mx, my)``."""
        self.data[my, mx] = cost

    def reset_map(self, x0: int, y0: int, xn: int, yn: int) -> None:
        """Set cells ``x0 <= mx < xn``, ``y0 <= my < yn`` to the default value."""
        self.data[max(y0, 0) : max(yn, 0), max(x0, 0) : max(xn, 0)] = self.default_value

    def reset_all(self) -> None:
        """Set every cell to the default value."""
        self.data.fill(self.default_value)

    def copy(self) -> Costmap2D:
        """A deep copy."""
        out = Costmap2D(
            self.size_x,
            self.size_y,
            self.resolution,
            self.origin_x,
            self.origin_y,
            default_value=self.default_value,
        )
        out.data[...] = self.data
        return out

    def resize_map(
        self,
        size_x: int,
        size_y: int,
        resolution: float,
        origin_x: float,
        origin_y: float,
        *,
        keep: bool = False,
    ) -> None:
        """Change size, resolution and origin.

        Args:
            size_x: new cells along x.
            size_y: new cells along y.
            resolution: new metres per cell.
            origin_x: new lower-left corner x.
            origin_y: new lower-left corner y.
            keep: copy the cells both grids cover (only when the resolution is unchanged
                and the origins differ by whole cells; otherwise the grid is cleared).
        """
        _check_geometry(size_x, size_y, resolution, origin_x, origin_y)
        old = self.data
        shift_x = (self.origin_x - origin_x) / resolution
        shift_y = (self.origin_y - origin_y) / resolution
        aligned = (
            resolution == self.resolution
            and abs(shift_x - round(shift_x)) < 1e-6
            and abs(shift_y - round(shift_y)) < 1e-6
        )
        self.data = np.full((size_y, size_x), self.default_value, dtype=np.uint8)
        self.resolution = float(resolution)
        self.origin_x = float(origin_x)
        self.origin_y = float(origin_y)
        if keep and aligned:
            _paste(self.data, old, round(shift_x), round(shift_y))

    def update_origin(self, new_origin_x: float, new_origin_y: float) -> None:
        """Move the grid (rolling window) by whole cells, keeping the overlap."""
        cell_ox = math.floor((new_origin_x - self.origin_x) / self.resolution)
        cell_oy = math.floor((new_origin_y - self.origin_y) / self.resolution)
        if cell_ox == 0 and cell_oy == 0:
            return
        old = self.data
        self.data = np.full_like(old, self.default_value)
        _paste(self.data, old, -cell_ox, -cell_oy)
        self.origin_x += cell_ox * self.resolution
        self.origin_y += cell_oy * self.resolution

    # ------------------------------------------------------------------ polygons
    def polygon_cells(self, polygon: ArrayLike) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """Cells ``(rows, cols)`` covered by a convex world polygon (outline included).

        Vertices outside the grid are clipped by the raster; costmap_2d's
        ``convexFillCells`` refuses such polygons instead.
        """
        pts = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            return np.empty(0, np.intp), np.empty(0, np.intp)
        cx = np.floor((pts[:, 0] - self.origin_x) / self.resolution).astype(np.int64)
        cy = np.floor((pts[:, 1] - self.origin_y) / self.resolution).astype(np.int64)
        x0, x1 = max(int(cx.min()), 0), min(int(cx.max()), self.size_x - 1)
        y0, y1 = max(int(cy.min()), 0), min(int(cy.max()), self.size_y - 1)
        if x1 < x0 or y1 < y0:
            return np.empty(0, np.intp), np.empty(0, np.intp)
        lo_x, lo_y = int(cx.min()), int(cy.min())
        mask = np.zeros((int(cy.max()) - lo_y + 1, int(cx.max()) - lo_x + 1), np.uint8)
        poly = np.stack([cx - lo_x, cy - lo_y], axis=1).astype(np.int32)
        cv2.fillPoly(mask, [poly], 1)
        rows, cols = np.nonzero(mask)
        rows = rows + lo_y
        cols = cols + lo_x
        ok = (rows >= 0) & (rows < self.size_y) & (cols >= 0) & (cols < self.size_x)
        return rows[ok], cols[ok]

    def set_convex_polygon_cost(self, polygon: ArrayLike, cost: int) -> None:
        """Set every cell of a convex world polygon to ``cost`` (footprint clearing)."""
        rows, cols = self.polygon_cells(polygon)
        self.data[rows, cols] = cost


def _paste(dst: NDArray[np.uint8], src: NDArray[np.uint8], dx: int, dy: int) -> None:
    """Copy ``src`` into ``dst`` with ``src[0, 0]`` landing on ``dst[dy, dx]``."""
    h, w = src.shape
    dh, dw = dst.shape
    x0, y0 = max(dx, 0), max(dy, 0)
    x1, y1 = min(dx + w, dw), min(dy + h, dh)
    if x1 <= x0 or y1 <= y0:
        return
    dst[y0:y1, x0:x1] = src[y0 - dy : y1 - dy, x0 - dx : x1 - dx]


def costmap_to_occupancy_grid(
    costmap: Costmap2D, frame_id: str, stamp_ns: int = 0
) -> OccupancyGrid:
    """Publish a costmap as ``nav_msgs/OccupancyGrid`` (Costmap2DPublisher's translation).

    Args:
        costmap: the costmap.
        frame_id: the costmap's global frame.
        stamp_ns: header stamp in nanoseconds.
    """
    header = Header(stamp=ns_to_time(stamp_ns), frame_id=frame_id)
    info = MapMetaData(
        map_load_time=ns_to_time(stamp_ns),
        resolution=float(costmap.resolution),
        width=costmap.size_x,
        height=costmap.size_y,
        origin=Pose(
            position=Point(x=costmap.origin_x, y=costmap.origin_y, z=0.0),
            orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
        ),
    )
    data = _TRANSLATION[costmap.data].reshape(-1)
    return OccupancyGrid(header=header, info=info, data=data)
