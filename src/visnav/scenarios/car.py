"""The car scenario's pipeline: the move_base data chain on the simulated car.

Built now: depth image -> laser scan (depthimage_to_laserscan on the depth camera).
The navigation stack (costmaps, planners, goals) and SLAM attach here as they land
(issues 7 and 9); until then the car stands still and the run records its sensors.
"""

from __future__ import annotations

from typing import Any

from visnav.graph.context import Context
from visnav.perception.nodes import DepthImageToLaserScanNode
from visnav.sim.simulator import Simulator

__all__ = ["build_car_pipeline"]


def build_car_pipeline(ctx: Context, sim: Simulator, seed: int) -> list[Any]:
    """Start the car's perception nodes on ``ctx``; return the tasks (none yet)."""
    del seed
    DepthImageToLaserScanNode(
        context=ctx,
        remappings={
            "depth": "/depth_camera/depth/image_raw",
            "depth_camera_info": "/depth_camera/depth/camera_info",
        },
        parameter_overrides={
            "use_sim_time": True,
            "output_frame": "camera_depth_frame",
            "scan_height": 10,
        },
    )
    return []
