"""DWA local planner (dwa_local_planner with base_local_planner's critics), vectorised.

Every control cycle (``controller_frequency``, 20 Hz):

1. **Samples** (``SimpleTrajectoryGenerator`` with ``use_dwa``): ``vx_samples`` x
   ``vth_samples`` velocities evenly spaced in the window reachable
   within one control period, ``v +- acc_lim * sim_period``, clamped to
   ``[min_vel, max_vel]`` (0 inserted between negative and positive samples, as
   ``VelocityIterator``). A sample below both ``min_vel_trans`` and ``min_vel_theta``, or
   above ``max_vel_trans``, is dropped.
2. **Rollouts**: each sample is held for ``sim_time`` (1.7 s) in
   ``ceil(max(|v| T / sim_granularity, |w| T / angular_sim_granularity))`` Euler steps.
   All trajectories are simulated at once as (samples x steps) arrays.
3. **Critics** (a trajectory is dropped if any returns a failure):

   * obstacles (``occdist_scale`` 0.01): the largest footprint cost along the
     trajectory; a lethal / inscribed / unknown cell under a circular robot, a lethal or
     unknown cell on a polygon's outline, or leaving the map, is a collision; for a
     circular robot a point in an inscribed cell collides only when the point itself
     lies closer to the nearest lethal cell centre than the inscribed radius (or than
     the robot does, when the robot is closer already: it may turn or move away);
   * path (``path_distance_bias`` 32 x resolution) and goal (``goal_distance_bias`` 24 x
     resolution): 4-connected cell distance from the trajectory's end to the plan
     cells and to the local goal (the last plan pose in the local costmap), through
     free cells (``MapGrid``);
   * alignment and goal-front (same scales): the same distances for a point
     ``forward_point_distance`` (0.325 m) ahead of the trajectory's end, against the
     plan and a goal pushed that far beyond the real one; they never reject, and the
     alignment term is off within ``forward_point_distance`` of the goal;
   * oscillation: once the robot reverses its choice of forward / backward or left /
     right rotation, the opposite direction is refused until it has moved
     ``oscillation_reset_dist`` (0.05 m) or turned ``oscillation_reset_angle`` (0.2 rad);
   * twirling (``twirling_scale`` 0): ``|w|``.

   The cheapest trajectory wins (the first on ties).
4. **At the goal** (``LatchedStopRotateController``): within ``xy_goal_tolerance`` (0.1 m)
   the robot brakes within its acceleration limits, then turns in place to the goal's
   yaw (``yaw_goal_tolerance`` 0.1 rad) at a speed that lets it stop there. The goal is
   reached when both tolerances hold and the robot is stopped
   (``trans_stopped_vel`` / ``theta_stopped_vel`` 0.1).

Differences: a differential-drive base only (dwa_local_planner's ``max_vel_y`` /
``min_vel_y`` / ``acc_lim_y`` / ``vy_samples``, 0.1 / -0.1 / 2.5 / 10 for a holonomic PR2,
are not parameters here: no ``vy`` is sampled); a circular robot is checked as an exact
circle instead of a 16-gon's outline: a point collides in a lethal cell, and in an
inscribed cell when it lies within the inscribed radius of a lethal cell's centre (ROS's
outline check lets the centre into the inscribed band; checking only the cost of the
point's cell (what this planner did at first) quantises the radius by up to a cell
diagonal both ways, and a car stopped 0.36-0.37 m from a corner, at the edge of the band
where DWA's rollouts at rest leave it, found every rollout "colliding" and waited 17 s
for the recovery behaviours: seed 5 with the map in the local costmap); the stop and rotate
commands are checked for collisions only (dwa scores them with every critic); the plan is
densified to the costmap resolution once per cycle (``adjustPlanResolution``); a new plan
to the same goal keeps the xy latch (dwa_local_planner resets it on every ``setPlan``,
i.e. on every move_base replan at ``planner_frequency``: a robot that drifts a centimetre
while turning in place at the edge of ``xy_goal_tolerance`` then drives back and turns
again, round and round until the oscillation timeout; nav2's ``SimpleGoalChecker`` with
``stateful: true`` keeps it likewise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from visnav.mapping.costmap_2d import (
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Costmap2D,
)
from visnav.mapping.footprint import Footprint
from visnav.planning._mapgrid import grid_distances
from visnav.planning.errors import PlanningError
from visnav.planning.local_planner import (
    ControlResult,
    Pose2D,
    angle_diff,
    transform_global_plan,
    transform_poses,
)

__all__ = ["DWAParams", "DWAPlanner", "velocity_samples"]


@dataclass(frozen=True)
class DWAParams:
    """dwa_local_planner parameters and defaults, for a differential-drive base.

    The holonomic ones (``max_vel_y``, ``min_vel_y``, ``acc_lim_y``, ``vy_samples``) are
    absent: visnav samples no ``vy``, so a launch file setting them gets the
    unknown-parameter warning instead of a value that does nothing.
    """

    max_vel_trans: float = 0.55
    min_vel_trans: float = 0.1
    max_vel_x: float = 0.55
    min_vel_x: float = 0.0
    max_vel_theta: float = 1.0
    min_vel_theta: float = 0.4
    acc_lim_x: float = 2.5
    acc_lim_theta: float = 3.2
    xy_goal_tolerance: float = 0.1
    yaw_goal_tolerance: float = 0.1
    latch_xy_goal_tolerance: bool = False
    trans_stopped_vel: float = 0.1
    theta_stopped_vel: float = 0.1
    sim_time: float = 1.7
    sim_granularity: float = 0.025
    angular_sim_granularity: float = 0.1
    path_distance_bias: float = 32.0
    goal_distance_bias: float = 24.0
    occdist_scale: float = 0.01
    twirling_scale: float = 0.0
    oscillation_reset_dist: float = 0.05
    oscillation_reset_angle: float = 0.2
    forward_point_distance: float = 0.325
    scaling_speed: float = 0.25
    max_scaling_factor: float = 0.2
    vx_samples: int = 3
    vth_samples: int = 20
    use_dwa: bool = True
    prune_plan: bool = False
    controller_frequency: float = 20.0

    def __post_init__(self) -> None:
        for name in (
            "sim_time",
            "sim_granularity",
            "angular_sim_granularity",
            "controller_frequency",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                msg = f"DWA parameter {name} is {v}; expected a finite value > 0"
                raise PlanningError(msg)
        if self.min_vel_x > self.max_vel_x:
            msg = (
                f"DWA velocity limits: min_vel_x {self.min_vel_x} / max_vel_x {self.max_vel_x}; "
                "expected min <= max"
            )
            raise PlanningError(msg)

    @property
    def sim_period(self) -> float:
        """One control period (1 / controller_frequency)."""
        return 1.0 / self.controller_frequency


def velocity_samples(lo: float, hi: float, n: int) -> NDArray[np.float64]:
    """``VelocityIterator``: ``n`` (>= 2) evenly spaced values, 0 inserted across zero."""
    if lo == hi:
        return np.array([lo])
    n = max(2, n)
    step = (hi - lo) / (n - 1)
    out: list[float] = []
    nxt = lo
    for _ in range(n - 1):
        cur = nxt
        nxt += step
        out.append(cur)
        if cur < 0 < nxt:
            out.append(0.0)
    out.append(hi)
    return np.array(out)


def _densify(poses: NDArray[np.float64], step: float) -> NDArray[np.float64]:
    if len(poses) < 2:
        return poses
    d = np.hypot(*np.diff(poses[:, :2], axis=0).T)
    n = np.maximum(1, np.ceil(d / step).astype(np.int64))
    if (n == 1).all():
        return poses
    t = np.concatenate([np.arange(k) / k for k in n])
    seg = np.repeat(np.arange(len(n)), n)
    xy = poses[seg, :2] + t[:, None] * (poses[seg + 1, :2] - poses[seg, :2])
    out = np.empty((len(xy) + 1, 3))
    out[:-1, :2] = xy
    out[:-1, 2] = poses[seg, 2]
    out[-1] = poses[-1]
    return out


class _Oscillation:
    def __init__(self) -> None:
        self.reset()
        self.prev = (0.0, 0.0, 0.0)

    def reset(self) -> None:
        self.fwd_pos = self.fwd_neg = self.fwd_pos_only = self.fwd_neg_only = False
        self.rot_pos = self.rot_neg = self.rot_pos_only = self.rot_neg_only = False

    def allowed(self, v: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.bool_]:
        bad = (
            (self.fwd_pos_only & (v < 0))
            | (self.fwd_neg_only & (v > 0))
            | (self.rot_pos_only & (w < 0))
            | (self.rot_neg_only & (w > 0))
        )
        return ~bad

    def update(self, pose: Pose2D, v: float, w: float, min_vel_trans: float, p: DWAParams) -> None:
        flag = False
        if v < 0:
            if self.fwd_pos:
                self.fwd_neg_only = flag = True
            self.fwd_pos, self.fwd_neg = False, True
        if v > 0:
            if self.fwd_neg:
                self.fwd_pos_only = flag = True
            self.fwd_neg, self.fwd_pos = False, True
        if abs(v) <= min_vel_trans:
            if w < 0:
                if self.rot_pos:
                    self.rot_neg_only = flag = True
                self.rot_pos, self.rot_neg = False, True
            if w > 0:
                if self.rot_neg:
                    self.rot_pos_only = flag = True
                self.rot_neg, self.rot_pos = False, True
        if flag:
            self.prev = pose
        if self.fwd_pos_only or self.fwd_neg_only or self.rot_pos_only or self.rot_neg_only:
            d = math.hypot(pose[0] - self.prev[0], pose[1] - self.prev[1])
            turned = abs(angle_diff(pose[2], self.prev[2]))
            if d > p.oscillation_reset_dist or turned > p.oscillation_reset_angle:
                self.reset()


class DWAPlanner:
    """The Dynamic Window Approach local planner.

    Args:
        params: planner parameters.
    """

    def __init__(self, params: DWAParams | None = None) -> None:
        self.params = params or DWAParams()
        self.plan: NDArray[np.float64] = np.empty((0, 3))
        self._osc = _Oscillation()
        self._xy_latched = False
        self._rotating = False
        self.last_samples = 0

    def set_plan(self, plan: NDArray[np.float64]) -> None:
        """Take a new global plan (global frame).

        Resets the oscillation flags, and the goal latch when the plan ends at another
        goal (see the module docs).
        """
        new = np.asarray(plan, dtype=np.float64).reshape(-1, 3)
        same_goal = (
            len(new) > 0
            and len(self.plan) > 0
            and bool(np.allclose(new[-1], self.plan[-1], rtol=0.0, atol=1e-9))
        )
        self.plan = new
        if not same_goal:
            self._xy_latched = False
            self._rotating = False
        self._osc.reset()

    def reset(self) -> None:
        """Forget the plan."""
        self.set_plan(np.empty((0, 3)))

    # ------------------------------------------------------------------ goal
    def _position_reached(self, pose: Pose2D, goal: NDArray[np.float64]) -> bool:
        d = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
        return self._xy_latched or d <= self.params.xy_goal_tolerance

    def _stopped(self, velocity: tuple[float, float]) -> bool:
        p = self.params
        return abs(velocity[0]) <= p.trans_stopped_vel and abs(velocity[1]) <= p.theta_stopped_vel

    def is_goal_reached(self, pose: Pose2D, velocity: tuple[float, float]) -> bool:
        """Position and yaw tolerances hold (pose in the global frame) and the robot is stopped."""
        if len(self.plan) == 0:
            return False
        goal = self.plan[-1]
        if not self._position_reached(pose, goal):
            return False
        yaw_ok = abs(angle_diff(float(goal[2]), pose[2])) <= self.params.yaw_goal_tolerance
        return yaw_ok and self._stopped(velocity)

    # ------------------------------------------------------------------ control
    def compute_velocity(
        self,
        pose: Pose2D,
        velocity: tuple[float, float],
        costmap: Costmap2D,
        footprint: Footprint,
        T_local_global: Pose2D,  # noqa: N803
    ) -> ControlResult:
        """One cycle: the best ``(v, w)`` for the robot at ``pose`` (local frame)."""
        p = self.params
        if len(self.plan) == 0:
            return ControlResult(False, reason="the local planner has no plan")
        local = transform_global_plan(self.plan, T_local_global, pose, costmap, prune=p.prune_plan)
        if len(local) == 0:
            return ControlResult(
                False,
                reason="no pose of the global plan lies within the local costmap around the robot",
            )
        goal = transform_poses(self.plan[-1:], T_local_global)[0]
        if self._position_reached(pose, goal):
            if p.latch_xy_goal_tolerance:
                self._xy_latched = True
            return self._stop_rotate(pose, velocity, float(goal[2]), costmap, footprint)
        self._rotating = False
        return self._find_best(
            pose, velocity, _densify(local, costmap.resolution), costmap, footprint
        )

    def _stop_rotate(
        self,
        pose: Pose2D,
        velocity: tuple[float, float],
        goal_yaw: float,
        costmap: Costmap2D,
        footprint: Footprint,
    ) -> ControlResult:
        p = self.params
        dt = p.sim_period
        diff = angle_diff(goal_yaw, pose[2])
        if abs(diff) <= p.yaw_goal_tolerance:
            self._rotating = False
            return ControlResult(True, 0.0, 0.0)
        v, w = velocity
        if not self._rotating and not self._stopped(velocity):
            nv = math.copysign(max(0.0, abs(v) - p.acc_lim_x * dt), v)
            nw = math.copysign(max(0.0, abs(w) - p.acc_lim_theta * dt), w)
            if self._collision_free(pose, nv, nw, costmap, footprint):
                return ControlResult(True, nv, nw)
            return ControlResult(False, reason="braking at the goal would collide")
        self._rotating = True
        sign = 1.0 if diff > 0 else -1.0
        mag = min(p.max_vel_theta, max(p.min_vel_theta, abs(diff)))
        lo = abs(w) - p.acc_lim_theta * dt
        hi = abs(w) + p.acc_lim_theta * dt
        mag = min(max(mag, lo), hi)
        mag = min(math.sqrt(2 * p.acc_lim_theta * abs(diff)), mag)
        mag = min(p.max_vel_theta, max(p.min_vel_theta, mag))
        if self._collision_free(pose, 0.0, sign * mag, costmap, footprint):
            return ControlResult(True, 0.0, sign * mag)
        return ControlResult(False, reason="rotating to the goal's yaw would collide")

    def _collision_free(
        self, pose: Pose2D, v: float, w: float, costmap: Costmap2D, footprint: Footprint
    ) -> bool:
        xs, ys, ths, mask, _ = self._rollout(pose, np.array([v]), np.array([w]))
        if not mask.any():
            return True
        ok, _ = self._obstacle_costs(
            xs, ys, ths, mask, np.array([v]), costmap, footprint, robot=(pose[0], pose[1])
        )
        return bool(ok[0])

    def _samples(
        self, velocity: tuple[float, float]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        p = self.params
        v, w = velocity
        span = p.sim_period if p.use_dwa else p.sim_time
        vx = velocity_samples(
            max(p.min_vel_x, v - p.acc_lim_x * span),
            min(p.max_vel_x, v + p.acc_lim_x * span),
            p.vx_samples,
        )
        vth = velocity_samples(
            max(-p.max_vel_theta, w - p.acc_lim_theta * span),
            min(p.max_vel_theta, w + p.acc_lim_theta * span),
            p.vth_samples,
        )
        mv, mw = np.meshgrid(vx, vth, indexing="ij")
        gv, gw = mv.ravel(), mw.ravel()
        eps = 1e-4
        keep = ~(
            (p.min_vel_trans >= 0)
            & (np.abs(gv) + eps < p.min_vel_trans)
            & (p.min_vel_theta >= 0)
            & (np.abs(gw) + eps < p.min_vel_theta)
        )
        if p.max_vel_trans >= 0:
            keep &= np.abs(gv) - eps <= p.max_vel_trans
        return gv[keep], gw[keep]

    def _rollout(
        self, pose: Pose2D, v: NDArray[np.float64], w: NDArray[np.float64]
    ) -> tuple[
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.bool_],
        NDArray[np.int64],
    ]:
        p = self.params
        steps = np.ceil(
            np.maximum(
                np.abs(v) * p.sim_time / p.sim_granularity,
                np.abs(w) * p.sim_time / p.angular_sim_granularity,
            )
            - 1e-9
        ).astype(np.int64)
        m = int(steps.max()) if len(steps) else 0
        k = np.arange(max(m, 1))
        dt = np.where(steps > 0, p.sim_time / np.maximum(steps, 1), 0.0)
        mask = k[None, :] < steps[:, None]
        ths = pose[2] + (w * dt)[:, None] * k[None, :]
        dx = (v * dt)[:, None] * np.cos(ths)
        dy = (v * dt)[:, None] * np.sin(ths)
        xs = pose[0] + np.concatenate(
            [np.zeros((len(v), 1)), np.cumsum(dx, axis=1)[:, :-1]], axis=1
        )
        ys = pose[1] + np.concatenate(
            [np.zeros((len(v), 1)), np.cumsum(dy, axis=1)[:, :-1]], axis=1
        )
        return xs, ys, ths, mask, steps

    def _obstacle_costs(
        self,
        xs: NDArray[np.float64],
        ys: NDArray[np.float64],
        ths: NDArray[np.float64],
        mask: NDArray[np.bool_],
        v: NDArray[np.float64],
        costmap: Costmap2D,
        footprint: Footprint,
        *,
        robot: tuple[float, float],
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
        """(valid, max cost) per trajectory; ``robot`` is the robot's position."""
        centre = costmap.costs_at(np.stack([xs[mask], ys[mask]], axis=1), outside=NO_INFORMATION)
        cost = np.zeros(xs.shape, np.int64)
        cost[mask] = centre
        _, _, inside = costmap.world_to_map_array(np.stack([xs[mask], ys[mask]], axis=1))
        off = np.zeros(xs.shape, np.bool_)
        off[mask] = ~inside
        if footprint.is_circular:
            bad = np.zeros(xs.shape, np.bool_)
            bad[mask] = _circle_collisions(
                xs[mask], ys[mask], centre, costmap, footprint, robot=robot
            )
        else:
            p = self.params
            per = footprint.perimeter
            vmag = np.abs(v)
            scale = np.where(
                vmag > p.scaling_speed,
                1.0
                + p.max_scaling_factor
                * (vmag - p.scaling_speed)
                / max(p.max_vel_trans - p.scaling_speed, 1e-9),
                1.0,
            )
            si, ki = np.nonzero(mask)
            c, s = np.cos(ths[si, ki]), np.sin(ths[si, ki])
            px = per[None, :, 0] * scale[si][:, None]
            py = per[None, :, 1] * scale[si][:, None]
            wx = xs[si, ki][:, None] + c[:, None] * px - s[:, None] * py
            wy = ys[si, ki][:, None] + s[:, None] * px + c[:, None] * py
            pc = costmap.costs_at(np.stack([wx.ravel(), wy.ravel()], axis=1)).reshape(wx.shape)
            outline_bad = ((pc == LETHAL_OBSTACLE) | (pc == NO_INFORMATION)).any(axis=1)
            outline_max = np.where(pc == NO_INFORMATION, 0, pc).max(axis=1)
            bad = np.zeros(xs.shape, np.bool_)
            bad[si, ki] = outline_bad
            cost[si, ki] = np.maximum(np.where(centre == NO_INFORMATION, 0, centre), outline_max)
        invalid = np.asarray((bad | off).any(axis=1), dtype=np.bool_)
        worst: NDArray[np.float64] = np.where(mask, cost, 0).max(axis=1).astype(np.float64)
        return ~invalid, worst

    def _find_best(
        self,
        pose: Pose2D,
        velocity: tuple[float, float],
        local: NDArray[np.float64],
        costmap: Costmap2D,
        footprint: Footprint,
    ) -> ControlResult:
        p = self.params
        v, w = self._samples(velocity)
        self.last_samples = len(v)
        if len(v) == 0:
            return ControlResult(False, reason="no velocity sample satisfies the limits")
        xs, ys, ths, mask, steps = self._rollout(pose, v, w)
        good = steps > 0
        valid, occ = self._obstacle_costs(
            xs, ys, ths, mask, v, costmap, footprint, robot=(pose[0], pose[1])
        )
        valid &= good & self._osc.allowed(v, w)
        fields = _Fields(costmap, local, pose, p.forward_point_distance)
        if fields.targets == 0:
            return ControlResult(
                False, reason="the plan has no cell inside the known local costmap"
            )
        last = np.maximum(steps - 1, 0)
        idx = np.arange(len(v))
        lx, ly, lth = xs[idx, last], ys[idx, last], ths[idx, last]
        path_d, path_ok = fields.lookup(fields.path, lx, ly, strict=True)
        goal_d, goal_ok = fields.lookup(fields.goal, lx, ly, strict=True)
        fpd = p.forward_point_distance
        fx, fy = lx + fpd * np.cos(lth), ly + fpd * np.sin(lth)
        align_d, align_ok = fields.lookup(fields.path, fx, fy, strict=False)
        front_d, front_ok = fields.lookup(fields.front, fx, fy, strict=False)
        valid &= path_ok & goal_ok & align_ok & front_ok
        res = costmap.resolution
        pdist = p.path_distance_bias * res
        gdist = p.goal_distance_bias * res
        align_scale = pdist if fields.goal_sq_dist > fpd * fpd else 0.0
        total = (
            pdist * path_d
            + gdist * goal_d
            + p.occdist_scale * occ
            + align_scale * align_d
            + gdist * front_d
            + p.twirling_scale * np.abs(w)
        )
        total = np.where(valid, total, np.inf)
        best = int(np.argmin(total))
        if not np.isfinite(total[best]):
            return ControlResult(
                False,
                reason=(
                    f"all {len(v)} DWA trajectories collide, leave the local costmap or lose "
                    "the plan"
                ),
            )
        self._osc.update(pose, float(v[best]), float(w[best]), p.min_vel_trans, p)
        n = int(steps[best])
        traj = np.stack([xs[best, :n], ys[best, :n], ths[best, :n]], axis=1)
        return ControlResult(True, float(v[best]), float(w[best]), trajectory=traj)


