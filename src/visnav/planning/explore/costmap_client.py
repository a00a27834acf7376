"""The grid explore_lite explores: a costmap rebuilt from ``OccupancyGrid`` messages.

As explore_lite's ``Costmap2DClient``: a full ``nav_msgs/OccupancyGrid`` replaces the
grid (size, resolution, origin and the frame, from its header), a partial update
(``map_msgs/OccupancyGridUpdate``'s ``x``, ``y``, ``width``, ``height``, ``data``)
overwrites a window of it, and both translate occupancy into costmap_2d costs with
:func:`~visnav.planning.explore.frontier_search.occupancy_to_costs`. The origin's
rotation is ignored, as costmap_2d ignores it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.planning.explore.frontier_search import FrontierSearchError, occupancy_to_costs

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["ExploreCostmap"]


@dataclass
class ExploreCostmap:
    """A costmap_2d-cost grid with its geometry.

    Attributes:
        costs: ``(height, width)`` ``uint8`` costs (row ``y``, column ``x``).
        resolution: Metres per cell.
        origin: ``(x, y)`` of cell ``(0, 0)``'s corner in ``frame_id``.
        frame_id: The grid's frame (explore_lite's global frame).
    """

    costs: NDArray[np.uint8]
    resolution: float
    origin: tuple[float, float]
    frame_id: str

    @classmethod
    def from_msg(cls, msg: Any, *, topic: str = "costmap") -> ExploreCostmap:
        """Build from a ``nav_msgs/OccupancyGrid``.

        Raises:
            FrontierSearchError: ``data`` does not hold ``width * height`` values or the
                resolution is not positive.
        """
        info = msg.info
        width, height = int(info.width), int(info.height)
        data = np.asarray(msg.data)
        if width <= 0 or height <= 0 or data.size != width * height:
            text = (
                f"{topic}: OccupancyGrid of {width} x {height} cells carries {data.size} "
                "values: expected width * height > 0 values; fix the map's publisher"
            )
            raise FrontierSearchError(text)
        resolution = float(info.resolution)
        if not (np.isfinite(resolution) and resolution > 0.0):
            text = f"{topic}: resolution is {resolution!r}: expected a positive cell size in m"
            raise FrontierSearchError(text)
        costs = occupancy_to_costs(data.astype(np.int8, copy=False)).reshape(height, width)
        origin = (float(info.origin.position.x), float(info.origin.position.y))
        return cls(costs.copy(), resolution, origin, str(msg.header.frame_id))

    def apply_update(self, x: int, y: int, width: int, height: int, data: Any) -> str:
        """Overwrite the window at cell ``(x, y)`` with ``data`` (row-major occupancy).

        Returns:
            ``""``, or why (part of) the update was not applied (for a warning).
        """
        if x < 0 or y < 0:
            return f"negative coordinates, update ignored: x {x}, y {y}"
        values = np.asarray(data).astype(np.int8, copy=False)
        if values.size != width * height:
            return (
                f"update of {width} x {height} cells carries {values.size} values: "
                "expected width * height; update ignored"
            )
        rows, cols = self.costs.shape
        note = ""
        if x + width > cols or y + height > rows:
            note = (
                f"update [{x}, {x + width}) x [{y}, {y + height}) does not fit the "
                f"{cols} x {rows} map: only the part inside was copied"
            )
        w, h = max(0, min(width, cols - x)), max(0, min(height, rows - y))
        window = occupancy_to_costs(values).reshape(height, width)
        self.costs[y : y + h, x : x + w] = window[:h, :w]
        return note
