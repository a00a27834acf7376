"""What local planners share: the interface, plan transformation, goal checks.

A local planner gets the global plan (``(x, y, yaw)`` poses in the global frame) with
:meth:`LocalPlanner.set_plan` and, every control cycle, the robot pose and velocity in
the local costmap's frame plus the 2D transform from the global frame into it; it
answers a :class:`ControlResult`.

:func:`transform_global_plan` follows base_local_planner's ``transformGlobalPlan``:
the plan is brought into the local frame, and only the first run of poses within
half the local costmap's larger side of the robot is kept; ``prune_plan`` then drops
the poses before the one closest to the robot (nav2's behaviour; base_local_planner
drops poses more than 1 m behind).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.costmap_2d import (
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Costmap2D,
)
from visnav.mapping.footprint import Footprint, transform_footprint

__all__ = [
    "ControlResult",
    "LocalPlanner",
    "Pose2D",
    "angle_diff",
    "compose_2d",
    "footprint_in_collision",
    "invert_2d",
    "transform_global_plan",
    "transform_poses",
]

Pose2D = tuple[float, float, float]
"""A planar pose ``(x, y, yaw)``."""


def angle_diff(a: float, b: float) -> float:
    """``a - b`` wrapped into ``(-pi, pi]``."""
    d = math.fmod(a - b, 2 * math.pi)
    if d <= -math.pi:
        d += 2 * math.pi
    elif d > math.pi:
        d -= 2 * math.pi
    return d


def compose_2d(a: Pose2D, b: Pose2D) -> Pose2D:
    """``a * b`` for planar transforms (``b`` expressed in ``a``)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def invert_2d(a: Pose2D) -> Pose2D:
    """The inverse of a planar transform."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-(c * a[0] + s * a[1]), -(-s * a[0] + c * a[1]), -a[2])


def transform_poses(poses: NDArray[np.float64], T: Pose2D) -> NDArray[np.float64]:  # noqa: N803
    """Apply the planar transform ``T`` to (N, 3) poses."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    c, s = math.cos(T[2]), math.sin(T[2])
    out = np.empty_like(p)
    out[:, 0] = T[0] + c * p[:, 0] - s * p[:, 1]
    out[:, 1] = T[1] + s * p[:, 0] + c * p[:, 1]
    out[:, 2] = p[:, 2] + T[2]
    return out


def transform_global_plan(
    plan: NDArray[np.float64],
    T_local_global: Pose2D,  # noqa: N803
    robot: Pose2D,
    costmap: Costmap2D,
    *,
    prune: bool = False,
) -> NDArray[np.float64]:
    """The part of the plan around the robot, in the local frame (see the module docs)."""
    local = transform_poses(plan, T_local_global)
    if len(local) == 0:
        return local
    d2 = (local[:, 0] - robot[0]) ** 2 + (local[:, 1] - robot[1]) ** 2
    thr = max(costmap.size_in_meters_x, costmap.size_in_meters_y) / 2.0
    inside = d2 <= thr * thr
    if not inside.any():
        return local[:0]
    first = int(np.argmax(inside))
    outside_after = np.nonzero(~inside[first:])[0]
    last = first + (int(outside_after[0]) if len(outside_after) else len(local) - first)
    out = local[first:last]
    if prune and len(out) > 1:
        k = int(np.argmin(d2[first:last]))
        out = out[k:]
    return out


@dataclass
class ControlResult:
    """A velocity command ``(v, w)`` or why there is none.

    Attributes:
        ok: a valid command was found.
        v: forward velocity (m/s).
        w: yaw rate (rad/s).
        reason: why not ok (empty when ok).
        trajectory: the chosen trajectory ``(x, y, yaw)`` rows, when the planner has one.
    """

    ok: bool
    v: float = 0.0
    w: float = 0.0
    reason: str = ""
    trajectory: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 3)))


class LocalPlanner(Protocol):
    """The local planner interface (nav_core's ``BaseLocalPlanner``, planar)."""

    def set_plan(self, plan: NDArray[np.float64]) -> None:
        """Take a new global plan (global frame)."""

    def compute_velocity(
        self,
        pose: Pose2D,
        velocity: tuple[float, float],
        costmap: Costmap2D,
        footprint: Footprint,
        T_local_global: Pose2D,  # noqa: N803
    ) -> ControlResult:
        """One control cycle: pose and velocity in the local frame."""
        ...

    def is_goal_reached(self, pose: Pose2D, velocity: tuple[float, float]) -> bool:
        """Whether the robot (pose in the global frame) is at the plan's end and stopped."""
        ...

    def reset(self) -> None:
        """Forget the plan and any latched state."""


def footprint_in_collision(pose: Pose2D, costmap: Costmap2D, footprint: Footprint) -> bool:
    """Whether the footprint at ``pose`` hits an obstacle (leaving the map counts).

    A circular robot collides when its centre cell is inscribed or lethal (unknown is
    not a collision); a polygon when a lethal cell lies on its outline.
    """
    if footprint.is_circular:
        cell = costmap.world_to_map(pose[0], pose[1])
        if cell is None:
            return True
        cost = costmap.get_cost(*cell)
        return INSCRIBED_INFLATED_OBSTACLE <= cost < NO_INFORMATION
    pts = transform_footprint(footprint.perimeter, *pose)
    costs = costmap.costs_at(pts, outside=LETHAL_OBSTACLE)
    return bool((costs == LETHAL_OBSTACLE).any())
