"""nav2's RotationShimController: turn in place toward a new plan, then hand over.

When a plan arrives, the shim looks at the first plan pose at least
``forward_sampling_distance`` (0.5 m) from the robot (none near the goal: it hands
over at once); if it lies more than ``angular_dist_threshold``
(0.785 rad) off the robot's heading, the robot turns in place toward it at
``rotate_to_heading_angular_vel`` (1.8 rad/s, changing by at most
``max_angular_accel`` (3.2 rad/s^2) per control period), checking the footprint over
``simulate_ahead_time`` (1 s) of the turn; once within the threshold, the wrapped
controller drives until the next plan.

Why visnav wraps DWA in it by default: with ``use_dwa`` the sampled yaw rates of a
robot at rest stay within ``+-acc_lim_theta / controller_frequency`` (0.16 rad/s),
below ``min_vel_theta`` (0.4), so dwa_local_planner cannot start turning in place,
and its critics, read one short rollout ahead, barely change with heading: a plan
behind the robot is followed by driving a long arc away from it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.costmap_2d import Costmap2D
from visnav.mapping.footprint import Footprint
from visnav.planning.local_planner import (
    ControlResult,
    LocalPlanner,
    Pose2D,
    footprint_in_collision,
    transform_poses,
)

__all__ = ["RotationShim"]


class RotationShim:
    """Wrap a local planner with an initial in-place rotation toward each new plan.

    Args:
        primary: the wrapped local planner.
        angular_dist_threshold: heading error that triggers the rotation (rad).
        forward_sampling_distance: how far along the plan the heading is taken (m).
        rotate_to_heading_angular_vel: turning speed (rad/s).
        max_angular_accel: angular acceleration limit (rad/s^2).
        simulate_ahead_time: seconds of the turn checked for collisions.
        controller_frequency: control rate (Hz).
    """

    def __init__(
        self,
        primary: LocalPlanner,
        *,
        angular_dist_threshold: float = 0.785,
        forward_sampling_distance: float = 0.5,
        rotate_to_heading_angular_vel: float = 1.8,
        max_angular_accel: float = 3.2,
        simulate_ahead_time: float = 1.0,
        controller_frequency: float = 20.0,
    ) -> None:
        self.primary = primary
        self.angular_dist_threshold = angular_dist_threshold
        self.forward_sampling_distance = forward_sampling_distance
        self.rotate_to_heading_angular_vel = rotate_to_heading_angular_vel
        self.max_angular_accel = max_angular_accel
        self.simulate_ahead_time = simulate_ahead_time
        self.period = 1.0 / controller_frequency
        self.plan: NDArray[np.float64] = np.empty((0, 3))
        self._path_updated = False

    def set_plan(self, plan: NDArray[np.float64]) -> None:
        """Pass the plan on and check the heading before the next command."""
        self.plan = np.asarray(plan, dtype=np.float64).reshape(-1, 3)
        self._path_updated = True
        self.primary.set_plan(plan)

    def reset(self) -> None:
        """Reset the wrapped planner."""
        self._path_updated = False
        self.plan = np.empty((0, 3))
        self.primary.reset()

    def is_goal_reached(self, pose: Pose2D, velocity: tuple[float, float]) -> bool:
        """The wrapped planner's goal check."""
        return self.primary.is_goal_reached(pose, velocity)

    def heading_error(self, pose: Pose2D, T_local_global: Pose2D) -> float | None:  # noqa: N803
        """Angle from the robot's heading to the sampled plan pose.

        None when there is no plan or no plan pose lies ``forward_sampling_distance``
        from the robot (near the goal), as nav2's shim hands over then.
        """
        if len(self.plan) == 0:
            return None
        local = transform_poses(self.plan, T_local_global)
        d = np.hypot(local[:, 0] - pose[0], local[:, 1] - pose[1])
        k = int(np.argmin(d))
        ahead = np.nonzero(d[k:] >= self.forward_sampling_distance)[0]
        if len(ahead) == 0:  # the plan ends closer: leave it to the wrapped planner
            return None
        j = k + int(ahead[0])
        dx, dy = local[j, 0] - pose[0], local[j, 1] - pose[1]
        return math.remainder(math.atan2(dy, dx) - pose[2], 2 * math.pi)

    def compute_velocity(
        self,
        pose: Pose2D,
        velocity: tuple[float, float],
        costmap: Costmap2D,
        footprint: Footprint,
        T_local_global: Pose2D,  # noqa: N803
    ) -> ControlResult:
        """Rotate while the new plan is behind; otherwise the wrapped planner's command."""
        if self._path_updated:
            err = self.heading_error(pose, T_local_global)
            if err is not None and abs(err) > self.angular_dist_threshold:
                return self._rotate(pose, velocity[1], err, costmap, footprint)
            self._path_updated = False
        return self.primary.compute_velocity(pose, velocity, costmap, footprint, T_local_global)

    def _rotate(
        self, pose: Pose2D, w_now: float, err: float, costmap: Costmap2D, footprint: Footprint
    ) -> ControlResult:
        dw = self.max_angular_accel * self.period
        w = math.copysign(self.rotate_to_heading_angular_vel, err)
        w = min(max(w, w_now - dw), w_now + dw)
        steps = max(1, math.ceil(self.simulate_ahead_time / self.period))
        for k in range(1, steps + 1):
            turned = w * k * self.period
            if abs(turned) > abs(err):
                break
            if footprint_in_collision((pose[0], pose[1], pose[2] + turned), costmap, footprint):
                if footprint.is_circular:
                    break  # a circle sweeps nothing new by turning
                return ControlResult(
                    False, reason="rotating toward the plan would make the footprint collide"
                )
        return ControlResult(True, 0.0, w)
