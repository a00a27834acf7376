"""Costmap layer plugins: the interface and the grid-holding base (costmap_2d's ``Layer``).

A :class:`~visnav.mapping.layered_costmap.LayeredCostmap` calls, every update,
``update_bounds`` on each enabled layer (each grows the world rectangle it wants
repainted), resets that rectangle of the master grid, then ``update_costs`` on each
layer in order. :class:`CostmapLayer` keeps a grid shaped like the master and offers
costmap_2d's three ways to combine it into the master.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from visnav.mapping.costmap_2d import NO_INFORMATION, Bounds, Costmap2D

if TYPE_CHECKING:
    from visnav.mapping.layered_costmap import LayeredCostmap

__all__ = ["CostmapLayer", "Layer"]


class Layer:
    """One costmap plugin.

    Args:
        name: the plugin name (``static_layer``, ``obstacle_layer``, ...).
        enabled: whether the layer takes part in updates.
    """

    def __init__(self, name: str, *, enabled: bool = True) -> None:
        self.name = name
        self.enabled = enabled
        self._layered: LayeredCostmap | None = None
        self.current = True
        self.reason = ""

    @property
    def layered(self) -> LayeredCostmap:
        """The layered costmap this layer belongs to.

        Raises:
            RuntimeError: the layer was not added to a layered costmap yet.
        """
        if self._layered is None:
            msg = f"layer {self.name!r} is not part of a LayeredCostmap: call add_layer first"
            raise RuntimeError(msg)
        return self._layered

    def initialize(self, layered: LayeredCostmap) -> None:
        """Attach to a layered costmap (called by ``LayeredCostmap.add_layer``)."""
        self._layered = layered
        self.on_initialize()
        self.match_size()

    def on_initialize(self) -> None:
        """Hook run once when the layer is attached."""

    def match_size(self) -> None:
        """Follow a change of the master grid's size, resolution or origin."""

    def on_footprint_changed(self) -> None:
        """Follow a change of the robot footprint."""

    def update_bounds(
        self, robot_x: float, robot_y: float, robot_yaw: float, bounds: Bounds
    ) -> None:
        """Grow ``bounds`` by the world area this layer wants to repaint."""

    def update_costs(self, master: Costmap2D, x0: int, y0: int, xn: int, yn: int) -> None:
        """Write this layer's contribution into ``master`` cells ``[x0, xn) x [y0, yn)``."""

    def reset(self) -> None:
        """Forget everything the layer learned (the ``clear_costmaps`` service)."""

    def is_current(self, now_ns: int) -> bool:
        """Whether the layer's data are up to date; ``reason`` says why not."""
        return self.current

    @property
    def is_clearable(self) -> bool:
        """Whether recovery behaviours may clear this layer."""
        return False


class CostmapLayer(Layer):
    """A layer that keeps its own grid with the master's geometry."""

    def __init__(self, name: str, *, enabled: bool = True) -> None:
        super().__init__(name, enabled=enabled)
        self.grid = Costmap2D(0, 0, 1.0)

    @property
    def default_value(self) -> int:
        """Value of cells the layer knows nothing about."""
        return self.grid.default_value

    def match_size(self) -> None:
        """Resize the grid to the master's geometry, keeping aligned content."""
        master = self.layered.costmap
        if self.grid.same_geometry(master):
            return
        self.grid.resize_map(
            master.size_x,
            master.size_y,
            master.resolution,
            master.origin_x,
            master.origin_y,
            keep=True,
        )

    def reset(self) -> None:
        """Clear the grid to the default value."""
        self.grid.reset_all()
        self.current = True

    def clear_outside(self, x: float, y: float, size: float) -> None:
        """Reset every cell outside a ``size``-metre square centred on ``(x, y)``.

        costmap_2d's ``ClearCostmapRecovery`` does this with ``reset_distance``.
        """
        g = self.grid
        x0, y0 = g.world_to_map_no_bounds(x - size / 2, y - size / 2)
        x1, y1 = g.world_to_map_no_bounds(x + size / 2, y + size / 2)
        keep = g.data[max(y0, 0) : max(y1 + 1, 0), max(x0, 0) : max(x1 + 1, 0)].copy()
        g.reset_all()
        g.data[max(y0, 0) : max(y1 + 1, 0), max(x0, 0) : max(x1 + 1, 0)] = keep

    # -------------------------------------------------------------- combining
    def _views(
        self, master: Costmap2D, x0: int, y0: int, xn: int, yn: int
    ) -> tuple[np.ndarray, np.ndarray]:
        return master.data[y0:yn, x0:xn], self.grid.data[y0:yn, x0:xn]

    def update_with_overwrite(self, master: Costmap2D, x0: int, y0: int, xn: int, yn: int) -> None:
        """Copy known cells (not NO_INFORMATION) into the master."""
        m, g = self._views(master, x0, y0, xn, yn)
        known = g != NO_INFORMATION
        m[known] = g[known]

    def update_with_max(self, master: Costmap2D, x0: int, y0: int, xn: int, yn: int) -> None:
        """Master = max(master, layer) on known layer cells (unknown master cells take them)."""
        m, g = self._views(master, x0, y0, xn, yn)
        take = (g != NO_INFORMATION) & ((m == NO_INFORMATION) | (m < g))
        m[take] = g[take]
