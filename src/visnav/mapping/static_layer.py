"""The static layer: costs from a ``nav_msgs/OccupancyGrid`` (costmap_2d's ``StaticLayer``).

Each map value (int8, read as unsigned as costmap_2d does, so -1 is 255) becomes a
cost (``interpretValue``):

* ``unknown_cost_value`` (-1): NO_INFORMATION when ``track_unknown_space``, else FREE;
* ``>= lethal_cost_threshold`` (100): LETHAL;
* otherwise FREE with ``trinary_costmap`` (default), else ``int(value / threshold * 254)``.

Until the first map arrives the layer is not current (costmap_2d's static layer blocks
the costmap's start instead). On a non-rolling costmap a map of another size, resolution
or origin resizes the whole layered costmap to it (unless the size is locked). Each new
map repaints the map's extent; ``use_maximum`` combines with max instead of overwriting
(the default overwrites every cell, unknown ones included). On a rolling costmap (or
when the map's frame is not the costmap's global frame) every master cell is looked up
in the map through the 2D transform ``T_global_map`` given with the map. On a
non-rolling costmap, when the map moves (a new transform) or a new map covers less,
the update also resets the extent painted last time, so no stale static costs stay
where the map no longer lies (costmap_2d's static layer never moves a map in a
non-rolling costmap; it has no such case).

Difference: costmap_2d's rolling static layer asks TF per update; here the caller
passes the transform with :meth:`StaticLayer.set_map` or :meth:`set_map_transform`
(:class:`~visnav.mapping.costmap_ros.CostmapROS` looks it up before every update).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.costmap_2d import (
    FREE_SPACE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Bounds,
    Costmap2D,
)
from visnav.mapping.errors import CostmapError
from visnav.mapping.layer import CostmapLayer
from visnav.msgs.types import OccupancyGrid
from visnav.tf.transforms import euler_from_quaternion

__all__ = ["StaticLayer", "interpret_table"]


def interpret_table(
    *,
    lethal_cost_threshold: int = 100,
    unknown_cost_value: int = -1,
    trinary_costmap: bool = True,
    track_unknown_space: bool = True,
) -> NDArray[np.uint8]:
    """The 256-entry map value (as uint8) -> cost table of ``interpretValue``."""
    values = np.arange(256)
    unknown = unknown_cost_value & 0xFF
    if trinary_costmap:
        scaled = np.full(256, FREE_SPACE)
    else:
        scaled = (values / max(lethal_cost_threshold, 1) * LETHAL_OBSTACLE).astype(np.int64)
    table = np.where(values >= lethal_cost_threshold, LETHAL_OBSTACLE, scaled)
    table[unknown] = NO_INFORMATION if track_unknown_space else FREE_SPACE
    return table.astype(np.uint8)


class StaticLayer(CostmapLayer):
    """Costs from an occupancy grid map.

    Args:
        name: plugin name.
        lethal_cost_threshold: map values at or above are lethal (100).
        unknown_cost_value: the map's unknown value (-1).
        trinary_costmap: map values below the threshold are free (True).
        track_unknown_space: unknown map cells stay NO_INFORMATION; None follows the
            layered costmap.
        use_maximum: combine with max instead of overwriting (False).
        first_map_only: ignore maps after the first (False).
        enabled: take part in updates.
    """

    def __init__(
        self,
        name: str = "static_layer",
        *,
        lethal_cost_threshold: int = 100,
        unknown_cost_value: int = -1,
        trinary_costmap: bool = True,
        track_unknown_space: bool | None = None,
        use_maximum: bool = False,
        first_map_only: bool = False,
        enabled: bool = True,
    ) -> None:
        super().__init__(name, enabled=enabled)
        self.lethal_cost_threshold = int(lethal_cost_threshold)
        self.unknown_cost_value = int(unknown_cost_value)
        self.trinary_costmap = trinary_costmap
        self.track_unknown_space = track_unknown_space
        self.use_maximum = use_maximum
        self.first_map_only = first_map_only
        self.map: Costmap2D | None = None
        self.map_frame = ""
        self.T_global_map = np.eye(3)
        self._has_updated_data = False
        self._painted: NDArray[np.float64] | None = None
        self._table = np.zeros(256, np.uint8)
        self.current = False
        self.reason = "no map received yet"

    def on_initialize(self) -> None:
        """Resolve ``track_unknown_space`` and build the value table."""
        if self.track_unknown_space is None:
            self.track_unknown_space = self.layered.track_unknown_space
        self._table = interpret_table(
            lethal_cost_threshold=self.lethal_cost_threshold,
            unknown_cost_value=self.unknown_cost_value,
            trinary_costmap=self.trinary_costmap,
            track_unknown_space=bool(self.track_unknown_space),
        )
        self.grid.default_value = NO_INFORMATION if self.track_unknown_space else FREE_SPACE

    def match_size(self) -> None:
        """The static layer keeps the map's own geometry (nothing to do)."""

    @property
    def map_received(self) -> bool:
        """Whether a map arrived."""
        return self.map is not None

    def set_map_transform(self, x: float, y: float, yaw: float) -> None:
        """Set the pose of the map frame in the costmap's global frame (2D).

        A changed pose repaints the map's extent at the next update.
        """
        c, s = math.cos(yaw), math.sin(yaw)
        new = np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])
        if self.map is not None and not np.array_equal(new, self.T_global_map):
            self._has_updated_data = True
        self.T_global_map = new

    def set_map(
        self, msg: OccupancyGrid, *, transform: tuple[float, float, float] | None = None
    ) -> None:
        """Take a new map (the ``map`` topic callback).

        Args:
            msg: the map.
            transform: pose ``(x, y, yaw)`` of the map frame in the global frame, when
                the frames differ (identity otherwise).

        Raises:
            CostmapError: the map's data length does not match width x height, or a
                bad resolution.
        """
        if self.first_map_only and self.map is not None:
            return
        info = msg.info
        w, h = int(info.width), int(info.height)
        data = np.asarray(msg.data)
        if data.size != w * h:
            text = (
                f"static layer {self.name!r}: map data has {data.size} cells but width x height "
                f"is {w} x {h} = {w * h}; publish a consistent OccupancyGrid"
            )
            raise CostmapError(text)
        q = info.origin.orientation
        _, _, map_yaw = euler_from_quaternion([q.x, q.y, q.z, q.w])
        if abs(map_yaw) > 1e-6:
            text = (
                f"static layer {self.name!r}: map origin is rotated by {map_yaw:.3f} rad; "
                "only axis-aligned maps are supported (as costmap_2d)"
            )
            raise CostmapError(text)
        ox, oy = float(info.origin.position.x), float(info.origin.position.y)
        res = float(info.resolution)
        grid = Costmap2D(w, h, res, ox, oy, default_value=self.grid.default_value)
        grid.data[...] = self._table[data.astype(np.int8).view(np.uint8).reshape(h, w)]
        self.map = grid
        self.map_frame = msg.header.frame_id
        if transform is not None:
            self.set_map_transform(*transform)
        layered = self.layered
        master = layered.costmap
        if (
            not layered.rolling_window
            and not layered.size_locked
            and self._identity
            and not master.same_geometry(grid)
        ):
            layered.resize_map(w, h, res, ox, oy)
        self._has_updated_data = True
        self.current = True
        self.reason = ""

    @property
    def _identity(self) -> bool:
        return bool(np.allclose(self.T_global_map, np.eye(3)))

    def update_bounds(
        self, robot_x: float, robot_y: float, robot_yaw: float, bounds: Bounds
    ) -> None:
        """Repaint the map's extent when a new map arrived (always on a rolling costmap).

        On a non-rolling costmap the extent painted last time is included too when it
        differs (the map moved): the layered costmap resets those cells and no layer
        paints static costs there any more.
        """
        if self.map is None:
            return
        rolling = self.layered.rolling_window
        if not rolling and not self._has_updated_data:
            return
        m = self.map
        corners = np.array(
            [
                [m.origin_x, m.origin_y, 1.0],
                [m.origin_x + m.size_in_meters_x, m.origin_y, 1.0],
                [m.origin_x, m.origin_y + m.size_in_meters_y, 1.0],
                [m.origin_x + m.size_in_meters_x, m.origin_y + m.size_in_meters_y, 1.0],
            ]
        )
        placed = corners @ self.T_global_map.T
        for cx, cy, _ in placed:
            bounds.touch(float(cx), float(cy))
        if not rolling:
            old = self._painted
            if old is not None and not np.array_equal(old, placed):
                for cx, cy, _ in old:
                    bounds.touch(float(cx), float(cy))
            self._painted = placed
        self._has_updated_data = False

    def update_costs(self, master: Costmap2D, x0: int, y0: int, xn: int, yn: int) -> None:
        """Overwrite (or max) the master with the map's costs."""
        if self.map is None or xn <= x0 or yn <= y0:
            return
        m = self.map
        src: NDArray[np.uint8] | NDArray[np.uint16]
        if self._identity and master.same_geometry(m):
            src = m.data[y0:yn, x0:xn]
        else:
            src = self._resample(master, x0, y0, xn, yn)
        dst = master.data[y0:yn, x0:xn]
        if self.use_maximum:
            take = (src < NO_INFORMATION) & ((dst == NO_INFORMATION) | (dst < src))
            dst[take] = src[take]
        else:
            inside = src != _OUTSIDE
            dst[inside] = src[inside]

    def _resample(
        self, master: Costmap2D, x0: int, y0: int, xn: int, yn: int
    ) -> NDArray[np.uint16]:
        """Map costs at the centres of master cells (nearest cell; outside -> sentinel)."""
        m = self.map
        assert m is not None
        xs = master.origin_x + (np.arange(x0, xn) + 0.5) * master.resolution
        ys = master.origin_y + (np.arange(y0, yn) + 0.5) * master.resolution
        gx, gy = np.meshgrid(xs, ys)
        inv = np.linalg.inv(self.T_global_map)
        mx = inv[0, 0] * gx + inv[0, 1] * gy + inv[0, 2]
        my = inv[1, 0] * gx + inv[1, 1] * gy + inv[1, 2]
        cx = np.floor((mx - m.origin_x) / m.resolution).astype(np.int64)
        cy = np.floor((my - m.origin_y) / m.resolution).astype(np.int64)
        inside = (cx >= 0) & (cy >= 0) & (cx < m.size_x) & (cy < m.size_y)
        out = np.full(gx.shape, _OUTSIDE, dtype=np.uint16)
        out[inside] = m.data[cy[inside], cx[inside]]
        return out

    def reset(self) -> None:
        """Re-apply the last map on the next update."""
        self._has_updated_data = True


_OUTSIDE = 256
