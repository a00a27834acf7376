"""``initial_pose.*``: where a localizer starts, as nav2 AMCL names it.

One parameter group shared by the nodes that place the robot in the global frame at
start-up (``amcl``'s ``set_initial_pose``, ``slam``'s ``set_initial_pose``); declare it
with ``declare_params(node, InitialPoseParams, prefix="initial_pose.")``. It lives in
tf/ because it is a transform (``T_global_base``) and both the mapping and the slam
layers may import tf.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from visnav.graph.param_dataclass import param
from visnav.tf.transforms import matrix_from_euler

__all__ = ["InitialPoseParams"]


@dataclass(frozen=True)
class InitialPoseParams:
    """nav2 AMCL's ``initial_pose.x|y|z|yaw``: the base's start pose in the global frame.

    ``z`` is part of nav2's set; a planar localizer (AMCL) reads only ``x``, ``y`` and
    ``yaw``, a 3D one (SLAM) takes ``z`` as the base's height in the map.
    """

    x: float = param(0.0, description="start x of the base in the global frame (m)")
    y: float = param(0.0, description="start y of the base in the global frame (m)")
    z: float = param(0.0, description="start z of the base in the global frame (m; AMCL: 2D)")
    yaw: float = param(0.0, description="start heading of the base in the global frame (rad)")

    def matrix(self) -> NDArray[np.float64]:
        """``T_global_base`` (4x4): rotated by ``yaw`` about z, at ``(x, y, z)``.

        Raises:
            InvalidArgumentException: ``yaw`` is not finite.
        """
        out = np.eye(4)
        out[:2, :2] = matrix_from_euler(0.0, 0.0, self.yaw)[:2, :2]
        out[:3, 3] = (self.x, self.y, self.z)
        return out
