"""Costmaps (costmap_2d equivalent) and occupancy grid mapping.

The algorithms are plain classes with numpy arrays and ROS messages in and out:
:class:`Costmap2D`, the layers (:class:`StaticLayer`, :class:`ObstacleLayer`,
:class:`InflationLayer`) inside a :class:`LayeredCostmap`, and the log-odds
:class:`OccupancyMapper`. The graph nodes live in :mod:`visnav.mapping.nodes`.
"""

from __future__ import annotations

from visnav.mapping.costmap_2d import (
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Bounds,
    Costmap2D,
    cost_translation_table,
    costmap_to_occupancy_grid,
)
from visnav.mapping.errors import CostmapError, MappingError, ObservationError
from visnav.mapping.footprint import (
    Footprint,
    make_footprint_from_radius,
    min_max_distances,
    pad_footprint,
    parse_footprint,
    transform_footprint,
)
from visnav.mapping.inflation_layer import InflationLayer, compute_cost
from visnav.mapping.layer import CostmapLayer, Layer
from visnav.mapping.layered_costmap import LayeredCostmap
from visnav.mapping.observation import (
    Observation,
    ObservationBuffer,
    ObservationSource,
    cloud_points,
    scan_points,
)
from visnav.mapping.obstacle_layer import ObstacleLayer
from visnav.mapping.occupancy import OccupancyMapper, logit
from visnav.mapping.static_layer import StaticLayer, interpret_table

__all__ = [
    "FREE_SPACE",
    "INSCRIBED_INFLATED_OBSTACLE",
    "LETHAL_OBSTACLE",
    "NO_INFORMATION",
    "Bounds",
    "Costmap2D",
    "CostmapError",
    "CostmapLayer",
    "Footprint",
    "InflationLayer",
    "Layer",
    "LayeredCostmap",
    "MappingError",
    "Observation",
    "ObservationBuffer",
    "ObservationError",
    "ObservationSource",
    "ObstacleLayer",
    "OccupancyMapper",
    "StaticLayer",
    "compute_cost",
    "cost_translation_table",
    "costmap_to_occupancy_grid",
    "cloud_points",
    "interpret_table",
    "logit",
    "make_footprint_from_radius",
    "min_max_distances",
    "pad_footprint",
    "parse_footprint",
    "scan_points",
    "transform_footprint",
]
