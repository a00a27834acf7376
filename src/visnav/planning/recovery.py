"""Recovery behaviours: clear costmaps, rotate in place, back up.

Each behaviour is a small state machine driven by the navigator's control loop
(move_base runs them as blocking calls): :meth:`Recovery.start`, then
:meth:`Recovery.step` every cycle until it reports done.

* :class:`ClearCostmapRecovery` (clear_costmap_recovery): resets the clearable layers
  (obstacle layers) of both costmaps outside a ``reset_distance`` square around the
  robot (3.0 m "conservative", ``4 x`` circumscribed radius "aggressive") and
  repaints them on the next update.
* :class:`RotateRecovery` (rotate_recovery): one full turn in place at
  ``sqrt(2 acc_lim_th * angle_left)`` clamped to [0.4, 1.0] rad/s, stopping within
  ``tolerance`` (0.1 rad) of the start; refused (ends) when the footprint would
  collide along the rest of the turn (``sim_granularity`` 0.017 rad).
* :class:`BackUpRecovery` (nav2's BackUp): drives backwards ``backup_dist`` (0.15 m) at
  ``backup_speed`` (0.025 m/s) within ``time_allowance`` (10 s), checking the footprint
  ``simulate_ahead_time`` (2 s) ahead.

Difference: a circular robot does not rotate in place while the centre of a lethal cell
lies more than one cell inside its radius (padded ``robot_radius``; one cell for the
grid's quantisation, so a robot stopped at the edge of the inscribed band, as DWA
leaves it, may still turn); rotate_recovery checks a 16-gon's outline for lethal cells
only, so it turns with an obstacle well inside the circle, where the longer robot the
circle stands for hits it (the car in the office, seed 5: BENCHMARKS.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from visnav.mapping.costmap_2d import Costmap2D
from visnav.mapping.layer import CostmapLayer
from visnav.mapping.layered_costmap import LayeredCostmap
from visnav.planning.local_planner import Pose2D, angle_diff, compose_2d, footprint_in_collision

__all__ = [
    "BackUpRecovery",
    "ClearCostmapRecovery",
    "Recovery",
    "RecoveryContext",
    "RecoveryStep",
    "RotateRecovery",
    "nearest_lethal",
]

_NS = 1_000_000_000


@dataclass
class RecoveryContext:
    """What a recovery behaviour sees each cycle."""

    now_ns: int
    pose_local: Pose2D
    pose_global: Pose2D
    velocity: tuple[float, float]
    local_costmap: LayeredCostmap
    global_costmap: LayeredCostmap


@dataclass
class RecoveryStep:
    """A behaviour's command for this cycle; ``done`` ends it (``failed`` says why, if so)."""

    v: float = 0.0
    w: float = 0.0
    done: bool = False
    failed: str = ""


class Recovery:
    """Base class of the recovery behaviours."""

    def __init__(self, name: str) -> None:
        self.name = name

    def start(self, ctx: RecoveryContext) -> None:
        """Begin (called once before the first step)."""

    def step(self, ctx: RecoveryContext) -> RecoveryStep:
        """One control cycle."""
        return RecoveryStep(done=True)


class ClearCostmapRecovery(Recovery):
    """Reset the clearable layers outside a square around the robot.

    Args:
        name: behaviour name.
        reset_distance: side of the square kept (metres).
        layer_names: layers to clear (default: every clearable layer).
    """

    def __init__(
        self,
        name: str = "conservative_reset",
        *,
        reset_distance: float = 3.0,
        layer_names: tuple[str, ...] = (),
    ) -> None:
        super().__init__(name)
        self.reset_distance = reset_distance
        self.layer_names = layer_names

    def step(self, ctx: RecoveryContext) -> RecoveryStep:
        """Clear both costmaps at once."""
        for cm, pose in (
            (ctx.global_costmap, ctx.pose_global),
            (ctx.local_costmap, ctx.pose_local),
        ):
            for layer in cm.layers:
                if not isinstance(layer, CostmapLayer) or not layer.is_clearable:
                    continue
                if self.layer_names and layer.name not in self.layer_names:
                    continue
                layer.clear_outside(pose[0], pose[1], self.reset_distance)
            cm.request_full_update()
        return RecoveryStep(done=True)


def nearest_lethal(costmap: Costmap2D, x: float, y: float, within: float) -> float:
    """Distance from ``(x, y)`` to the nearest lethal cell centre (inf beyond ``within``).

    The search covers the cells of the square of half-side ``within`` around the
    point (:meth:`Costmap2D.lethal_centres`), so a lethal centre slightly farther
    than ``within`` (a diagonal) may still be found.
    """
    cells = costmap.lethal_centres(x - within, y - within, x + within, y + within)
    if len(cells) == 0:
        return math.inf
    return float(np.hypot(cells[:, 0] - x, cells[:, 1] - y).min())


