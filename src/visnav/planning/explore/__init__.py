"""Frontier exploration: explore_lite's frontier search, goal choice and node.

:func:`search_frontiers` and :class:`GoalSelector` are plain code (numpy, numba); the
graph node is :class:`visnav.planning.explore.node.ExploreNode` (registry name
``explore_lite``), imported from its module so that this package imports no graph code.
"""

from __future__ import annotations

from visnav.planning.explore.costmap_client import ExploreCostmap
from visnav.planning.explore.frontier_search import (
    Frontier,
    FrontierSearchError,
    cost_translation_table,
    frontier_cost,
    occupancy_to_costs,
    search_frontiers,
)
from visnav.planning.explore.goals import Decision, GoalSelector, Selection

__all__ = [
    "Decision",
    "ExploreCostmap",
    "Frontier",
    "FrontierSearchError",
    "GoalSelector",
    "Selection",
    "cost_translation_table",
    "frontier_cost",
    "occupancy_to_costs",
    "search_frontiers",
]
