"""The messages RViz's "2D Nav Goal" and "2D Pose Estimate" tools publish.

GoalTool sends a ``geometry_msgs/PoseStamped`` and InitialPoseTool a
``geometry_msgs/PoseWithCovarianceStamped``, both in the fixed frame at the clicked
``(x, y)`` facing ``yaw``, the pose estimate with a covariance of 0.5 m standard deviation
in x and y and pi/12 in yaw. ``visnav goal`` / ``visnav initialpose`` and the scenarios
that play a person at RViz send these.
"""

from __future__ import annotations

import math

import numpy as np

from visnav.msgs.time import ns_to_time
from visnav.msgs.types import (
    Header,
    Point,
    Pose,
    PoseStamped,
    PoseWithCovariance,
    PoseWithCovarianceStamped,
    Quaternion,
)

__all__ = ["INITIALPOSE_COVARIANCE", "nav_goal", "planar_pose", "pose_estimate"]

INITIALPOSE_COVARIANCE: tuple[float, ...] = tuple(
    {0: 0.5**2, 7: 0.5**2, 35: (math.pi / 12.0) ** 2}.get(i, 0.0) for i in range(36)
)
"""RViz's InitialPoseTool: x, y standard deviation 0.5 m, yaw pi/12 rad (row-major 6x6)."""


def planar_pose(x: float, y: float, yaw: float) -> Pose:
    """A pose on the ground plane at ``(x, y)`` facing ``yaw`` (rad)."""
    return Pose(
        position=Point(x=x, y=y, z=0.0),
        orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0)),
    )


def nav_goal(x: float, y: float, yaw: float, *, frame_id: str, stamp_ns: int) -> PoseStamped:
    """The ``PoseStamped`` of RViz's 2D Nav Goal."""
    header = Header(stamp=ns_to_time(stamp_ns), frame_id=frame_id)
    return PoseStamped(header=header, pose=planar_pose(x, y, yaw))


def pose_estimate(
    x: float, y: float, yaw: float, *, frame_id: str, stamp_ns: int
) -> PoseWithCovarianceStamped:
    """The ``PoseWithCovarianceStamped`` of RViz's 2D Pose Estimate."""
    header = Header(stamp=ns_to_time(stamp_ns), frame_id=frame_id)
    return PoseWithCovarianceStamped(
        header=header,
        pose=PoseWithCovariance(
            pose=planar_pose(x, y, yaw),
            covariance=np.array(INITIALPOSE_COVARIANCE, dtype=np.float64),
        ),
    )