class RotateRecovery(Recovery):
    """Turn once in place (rotate_recovery)."""

    def __init__(
        self,
        name: str = "rotate_recovery",
        *,
        acc_lim_th: float = 3.2,
        max_rotational_vel: float = 1.0,
        min_rotational_vel: float = 0.4,
        tolerance: float = 0.10,
        sim_granularity: float = 0.017,
    ) -> None:
        super().__init__(name)
        self.acc_lim_th = acc_lim_th
        self.max_rotational_vel = max_rotational_vel
        self.min_rotational_vel = min_rotational_vel
        self.tolerance = tolerance
        self.sim_granularity = sim_granularity
        self._start_yaw = 0.0
        self._got_180 = False

    def start(self, ctx: RecoveryContext) -> None:
        """Remember the starting heading."""
        self._start_yaw = ctx.pose_local[2]
        self._got_180 = False

    def step(self, ctx: RecoveryContext) -> RecoveryStep:
        """Keep turning until a full turn is done (or a collision is ahead)."""
        x, y, yaw = ctx.pose_local
        current = angle_diff(yaw, self._start_yaw)
        if not self._got_180:
            to_180 = abs(angle_diff(current, math.pi))
            left = math.pi + to_180
            if to_180 < self.tolerance:
                self._got_180 = True
        else:
            left = abs(angle_diff(current, 0.0))
            if left < self.tolerance:
                return RecoveryStep(done=True)
        cm = ctx.local_costmap.costmap
        fp = ctx.local_costmap.footprint
        if fp.is_circular:
            # the circle usually stands for a longer robot (the car's chassis reaches
            # 0.30 m behind its centre): a full turn sweeps the whole circle, so an
            # obstacle well inside it would be hit (module docs)
            d = nearest_lethal(cm, x, y, fp.radius)
            if d < fp.radius - cm.resolution:
                return RecoveryStep(
                    done=True,
                    failed=(
                        f"cannot rotate in place: an obstacle lies {d:.2f} m from the robot's "
                        f"centre, inside its {fp.radius:.2f} m radius"
                    ),
                )
        else:
            n = max(1, int(left / self.sim_granularity))
            for k in range(n + 1):
                if footprint_in_collision((x, y, yaw + k * self.sim_granularity), cm, fp):
                    return RecoveryStep(
                        done=True,
                        failed="cannot rotate in place: the footprint would hit an obstacle",
                    )
        vel = math.sqrt(2 * self.acc_lim_th * left)
        vel = min(max(vel, self.min_rotational_vel), self.max_rotational_vel)
        return RecoveryStep(0.0, vel)


class BackUpRecovery(Recovery):
    """Drive straight backwards (nav2 BackUp)."""

    def __init__(
        self,
        name: str = "back_up",
        *,
        backup_dist: float = 0.15,
        backup_speed: float = 0.025,
        time_allowance: float = 10.0,
        simulate_ahead_time: float = 2.0,
    ) -> None:
        super().__init__(name)
        self.backup_dist = backup_dist
        self.backup_speed = backup_speed
        self.time_allowance = time_allowance
        self.simulate_ahead_time = simulate_ahead_time
        self._start: Pose2D = (0.0, 0.0, 0.0)
        self._t0 = 0

    def start(self, ctx: RecoveryContext) -> None:
        """Remember where the robot started."""
        self._start = ctx.pose_local
        self._t0 = ctx.now_ns

    def step(self, ctx: RecoveryContext) -> RecoveryStep:
        """Back up until the distance is covered, time runs out or a collision is ahead."""
        x, y, _ = ctx.pose_local
        moved = math.hypot(x - self._start[0], y - self._start[1])
        left = self.backup_dist - moved
        if left <= 0:
            return RecoveryStep(done=True)
        if (ctx.now_ns - self._t0) / _NS > self.time_allowance:
            return RecoveryStep(
                done=True, failed=f"backing up took longer than {self.time_allowance:.1f} s"
            )
        cm = ctx.local_costmap.costmap
        fp = ctx.local_costmap.footprint
        ahead = min(left, self.backup_speed * self.simulate_ahead_time)
        n = max(1, math.ceil(ahead / max(cm.resolution / 2, 1e-3)))
        for k in range(1, n + 1):
            pose = compose_2d(ctx.pose_local, (-ahead * k / n, 0.0, 0.0))
            if footprint_in_collision(pose, cm, fp):
                return RecoveryStep(
                    done=True, failed="cannot back up: an obstacle is behind the robot"
                )
        return RecoveryStep(-self.backup_speed, 0.0)
