"""How good a SLAM map is against the world it was made in (the ``map_quality`` summary key).

:func:`map_quality` compares an occupancy grid (``nav_msgs/OccupancyGrid`` layout, in the
world's frame) with the world's collision geometry:

* ``occupied_near_surface``: the share of the map's occupied cells (>= 65, map_saver's
  threshold) whose centre, at the laser's height, lies within ``surface_tolerance`` of an
  obstacle surface (:func:`visnav.sim.world_geometry.obstacle_distance`); a doubled or
  shifted wall lowers it;
* ``free_known``: the share of the reachable free space (true free cells connected to the
  robot's start, farther than ``robot_radius`` from obstacles: where the robot's centre can
  go) that the map marks free (0 .. 24);
* ``free_wrong``: the share of the map's free cells that are inside an obstacle.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import ndimage

from visnav.description.worldmodel import WorldDescription
from visnav.sim.world_geometry import obstacle_distance, true_occupancy_grid

__all__ = ["map_quality"]


def map_quality(
    data: Any,
    *,
    resolution: float,
    origin: tuple[float, float],
    world: WorldDescription,
    start: tuple[float, float],
    robot_radius: float = 0.105,
    surface_tolerance: float = 0.05,
    laser_height: float = 0.17,
) -> dict[str, Any]:
    """Score an occupancy grid against ``world`` (module docstring).

    Args:
        data: ``(height, width)`` occupancy values (-1 unknown, 0..100), row 0 at ``origin``.
        resolution: cell size (m).
        origin: the lower-left corner of cell (0, 0) in the world frame (m).
        world: the world the map was made in.
        start: where the robot started (x, y), inside the reachable space.
        robot_radius: the robot's radius (m).
        surface_tolerance: an occupied cell this close to a surface is right (m).
        laser_height: the height the cells' centres are measured at (m).

    Returns:
        ``occupied_cells``, ``occupied_near_surface``, ``free_known``, ``free_wrong``
        (fractions rounded to 4 digits; None where there is nothing to count).
    """
    grid = np.asarray(data, dtype=np.int16)
    h, w = grid.shape
    ox, oy = origin
    bounds = (ox, oy, ox + w * resolution, oy + h * resolution)
    truth, _ = true_occupancy_grid(world, resolution, bounds=bounds)
    truth = truth[:h, :w]
    occupied = grid >= 65
    free = (grid >= 0) & (grid < 25)
    rows, cols = np.nonzero(occupied)
    near = None
    if len(rows):
        pts = np.column_stack(
            [
                ox + (cols + 0.5) * resolution,
                oy + (rows + 0.5) * resolution,
                np.full(len(rows), laser_height),
            ]
        )
        dist = np.abs(obstacle_distance(world, pts))
        near = float(np.mean(dist <= surface_tolerance))
    clear = ndimage.distance_transform_edt(~truth) * resolution > robot_radius
    labels, _ = ndimage.label(clear)
    sc, sr = int((start[0] - ox) / resolution), int((start[1] - oy) / resolution)
    known = None
    if 0 <= sr < h and 0 <= sc < w and labels[sr, sc] > 0:
        reachable = labels == labels[sr, sc]
        known = float(np.mean(free[reachable]))
    wrong = float(np.mean(truth[free])) if free.any() else None
    return {
        "occupied_cells": int(occupied.sum()),
        "occupied_near_surface": None if near is None else round(near, 4),
        "free_known": None if known is None else round(known, 4),
        "free_wrong": None if wrong is None else round(wrong, 4),
    }