class _Fields:
    """The three MapGrid distance fields of one cycle (path, local goal, goal front)."""

    def __init__(
        self, costmap: Costmap2D, plan: NDArray[np.float64], pose: Pose2D, fpd: float
    ) -> None:
        h, w = costmap.data.shape
        self.costmap = costmap
        self.obstacle = h * w
        self.unreachable = h * w + 1
        run = _first_known_run(costmap, plan[:, :2])
        self.targets = len(run)
        if not len(run):
            return
        data = costmap.data
        self.path = grid_distances(data, run, self.obstacle, self.unreachable)
        self.goal = grid_distances(data, run[-1:], self.obstacle, self.unreachable)
        g = plan[-1]
        self.goal_sq_dist = (g[0] - pose[0]) ** 2 + (g[1] - pose[1]) ** 2
        ang = math.atan2(g[1] - pose[1], g[0] - pose[0])
        front = plan[:, :2].copy()
        front[-1] += fpd * np.array([math.cos(ang), math.sin(ang)])
        frun = _first_known_run(costmap, front)
        self.front = (
            grid_distances(data, frun[-1:], self.obstacle, self.unreachable)
            if len(frun)
            else self.goal
        )

    def lookup(
        self,
        field: NDArray[np.int32],
        x: NDArray[np.float64],
        y: NDArray[np.float64],
        *,
        strict: bool,
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        mx, my, inside = self.costmap.world_to_map_array(np.stack([x, y], axis=1))
        d = np.full(x.shape, float(self.unreachable))
        d[inside] = field[my[inside], mx[inside]]
        ok = inside.copy()
        if strict:
            # an end in an inscribed cell passed the exact-circle check: it is as far
            # from the plan as its nearest neighbour outside the band, plus one cell
            data = self.costmap.data
            h, w = data.shape
            for k in np.nonzero(inside & (d >= self.obstacle))[0]:
                cx, cy = int(mx[k]), int(my[k])
                if data[cy, cx] != INSCRIBED_INFLATED_OBSTACLE:
                    continue
                nb = field[max(cy - 1, 0) : min(cy + 2, h), max(cx - 1, 0) : min(cx + 2, w)]
                free = nb[nb < self.obstacle]
                if len(free):
                    d[k] = float(free.min()) + 1.0
            ok &= d < self.obstacle
        return d, ok


def _circle_collisions(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    cost: NDArray[np.uint8],
    costmap: Costmap2D,
    footprint: Footprint,
    *,
    robot: tuple[float, float],
) -> NDArray[np.bool_]:
    """Which trajectory points collide for a circular robot (module docs).

    ``x``, ``y`` are the points, ``cost`` their cells' costs, ``robot`` the robot's
    position. A lethal, unknown or off-map cell collides; a point in an inscribed
    cell collides when it lies closer to the nearest lethal cell centre than the
    inscribed radius, or than the robot's position does if that is closer already.
    """
    bad = cost > INSCRIBED_INFLATED_OBSTACLE
    band = cost == INSCRIBED_INFLATED_OBSTACLE
    if not band.any():
        return bad
    reach = footprint.inscribed_radius + costmap.resolution
    px = np.concatenate([[robot[0]], x[band]])
    py = np.concatenate([[robot[1]], y[band]])
    cells = costmap.lethal_centres(
        float(px.min()) - reach,
        float(py.min()) - reach,
        float(px.max()) + reach,
        float(py.max()) + reach,
    )
    if len(cells) == 0:  # inscribed by an obstacle that has left the map since: keep the cost
        bad |= band
        return bad
    d, _ = cKDTree(cells).query(np.stack([px, py], axis=1))
    limit = min(footprint.inscribed_radius, float(d[0]))
    bad[band] = d[1:] < limit - 1e-9
    return bad


def _first_known_run(costmap: Costmap2D, xy: NDArray[np.float64]) -> NDArray[np.int64]:
    """Cells of the first run of plan points inside the map and not unknown (``MapGrid``)."""
    mx, my, inside = costmap.world_to_map_array(xy)
    known = inside.copy()
    known[inside] = costmap.data[my[inside], mx[inside]] != NO_INFORMATION
    if not known.any():
        return np.empty((0, 2), np.int64)
    first = int(np.argmax(known))
    after = np.nonzero(~known[first:])[0]
    last = first + (int(after[0]) if len(after) else len(known) - first)
    return np.stack([mx[first:last], my[first:last]], axis=1).astype(np.int64)
