"""Regulated pure pursuit (nav2_regulated_pure_pursuit_controller).

Each cycle the plan is cut to the part ahead of the robot (the closest pose within
``max_robot_pose_search_dist`` of path length, up to the local costmap's half size;
the stored plan is pruned up to that pose), a carrot is placed ``lookahead_dist``
(0.6 m, or ``|v| * lookahead_time`` clamped to [0.3, 0.9] with
``use_velocity_scaled_lookahead_dist``) along it by intersecting the path with a
circle, and the command follows the circular arc through the carrot: curvature
``2 y / (x^2 + y^2)`` in the robot frame, ``w = v * curvature``.

The speed starts at ``desired_linear_vel`` (0.5) and is regulated:

* curvature: below a turning radius of ``regulated_linear_scaling_min_radius`` (0.9 m)
  the speed scales with ``radius / min_radius``;
* cost: near obstacles the distance implied by the robot cell's inflated cost
  (inverting the inflation formula with ``inflation_cost_scaling_factor``) below
  ``cost_scaling_dist`` (0.6 m) scales the speed by ``gain * distance / cost_scaling_dist``;
* the result is at least ``regulated_linear_scaling_min_speed`` (0.25), then slowed
  within ``approach_velocity_scaling_dist`` (0.6 m) of the goal, not below
  ``min_approach_linear_velocity`` (0.05).

With ``use_rotate_to_heading`` the robot turns in place (``rotate_to_heading_angular_vel``
1.8 rad/s, limited by ``max_angular_accel`` 3.2 per control period) toward the carrot
when it is more than ``rotate_to_heading_min_angle`` (0.785 rad) off, and to the goal's
yaw once the carrot is within the goal tolerance. With ``use_collision_detection`` the
command is projected forward (one cell per step) up to
``max_allowed_time_to_collision_up_to_carrot`` (1 s) or the carrot, and refused if the
footprint would hit an obstacle.

The goal check is nav2's stateful ``SimpleGoalChecker`` (0.25 m, 0.25 rad; once inside
the position tolerance only the yaw is checked).

Difference: ``inflation_cost_scaling_factor`` defaults to 10.0, visnav's (and
costmap_2d's) inflation default, where nav2 uses 3.0, its own inflation default; the
two must match for the cost regulation to mean a distance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.costmap_2d import (
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    NO_INFORMATION,
    Costmap2D,
)
from visnav.mapping.footprint import Footprint
from visnav.planning.errors import PlanningError
from visnav.planning.local_planner import (
    ControlResult,
    Pose2D,
    angle_diff,
    compose_2d,
    footprint_in_collision,
    invert_2d,
    transform_poses,
)

__all__ = ["RegulatedPurePursuit", "RPPParams", "carrot_curvature", "circle_segment_intersection"]


@dataclass(frozen=True)
class RPPParams:
    """Regulated pure pursuit parameters (nav2 defaults; see the module docs)."""

    desired_linear_vel: float = 0.5
    lookahead_dist: float = 0.6
    min_lookahead_dist: float = 0.3
    max_lookahead_dist: float = 0.9
    lookahead_time: float = 1.5
    rotate_to_heading_angular_vel: float = 1.8
    use_velocity_scaled_lookahead_dist: bool = False
    min_approach_linear_velocity: float = 0.05
    approach_velocity_scaling_dist: float = 0.6
    use_collision_detection: bool = True
    max_allowed_time_to_collision_up_to_carrot: float = 1.0
    use_regulated_linear_velocity_scaling: bool = True
    use_cost_regulated_linear_velocity_scaling: bool = True
    regulated_linear_scaling_min_radius: float = 0.9
    regulated_linear_scaling_min_speed: float = 0.25
    use_rotate_to_heading: bool = True
    rotate_to_heading_min_angle: float = 0.785
    max_angular_accel: float = 3.2
    cost_scaling_dist: float = 0.6
    cost_scaling_gain: float = 1.0
    inflation_cost_scaling_factor: float = 10.0
    max_robot_pose_search_dist: float = 0.0
    xy_goal_tolerance: float = 0.25
    yaw_goal_tolerance: float = 0.25
    stateful_goal_check: bool = True
    controller_frequency: float = 20.0

    def __post_init__(self) -> None:
        for name in ("desired_linear_vel", "lookahead_dist", "controller_frequency"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                msg = f"pure pursuit parameter {name} is {v}; expected a finite value > 0"
                raise PlanningError(msg)
        if self.min_lookahead_dist > self.max_lookahead_dist:
            msg = (
                f"min_lookahead_dist {self.min_lookahead_dist} > max_lookahead_dist "
                f"{self.max_lookahead_dist}; expected min <= max"
            )
            raise PlanningError(msg)


def carrot_curvature(x: float, y: float) -> float:
    """Curvature of the arc from the robot (origin, facing +x) through ``(x, y)``."""
    d2 = x * x + y * y
    return 2.0 * y / d2 if d2 > 0.001 else 0.0


def circle_segment_intersection(
    p1: NDArray[np.float64], p2: NDArray[np.float64], r: float
) -> NDArray[np.float64]:
    """The point at distance ``r`` from the origin on ``p1 -> p2`` (p1 inside, p2 outside)."""
    x1, y1 = float(p1[0]), float(p1[1])
    x2, y2 = float(p2[0]), float(p2[1])
    dx, dy = x2 - x1, y2 - y1
    dr2 = dx * dx + dy * dy
    d = x1 * y2 - x2 * y1
    dd = (x2 * x2 + y2 * y2) - (x1 * x1 + y1 * y1)
    sq = math.sqrt(max(0.0, r * r * dr2 - d * d))
    sgn = math.copysign(1.0, dd)
    return np.array([(d * dy + sgn * dx * sq) / dr2, (-d * dx + sgn * dy * sq) / dr2])


class RegulatedPurePursuit:
    """The regulated pure pursuit controller.

    Args:
        params: controller parameters.
    """

    def __init__(self, params: RPPParams | None = None) -> None:
        self.params = params or RPPParams()
        self.plan: NDArray[np.float64] = np.empty((0, 3))
        self._check_xy = True
        self.carrot = np.zeros(2)
        self.curvature = 0.0

    def set_plan(self, plan: NDArray[np.float64]) -> None:
        """Take a new global plan (global frame)."""
        self.plan = np.asarray(plan, dtype=np.float64).reshape(-1, 3)
        self._check_xy = True

    def reset(self) -> None:
        """Forget the plan."""
        self.set_plan(np.empty((0, 3)))

    def is_goal_reached(self, pose: Pose2D, velocity: tuple[float, float]) -> bool:
        """nav2's stateful SimpleGoalChecker (pose in the global frame)."""
        if len(self.plan) == 0:
            return False
        p = self.params
        goal = self.plan[-1]
        if self._check_xy:
            if math.hypot(goal[0] - pose[0], goal[1] - pose[1]) > p.xy_goal_tolerance:
                return False
            if p.stateful_goal_check:
                self._check_xy = False
        return abs(angle_diff(float(goal[2]), pose[2])) <= p.yaw_goal_tolerance

    def _robot_frame_path(
        self,
        pose: Pose2D,
        costmap: Costmap2D,
        T_local_global: Pose2D,  # noqa: N803
    ) -> NDArray[np.float64]:
        p = self.params
        local = transform_poses(self.plan, T_local_global)
        d = np.hypot(local[:, 0] - pose[0], local[:, 1] - pose[1])
        extent = max(costmap.size_in_meters_x, costmap.size_in_meters_y) / 2.0
        search = p.max_robot_pose_search_dist or extent
        seg = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(local[:, :2], axis=0).T))])
        window = max(1, int(np.searchsorted(seg, search, side="right")))
        k = int(np.argmin(d[:window]))
        beyond = np.nonzero(d[k:] > extent)[0]
        end = k + (int(beyond[0]) if len(beyond) else len(local) - k)
        self.plan = self.plan[k:]
        return transform_poses(local[k : max(end, k + 1)], invert_2d(pose))

    def compute_velocity(
        self,
        pose: Pose2D,
        velocity: tuple[float, float],
        costmap: Costmap2D,
        footprint: Footprint,
        T_local_global: Pose2D,  # noqa: N803
    ) -> ControlResult:
        """One control cycle (pose and velocity in the local frame)."""
        p = self.params
        if len(self.plan) == 0:
            return ControlResult(False, reason="the local planner has no plan")
        path = self._robot_frame_path(pose, costmap, T_local_global)
        lookahead = p.lookahead_dist
        if p.use_velocity_scaled_lookahead_dist:
            lookahead = min(
                max(abs(velocity[0]) * p.lookahead_time, p.min_lookahead_dist), p.max_lookahead_dist
            )
        carrot = self._lookahead_point(path, lookahead)
        self.carrot = carrot
        curvature = carrot_curvature(float(carrot[0]), float(carrot[1]))
        self.curvature = curvature
        dt = 1.0 / p.controller_frequency
        carrot_dist = float(np.hypot(*carrot))
        if p.use_rotate_to_heading and carrot_dist < p.xy_goal_tolerance:
            v, w = 0.0, self._rotate(float(path[-1, 2]), velocity[1], dt)
        elif (
            p.use_rotate_to_heading
            and abs(math.atan2(carrot[1], carrot[0])) > p.rotate_to_heading_min_angle
        ):
            v, w = 0.0, self._rotate(math.atan2(carrot[1], carrot[0]), velocity[1], dt)
        else:
            v = self._regulate(curvature, pose, costmap, footprint, path)
            w = v * curvature
        if p.use_collision_detection and self._collision_ahead(
            pose, v, w, carrot_dist, costmap, footprint
        ):
            return ControlResult(
                False,
                reason=(
                    f"collision ahead: the command v={v:.2f} m/s w={w:.2f} rad/s would hit an "
                    f"obstacle within {p.max_allowed_time_to_collision_up_to_carrot:.1f} s"
                ),
            )
        return ControlResult(True, v, w)

    def _lookahead_point(self, path: NDArray[np.float64], dist: float) -> NDArray[np.float64]:
        d = np.hypot(path[:, 0], path[:, 1])
        far = np.nonzero(d >= dist)[0]
        if len(far) == 0:
            return np.array(path[-1, :2], dtype=np.float64)
        i = int(far[0])
        if i == 0:
            return np.array(path[0, :2], dtype=np.float64)
        return circle_segment_intersection(path[i - 1, :2], path[i, :2], dist)

    def _rotate(self, angle: float, w_now: float, dt: float) -> float:
        p = self.params
        w = math.copysign(p.rotate_to_heading_angular_vel, angle)
        return min(max(w, w_now - p.max_angular_accel * dt), w_now + p.max_angular_accel * dt)

    def _regulate(
        self,
        curvature: float,
        pose: Pose2D,
        costmap: Costmap2D,
        footprint: Footprint,
        path: NDArray[np.float64],
    ) -> float:
        p = self.params
        v = p.desired_linear_vel
        curv_v = cost_v = v
        if p.use_regulated_linear_velocity_scaling and curvature != 0:
            radius = abs(1.0 / curvature)
            if radius < p.regulated_linear_scaling_min_radius:
                curv_v = v * (
                    1.0
                    - abs(radius - p.regulated_linear_scaling_min_radius)
                    / p.regulated_linear_scaling_min_radius
                )
        if p.use_cost_regulated_linear_velocity_scaling:
            cell = costmap.world_to_map(pose[0], pose[1])
            cost = costmap.get_cost(*cell) if cell is not None else NO_INFORMATION
            if cost not in (NO_INFORMATION, FREE_SPACE):
                dist = (
                    -1.0
                    / p.inflation_cost_scaling_factor
                    * math.log(cost / (INSCRIBED_INFLATED_OBSTACLE - 1))
                    + footprint.inscribed_radius
                )
                if dist < p.cost_scaling_dist:
                    cost_v = v * p.cost_scaling_gain * dist / p.cost_scaling_dist
        v = max(min(curv_v, cost_v), p.regulated_linear_scaling_min_speed)
        remaining = float(np.hypot(*np.diff(path[:, :2], axis=0).T).sum()) if len(path) > 1 else 0.0
        if remaining < p.approach_velocity_scaling_dist:
            last = float(np.hypot(path[-1, 0], path[-1, 1]))
            approach = max(
                v * last / p.approach_velocity_scaling_dist, p.min_approach_linear_velocity
            )
            v = min(v, approach)
        return min(max(v, 0.0), p.desired_linear_vel)

    def _collision_ahead(
        self,
        pose: Pose2D,
        v: float,
        w: float,
        carrot_dist: float,
        costmap: Costmap2D,
        footprint: Footprint,
    ) -> bool:
        p = self.params
        if abs(v) < 0.01 and abs(w) > 0.01:
            step_t = (
                2.0
                * math.sin((costmap.resolution / 2) / max(footprint.circumscribed_radius, 1e-3))
                / abs(w)
            )
        elif abs(v) >= 0.01:
            step_t = costmap.resolution / abs(v)
        else:
            return footprint_in_collision(pose, costmap, footprint)
        if footprint_in_collision(pose, costmap, footprint):
            return True
        x = y = th = 0.0
        i = 1
        while i * step_t < p.max_allowed_time_to_collision_up_to_carrot:
            i += 1
            x += step_t * v * math.cos(th)
            y += step_t * v * math.sin(th)
            th += step_t * w
            if math.hypot(x, y) > carrot_dist:
                break
            if footprint_in_collision(compose_2d(pose, (x, y, th)), costmap, footprint):
                return True
        return False
