"""The drone scenario's pipeline: the quadrotor in the forest.

The ego-planner stack (grid map, planner, FSM, trajectory server) attaches here as it
lands (issue 8); until then the quadrotor hovers at its spawn and the run records its
sensors.
"""

from __future__ import annotations

from typing import Any

from visnav.graph.context import Context
from visnav.sim.simulator import Simulator

__all__ = ["build_drone_pipeline"]


def build_drone_pipeline(ctx: Context, sim: Simulator, seed: int) -> list[Any]:
    """Start the drone's nodes on ``ctx``; return the tasks (none yet)."""
    del ctx, sim, seed
    return []
