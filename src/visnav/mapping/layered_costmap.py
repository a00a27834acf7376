"""The layered costmap: a master grid painted by layers (costmap_2d's ``LayeredCostmap``).

Every :meth:`LayeredCostmap.update_map` call:

1. a rolling window moves the master so the robot is at its centre (whole cells);
2. each enabled layer grows a world rectangle (``update_bounds``);
3. that rectangle, clamped to the grid, is reset to the default value (NO_INFORMATION
   when tracking unknown space, FREE otherwise);
4. each enabled layer writes its costs into it (``update_costs``), in order.

The updated cell window is kept (``last_window``) for partial publication. The costmap
is current when every layer is (``is_current`` + ``reason``).
"""

from __future__ import annotations

from collections.abc import Sequence

from visnav.mapping.costmap_2d import FREE_SPACE, NO_INFORMATION, Bounds, Costmap2D
from visnav.mapping.errors import CostmapError
from visnav.mapping.footprint import Footprint
from visnav.mapping.layer import Layer

__all__ = ["LayeredCostmap"]


class LayeredCostmap:
    """A master costmap plus its layers.

    Args:
        global_frame: the frame the grid lives in (``map``, ``odom``).
        width: metres along x (costmap_2d's ``width``, default 10).
        height: metres along y (default 10).
        resolution: metres per cell (0.05).
        origin_x: lower-left corner x (ignored by a rolling window).
        origin_y: lower-left corner y.
        rolling_window: keep the robot at the centre.
        track_unknown_space: unknown cells are NO_INFORMATION (else FREE).
        footprint: the robot footprint (default ``robot_radius`` 0.46).
        layers: layers to add, in order.

    Raises:
        CostmapError: a bad size or resolution.
    """

    def __init__(
        self,
        global_frame: str = "map",
        *,
        width: float = 10.0,
        height: float = 10.0,
        resolution: float = 0.05,
        origin_x: float = 0.0,
        origin_y: float = 0.0,
        rolling_window: bool = False,
        track_unknown_space: bool = False,
        footprint: Footprint | None = None,
        layers: Sequence[Layer] = (),
    ) -> None:
        if not (width > 0 and height > 0):
            msg = f"costmap width x height is {width} x {height} m: expected positive sizes"
            raise CostmapError(msg)
        if not resolution > 0:
            msg = f"costmap resolution is {resolution}: expected metres per cell > 0"
            raise CostmapError(msg)
        self.global_frame = global_frame
        self.rolling_window = rolling_window
        self.track_unknown_space = track_unknown_space
        self.size_locked = False
        self.footprint = footprint if footprint is not None else Footprint.from_params()
        default = NO_INFORMATION if track_unknown_space else FREE_SPACE
        self.costmap = Costmap2D(
            round(width / resolution),
            round(height / resolution),
            resolution,
            origin_x,
            origin_y,
            default_value=default,
        )
        self.layers: list[Layer] = []
        self.last_window = (0, 0, 0, 0)
        self.initialized = False
        self.now_ns = 0
        self.reason = ""
        self._full_update = False
        for layer in layers:
            self.add_layer(layer)

    def add_layer(self, layer: Layer) -> None:
        """Append a layer (it sizes itself to the master)."""
        self.layers.append(layer)
        layer.initialize(self)

    def layer(self, name: str) -> Layer:
        """The layer called ``name``.

        Raises:
            CostmapError: no such layer.
        """
        for layer in self.layers:
            if layer.name == name:
                return layer
        msg = f"no layer {name!r}; layers: {[la.name for la in self.layers]}"
        raise CostmapError(msg)

    def resize_map(
        self,
        size_x: int,
        size_y: int,
        resolution: float,
        origin_x: float,
        origin_y: float,
        *,
        keep: bool = True,
    ) -> None:
        """Resize the master and every layer (kept content stays where it was)."""
        self.costmap.resize_map(size_x, size_y, resolution, origin_x, origin_y, keep=keep)
        for layer in self.layers:
            layer.match_size()

    def update_map(
        self, robot_x: float, robot_y: float, robot_yaw: float, *, now_ns: int = 0
    ) -> None:
        """Run one update cycle (see the module docs)."""
        self.now_ns = now_ns
        cm = self.costmap
        if self.rolling_window:
            cm.update_origin(robot_x - cm.size_in_meters_x / 2, robot_y - cm.size_in_meters_y / 2)
        if not self.layers:
            return
        bounds = Bounds()
        for layer in self.layers:
            if layer.enabled:
                layer.update_bounds(robot_x, robot_y, robot_yaw, bounds)
        if self._full_update:
            bounds.touch(-1e30, -1e30)
            bounds.touch(1e30, 1e30)
            self._full_update = False
        if bounds.empty:
            return
        x0, y0 = cm.world_to_map_enforce_bounds(bounds.min_x, bounds.min_y)
        xn, yn = cm.world_to_map_enforce_bounds(bounds.max_x, bounds.max_y)
        x0, y0 = max(0, x0), max(0, y0)
        xn, yn = min(cm.size_x, xn + 1), min(cm.size_y, yn + 1)
        if xn <= x0 or yn <= y0:
            return
        cm.reset_map(x0, y0, xn, yn)
        for layer in self.layers:
            if layer.enabled:
                layer.update_costs(cm, x0, y0, xn, yn)
        self.last_window = (x0, y0, xn, yn)
        self.initialized = True

    def is_current(self, now_ns: int) -> bool:
        """Whether every enabled layer is current; ``reason`` joins the layers' reasons."""
        reasons = [
            f"{layer.name}: {layer.reason}"
            for layer in self.layers
            if layer.enabled and not layer.is_current(now_ns)
        ]
        self.reason = "; ".join(reasons)
        return not reasons

    def request_full_update(self) -> None:
        """Repaint the whole grid on the next update (after layers were cleared)."""
        self._full_update = True

    def reset_layers(self) -> None:
        """Reset every layer and the master (the ``clear_costmaps`` service)."""
        self.costmap.reset_all()
        for layer in self.layers:
            layer.reset()
