"""The likelihood field of an occupancy grid: AMCL's laser model map.

ROS amcl (``map_update_cspace``) precomputes, for every cell, the distance to the
nearest occupied cell, capped at ``laser_likelihood_max_dist``; a beam end point then
scores by that distance alone. :class:`LikelihoodField` does the same with an exact
Euclidean distance transform (:func:`scipy.ndimage.distance_transform_edt`) instead of
amcl's brushfire over a square kernel, and answers distance queries for many points at
once (``(N, 2)`` arrays in the map frame).

The grid follows ``nav_msgs/OccupancyGrid``: ``data[row, col]`` with row 0 at the
origin, cells ``>= 65`` occupied (map_saver's threshold; amcl itself reads only 100
as occupied, the same for trinary maps), ``0`` free, ``-1`` unknown. The origin may
carry a yaw (map_server's third origin number), which amcl ignores; here points are
rotated into the grid.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from visnav.mapping.errors import MappingError
from visnav.tf.errors import InvalidArgumentException
from visnav.tf.transforms import yaw_from_quaternion

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from visnav.msgs.types import OccupancyGrid

__all__ = ["OCCUPIED_VALUE", "LikelihoodField", "LikelihoodFieldError"]

OCCUPIED_VALUE = 65
"""Grid values at or above this are obstacles (map_saver's ``--occ``)."""


class LikelihoodFieldError(MappingError, ValueError):
    """A map that cannot become a likelihood field (the message names the field)."""


class LikelihoodField:
    """Distances to the nearest obstacle of an occupancy grid.

    Args:
        data: ``(height, width)`` occupancy values, row 0 at ``origin``.
        resolution: Metres per cell (> 0).
        origin: ``(x, y, yaw)`` of cell ``(0, 0)``'s corner in the map frame.
        max_dist: Distances are capped here (amcl's ``laser_likelihood_max_dist``), m.

    Raises:
        LikelihoodFieldError: an empty grid, a resolution or ``max_dist`` that is not > 0.
    """

    def __init__(
        self,
        data: NDArray[np.integer],
        resolution: float,
        origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
        *,
        max_dist: float = 2.0,
    ) -> None:
        grid = np.asarray(data)
        if grid.ndim != 2 or grid.size == 0:
            msg = (
                f"likelihood field: map data of shape {grid.shape}; expected a non-empty "
                "(height, width) grid. Fix: pass OccupancyGrid data reshaped to height x width"
            )
            raise LikelihoodFieldError(msg)
        if not (math.isfinite(resolution) and resolution > 0):
            msg = f"likelihood field: resolution {resolution!r}; expected > 0 m/cell"
            raise LikelihoodFieldError(msg)
        if not (math.isfinite(max_dist) and max_dist > 0):
            msg = (
                f"likelihood field: laser_likelihood_max_dist {max_dist!r}; expected > 0 m "
                "(amcl's default is 2.0)"
            )
            raise LikelihoodFieldError(msg)
        self.resolution = float(resolution)
        self.origin = (float(origin[0]), float(origin[1]), float(origin[2]))
        self.max_dist = float(max_dist)
        self.height, self.width = (int(n) for n in grid.shape)
        self.occupied: NDArray[np.bool_] = grid >= OCCUPIED_VALUE
        self.free: NDArray[np.bool_] = grid == 0
        # distances between cell centres, moved to the obstacle's surface: a wall's
        # surface is the boundary of its cells, half a cell from the centres
        half = 0.5 * self.resolution
        if self.occupied.any() and not self.occupied.all():
            outside = ndimage.distance_transform_edt(~self.occupied) * self.resolution - half
            inside = ndimage.distance_transform_edt(self.occupied) * self.resolution - half
            signed = np.where(self.occupied, -inside, outside)
        elif self.occupied.any():
            signed = np.full(grid.shape, -self.max_dist)
        else:
            signed = np.full(grid.shape, self.max_dist)
        self.signed: NDArray[np.float32] = np.clip(signed, -self.max_dist, self.max_dist).astype(
            np.float32
        )
        self.distance: NDArray[np.float32] = np.abs(self.signed)
        # one cell of max_dist around the grid, so that bilinear lookups need no edge cases
        self.padded: NDArray[np.float64] = np.pad(
            self.signed.astype(np.float64), 1, constant_values=self.max_dist
        )
        self._cos = math.cos(self.origin[2])
        self._sin = math.sin(self.origin[2])
        self.grid_pose: NDArray[np.float64] = np.array(
            [self.origin[0], self.origin[1], self._cos, self._sin]
        )
        rows, cols = np.nonzero(self.free)
        self._free_rc: NDArray[np.int64] = np.stack([rows, cols], axis=1).astype(np.int64)

    @classmethod
    def from_msg(cls, msg: OccupancyGrid, *, max_dist: float = 2.0) -> LikelihoodField:
        """Build from a ``nav_msgs/OccupancyGrid`` (map_server's ``map``).

        Raises:
            LikelihoodFieldError: the message's size does not match its data.
        """
        info = msg.info
        width, height = int(info.width), int(info.height)
        data = np.asarray(msg.data, dtype=np.int8)
        if width <= 0 or height <= 0 or data.size != width * height:
            text = (
                f"map: OccupancyGrid info is {width} x {height} but data holds {data.size} "
                "cells; expected width*height > 0 cells (is the map publisher sending a "
                "whole grid?)"
            )
            raise LikelihoodFieldError(text)
        try:
            yaw = yaw_from_quaternion(info.origin.orientation)
        except InvalidArgumentException as exc:
            text = (
                f"map: OccupancyGrid info.origin.orientation: {exc}; expected a unit "
                "quaternion (x, y, z, w). Fix: give the map origin a rotation (w = 1 for none)"
            )
            raise LikelihoodFieldError(text) from None
        origin = (float(info.origin.position.x), float(info.origin.position.y), yaw)
        return cls(data.reshape(height, width), float(info.resolution), origin, max_dist=max_dist)

    # ------------------------------------------------------------------ geometry
    def to_cells(self, points: NDArray[np.floating]) -> tuple[NDArray[np.int64], ...]:
        """Cell ``(col, row)`` indices of ``(..., 2)`` map-frame points (may be off the map)."""
        px = points[..., 0] - self.origin[0]
        py = points[..., 1] - self.origin[1]
        gx = self._cos * px + self._sin * py
        gy = -self._sin * px + self._cos * py
        inv = 1.0 / self.resolution
        col = np.floor(gx * inv).astype(np.int64)
        row = np.floor(gy * inv).astype(np.int64)
        return col, row

    def cell_centres(self, rows: NDArray[np.int64], cols: NDArray[np.int64]) -> NDArray[np.float64]:
        """Map-frame ``(N, 2)`` centres of cells."""
        gx = (cols.astype(np.float64) + 0.5) * self.resolution
        gy = (rows.astype(np.float64) + 0.5) * self.resolution
        x = self.origin[0] + self._cos * gx - self._sin * gy
        y = self.origin[1] + self._sin * gx + self._cos * gy
        return np.stack([x, y], axis=-1)

    def inside(self, points: NDArray[np.floating]) -> NDArray[np.bool_]:
        """Whether each ``(..., 2)`` point lies on the grid."""
        col, row = self.to_cells(points)
        return (col >= 0) & (col < self.width) & (row >= 0) & (row < self.height)

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` of the grid's corners in the map frame."""
        w, h = self.width * self.resolution, self.height * self.resolution
        corners = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
        x = self.origin[0] + self._cos * corners[:, 0] - self._sin * corners[:, 1]
        y = self.origin[1] + self._sin * corners[:, 0] + self._cos * corners[:, 1]
        return float(x.min()), float(y.min()), float(x.max()), float(y.max())

    # ------------------------------------------------------------------ queries
    def distance_at(self, points: NDArray[np.floating]) -> NDArray[np.float32]:
        """Distance to the nearest obstacle surface of each ``(..., 2)`` point.

        Bilinear between cell centres (so a point between two cells gets a distance
        between theirs), capped at ``max_dist``, which is also the distance off the map.
        """
        px = points[..., 0] - self.origin[0]
        py = points[..., 1] - self.origin[1]
        inv = 1.0 / self.resolution
        gx = (self._cos * px + self._sin * py) * inv - 0.5
        gy = (-self._sin * px + self._cos * py) * inv - 0.5
        c0 = np.floor(gx)
        r0 = np.floor(gy)
        fx = (gx - c0).astype(np.float32)
        fy = (gy - r0).astype(np.float32)
        col = c0.astype(np.int64)
        row = r0.astype(np.int64)
        ok = (col >= -1) & (col < self.width) & (row >= -1) & (row < self.height)
        out = np.full(col.shape, self.max_dist, dtype=np.float32)
        if not ok.any():
            return out
        c, r, fx, fy = col[ok], row[ok], fx[ok], fy[ok]
        grid = self.padded
        v00 = grid[r + 1, c + 1]
        v01 = grid[r + 1, c + 2]
        v10 = grid[r + 2, c + 1]
        v11 = grid[r + 2, c + 2]
        top = v00 + (v01 - v00) * fx
        bottom = v10 + (v11 - v10) * fx
        out[ok] = np.minimum(np.abs(top + (bottom - top) * fy), self.max_dist)
        return out

    def is_known(self, points: NDArray[np.floating]) -> NDArray[np.bool_]:
        """Whether each ``(..., 2)`` point lies in a known (free or occupied) cell."""
        col, row = self.to_cells(points)
        ok = (col >= 0) & (col < self.width) & (row >= 0) & (row < self.height)
        out = np.zeros(col.shape, dtype=bool)
        out[ok] = self.free[row[ok], col[ok]] | self.occupied[row[ok], col[ok]]
        return out

    def is_free(self, points: NDArray[np.floating]) -> NDArray[np.bool_]:
        """Whether each ``(..., 2)`` point lies in a known free cell."""
        col, row = self.to_cells(points)
        ok = (col >= 0) & (col < self.width) & (row >= 0) & (row < self.height)
        out = np.zeros(col.shape, dtype=bool)
        out[ok] = self.free[row[ok], col[ok]]
        return out

    @property
    def free_count(self) -> int:
        """Number of known free cells (where global localisation may put particles)."""
        return int(self._free_rc.shape[0])

    def sample_free(self, count: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """``(count, 3)`` poses uniform over free cells and heading (amcl's pose generator).

        Raises:
            LikelihoodFieldError: the map has no free cell.
        """
        if self.free_count == 0:
            msg = (
                "map: no free cell (value 0) to place particles in; expected a map with "
                "free space. Fix: check the map's thresholds (free_thresh) or negate"
            )
            raise LikelihoodFieldError(msg)
        pick = self._free_rc[rng.integers(self.free_count, size=count)]
        xy = self.cell_centres(pick[:, 0], pick[:, 1])
        xy += (rng.random((count, 2)) - 0.5) * self.resolution
        yaw = rng.uniform(-math.pi, math.pi, size=count)
        return np.column_stack([xy, yaw])
