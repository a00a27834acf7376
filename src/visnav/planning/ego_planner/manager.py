"""ego-planner's planner manager (``plan_manage/planner_manager.cpp``): one replan, start to end.

:meth:`PlannerManager.rebound_replan` turns a start state and a local target into
a new local trajectory:

1. **Initial path.** From a quintic polynomial start -> target (on the first call,
   after a new goal, or when asked; with a random middle waypoint when earlier
   attempts failed), sampled every ``ts`` (shrunk by 1.5 until consecutive samples
   are within ``1.5 * control_points_distance`` and there are at least 7); or from
   the rest of the current trajectory, extended to the target by a quintic and
   resampled every ``control_points_distance`` of arc length. ``ts`` starts at
   ``1.2 * control_points_distance / max_vel``.
2. **Fit and optimise.** The points become a uniform cubic B-spline
   (:func:`~visnav.planning.ego_planner.bspline.parameterize_to_bspline`), get
   their ``{p, v}`` pairs and go through the rebound optimisation.
3. **Time re-allocation and refinement.** When a velocity or acceleration control
   point exceeds the limits (5 % tolerance) the time is stretched by
   ``ratio = max(v / max_vel, sqrt(a / max_acc))``, the curve resampled and
   refitted, and the refinement pulls it back to the stretched shape within the
   limits.

The global trajectory (for choosing local targets) is a minimum-snap polynomial
through the start, the goal(s) and points inserted every 4 m.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from visnav.planning.ego_planner.astar import AStar
from visnav.planning.ego_planner.bspline import UniformBspline, parameterize_to_bspline
from visnav.planning.ego_planner.optimizer import BsplineOptimizer, OptimizerParams
from visnav.planning.ego_planner.polynomial import PolynomialTraj
from visnav.planning.errors import PlanningError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from visnav.mapping.grid_map import GridMap

__all__ = [
    "GlobalTrajectory",
    "LocalTrajectory",
    "PlannerError",
    "PlannerManager",
    "PlannerParams",
    "ReplanRecord",
    "warm_up",
]

_NS = 1_000_000_000


class PlannerError(PlanningError):
    """Invalid planner parameters or inputs."""


@dataclass(frozen=True, kw_only=True)
class PlannerParams:
    """ego-planner's ``manager/...`` parameters.

    Upstream's ``manager/max_jerk`` is read there and never used (its B-spline limits are
    velocity and acceleration only), so it is not a parameter here.

    Attributes:
        max_vel: Velocity limit per axis (m/s).
        max_acc: Acceleration limit per axis (m/s^2).
        control_points_distance: Spacing of the initial path's points (m).
        feasibility_tolerance: Relative excess tolerated before re-allocating time.
        planning_horizon: Length of the local plan (m).
    """

    max_vel: float = 2.0
    max_acc: float = 3.0
    control_points_distance: float = 0.4
    feasibility_tolerance: float = 0.05
    planning_horizon: float = 7.5

    def __post_init__(self) -> None:
        for name in ("max_vel", "max_acc", "control_points_distance", "planning_horizon"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                msg = f"manager: {name} is {value!r}; expected a value > 0"
                raise PlannerError(msg)


@dataclass
class LocalTrajectory:
    """The trajectory being executed (ego-planner's ``LocalTrajData``).

    Attributes:
        position: Position B-spline.
        velocity: Its derivative.
        acceleration: Its second derivative.
        start_time_ns: When its time 0 is (graph clock).
        duration: Its duration (s).
        start_pos: Its first point.
        traj_id: Increments with every new trajectory.
    """

    position: UniformBspline
    velocity: UniformBspline
    acceleration: UniformBspline
    start_time_ns: int
    duration: float
    start_pos: NDArray[np.float64]
    traj_id: int

    @classmethod
    def from_spline(
        cls, position: UniformBspline, start_time_ns: int, traj_id: int
    ) -> LocalTrajectory:
        """Wrap a position spline starting at ``start_time_ns``."""
        vel = position.derivative()
        return cls(
            position=position,
            velocity=vel,
            acceleration=vel.derivative(),
            start_time_ns=int(start_time_ns),
            duration=position.duration,
            start_pos=position.evaluate(0.0),
            traj_id=int(traj_id),
        )

    def elapsed(self, now_ns: int) -> float:
        """Seconds since the start (may exceed the duration)."""
        return (now_ns - self.start_time_ns) / _NS


@dataclass
class GlobalTrajectory:
    """The global reference (ego-planner's ``GlobalTrajData``).

    Attributes:
        traj: The polynomial.
        start_time_ns: When it was planned.
        last_progress_time: Time along it of the nearest point reached so far (s).
    """

    traj: PolynomialTraj
    start_time_ns: int
    last_progress_time: float = 0.0

    @property
    def duration(self) -> float:
        """Its duration (s)."""
        return self.traj.duration


@dataclass(frozen=True)
class ReplanRecord:
    """Timing and outcome of one :meth:`PlannerManager.rebound_replan` call.

    Attributes:
        success: Whether a new trajectory was made.
        total_s: Wall time of the call (s).
        init_s: Initial path, fit and pairs (s).
        optimize_s: Rebound optimisation (s).
        refine_s: Feasibility check, re-allocation and refinement (s).
        reason: Why it failed ("" on success).
        refined: Whether time was re-allocated.
    """

    success: bool
    total_s: float
    init_s: float = 0.0
    optimize_s: float = 0.0
    refine_s: float = 0.0
    reason: str = ""
    refined: bool = False


@dataclass
class _Init:
    points: NDArray[np.float64]
    derivatives: NDArray[np.float64]
    ts: float


class PlannerManager:
    """Plans local trajectories on a grid map (``EGOPlannerManager``).

    Args:
        grid_map: The map.
        params: Manager parameters.
        optimizer: Optimiser parameters (``max_vel`` / ``max_acc`` should match ``params``).
        seed: Seed of the random initial paths.
        astar_pool: A* nodes along x, y, z.
    """

    def __init__(
        self,
        grid_map: GridMap,
        params: PlannerParams | None = None,
        optimizer: OptimizerParams | None = None,
        *,
        seed: int = 0,
        astar_pool: tuple[int, int, int] = (100, 100, 100),
    ) -> None:
        self.grid_map = grid_map
        self.params = params or PlannerParams()
        opt = optimizer or OptimizerParams(max_vel=self.params.max_vel, max_acc=self.params.max_acc)
        self.astar = AStar(astar_pool, max_expansions=opt.max_astar_expansions)
        self.optimizer = BsplineOptimizer(grid_map, self.astar, opt)
        self.local: LocalTrajectory | None = None
        self.global_traj: GlobalTrajectory | None = None
        self.continuous_failures = 0
        self.records: list[ReplanRecord] = []
        self._rng = np.random.default_rng(seed)
        self._first_call = True
        self._force_polynomial = False
        self._traj_id = 0

    # ------------------------------------------------------------------ global
    def plan_global_trajectory(
        self,
        start_pos: ArrayLike,
        start_vel: ArrayLike,
        start_acc: ArrayLike,
        waypoints: ArrayLike,
        end_vel: ArrayLike,
        end_acc: ArrayLike,
        *,
        now_ns: int,
    ) -> bool:
        """Plan the global reference through ``(K, 3)`` waypoints (``planGlobalTraj*``).

        Points are inserted every ``max(total / 8, 4)`` m for several waypoints
        and every 4 m for one goal; piece times are ``length / max_vel``,
        doubled for the first and the last.

        Returns:
            Whether a trajectory was made.
        """
        start = np.asarray(start_pos, dtype=np.float64).reshape(3)
        wps = np.asarray(waypoints, dtype=np.float64).reshape(-1, 3)
        if wps.shape[0] == 0:
            return False
        points = np.vstack([start, wps])
        lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
        thresh = max(float(lengths.sum()) / 8.0, 4.0) if wps.shape[0] > 1 else 4.0
        inter = [points[0]]
        for i in range(points.shape[0] - 1):
            if lengths[i] > thresh:
                n = math.floor(lengths[i] / thresh) + 1
                inter.extend(points[i] + (points[i + 1] - points[i]) * (j / n) for j in range(1, n))
            inter.append(points[i + 1])
        pos = np.array(inter)
        keep = np.concatenate([[True], np.linalg.norm(np.diff(pos, axis=0), axis=1) > 1e-6])
        pos = pos[keep]
        if pos.shape[0] < 2:
            return False
        times = np.linalg.norm(np.diff(pos, axis=0), axis=1) / self.params.max_vel
        times[0] *= 2.0
        times[-1] *= 2.0
        if pos.shape[0] == 2:
            traj = PolynomialTraj.one_segment(
                pos[0], start_vel, start_acc, pos[1], end_vel, end_acc, float(times[0])
            )
        else:
            traj = PolynomialTraj.min_snap(pos, start_vel, end_vel, start_acc, end_acc, times)
        self.global_traj = GlobalTrajectory(traj, int(now_ns))
        return True

    # ------------------------------------------------------------------ local
    def emergency_stop(self, stop_pos: ArrayLike, *, now_ns: int) -> None:
        """Replace the trajectory by one standing at ``stop_pos`` (``EmergencyStop``)."""
        ctrl = np.repeat(np.asarray(stop_pos, dtype=np.float64).reshape(1, 3), 6, axis=0)
        self._set_local(UniformBspline(ctrl, 3, 1.0), now_ns)

    def _set_local(self, spline: UniformBspline, now_ns: int) -> None:
        self._traj_id += 1
        self.local = LocalTrajectory.from_spline(spline, now_ns, self._traj_id)

    def _poly_init(
        self,
        start: NDArray[np.float64],
        vel: NDArray[np.float64],
        acc: NDArray[np.float64],
        target: NDArray[np.float64],
        target_vel: NDArray[np.float64],
        ts: float,
        *,
        random_poly: bool,
    ) -> _Init:
        p = self.params
        dist = float(np.linalg.norm(start - target))
        v, a = p.max_vel, p.max_acc
        duration = math.sqrt(dist / a) if v * v / a > dist else (dist - v * v / a) / v + 2 * v / a
        zero = np.zeros(3)
        if not random_poly:
            poly = PolynomialTraj.one_segment(start, vel, acc, target, target_vel, zero, duration)
        else:
            diff = start - target
            horizontal = np.cross(diff, [0.0, 0.0, 1.0])
            horizontal /= max(float(np.linalg.norm(horizontal)), 1e-12)
            vertical = np.cross(diff, horizontal)
            vertical /= max(float(np.linalg.norm(vertical)), 1e-12)
            spread = -0.978 / (self.continuous_failures + 0.989) + 0.989
            middle = (
                (start + target) / 2
                + (self._rng.random() - 0.5) * dist * horizontal * 0.8 * spread
                + (self._rng.random() - 0.5) * dist * vertical * 0.4 * spread
            )
            poly = PolynomialTraj.min_snap(
                np.array([start, middle, target]),
                vel,
                target_vel,
                acc,
                zero,
                [duration / 2, duration / 2],
            )
        ts *= 1.5
        while True:
            ts /= 1.5
            times = np.arange(0.0, duration, ts)
            pts = poly.evaluate(times)
            gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            if pts.shape[0] >= 7 and not np.any(gaps > p.control_points_distance * 1.5):
                break
        t_last = float(times[-1])
        der = np.array(
            [poly.evaluate_vel(0.0), target_vel, poly.evaluate_acc(0.0), poly.evaluate_acc(t_last)]
        )
        return _Init(pts, der, ts)

    def _continue_init(
        self,
        local: LocalTrajectory,
        target: NDArray[np.float64],
        target_vel: NDArray[np.float64],
        ts: float,
        now_ns: int,
    ) -> _Init | None:
        p = self.params
        t_cur = local.elapsed(now_ns)
        times = np.arange(t_cur, local.duration + 1e-3, ts)
        if times.size == 0:
            times = np.array([min(t_cur, local.duration)])
        seg = local.position.evaluate(times)
        t_last = float(times[-1])
        end = local.position.evaluate(t_last)
        poly_time = float(np.linalg.norm(end - target)) / p.max_vel * 2
        if poly_time > ts:
            poly = PolynomialTraj.one_segment(
                end,
                local.velocity.evaluate(t_last),
                local.acceleration.evaluate(t_last),
                target,
                target_vel,
                np.zeros(3),
                poly_time,
            )
            seg = np.vstack([seg, poly.evaluate(np.arange(ts, poly_time, ts))])
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(seg, axis=0), axis=1))])
        spacing = p.control_points_distance * 1.5
        while True:
            spacing /= 1.5
            samples = np.arange(0.0, arc[-1], spacing) if arc[-1] > 0 else np.zeros(1)
            pts = np.column_stack([np.interp(samples, arc, seg[:, k]) for k in range(3)])
            pts = np.vstack([pts, target])
            if pts.shape[0] >= 7:
                break
        if pts.shape[0] > p.planning_horizon / p.control_points_distance * 3:
            return None  # abnormally long: regenerate from a polynomial
        der = np.array(
            [
                local.velocity.evaluate(t_cur),
                target_vel,
                local.acceleration.evaluate(t_cur),
                np.zeros(3),
            ]
        )
        return _Init(pts, der, ts)

    def rebound_replan(
        self,
        start_pt: ArrayLike,
        start_vel: ArrayLike,
        start_acc: ArrayLike,
        target_pt: ArrayLike,
        target_vel: ArrayLike,
        *,
        now_ns: int,
        poly_init: bool,
        random_poly: bool = False,
    ) -> bool:
        """Plan a new local trajectory from a start state to a local target (``reboundReplan``).

        Args:
            start_pt: Start position.
            start_vel: Start velocity.
            start_acc: Start acceleration.
            target_pt: Local target.
            target_vel: Velocity at the local target.
            now_ns: Current graph time; the new trajectory starts then.
            poly_init: Start from a polynomial instead of the current trajectory.
            random_poly: Pass the polynomial through a random middle point.

        Returns:
            Whether :attr:`local` was replaced. A :class:`ReplanRecord` is appended
            to :attr:`records` either way.
        """
        t0 = time.perf_counter()
        start = np.asarray(start_pt, dtype=np.float64).reshape(3)
        vel = np.asarray(start_vel, dtype=np.float64).reshape(3)
        acc = np.asarray(start_acc, dtype=np.float64).reshape(3)
        target = np.asarray(target_pt, dtype=np.float64).reshape(3)
        tvel = np.asarray(target_vel, dtype=np.float64).reshape(3)
        p = self.params
        if float(np.linalg.norm(start - target)) < 0.2:
            self.continuous_failures += 1
            return self._record(False, t0, reason="close to the goal")
        ts0 = (
            p.control_points_distance
            / p.max_vel
            * (1.2 if np.linalg.norm(start - target) > 0.1 else 5.0)
        )
        init: _Init | None = None
        while init is None:
            local = self.local
            if self._first_call or poly_init or self._force_polynomial or local is None:
                self._first_call = False
                self._force_polynomial = False
                init = self._poly_init(start, vel, acc, target, tvel, ts0, random_poly=random_poly)
            else:
                init = self._continue_init(local, target, tvel, ts0, now_ns)
                if init is None:
                    self._force_polynomial = True
        ts = init.ts
        ctrl = parameterize_to_bspline(ts, init.points, init.derivatives)
        self.optimizer.init_control_points(ctrl, first=True)
        t1 = time.perf_counter()
        result = self.optimizer.optimize_rebound(ctrl, ts)
        t2 = time.perf_counter()
        if not result.success:
            self.continuous_failures += 1
            return self._record(False, t0, t1, t2, reason=result.reason)
        spline = UniformBspline(result.control_points, 3, ts)
        feasible, ratio = spline.check_feasibility(p.max_vel, p.max_acc, p.feasibility_tolerance)
        refined = False
        if not feasible:
            refined = True
            ok, spline = self._refine(spline, init.derivatives, ratio)
            if not ok:
                self.continuous_failures += 1
                return self._record(
                    False, t0, t1, t2, reason="the refined trajectory hits obstacles", refined=True
                )
        self._set_local(spline, now_ns)
        self.continuous_failures = 0
        return self._record(True, t0, t1, t2, refined=refined)

    def _refine(
        self, spline: UniformBspline, derivatives: NDArray[np.float64], ratio: float
    ) -> tuple[bool, UniformBspline]:
        """Re-allocate time by ``ratio`` and refine (``refineTrajAlgo`` + ``reparamBspline``)."""
        seg_num = spline.control_points.shape[0] - 3
        longer = spline.lengthen_time(ratio)
        duration = longer.duration
        dt = duration / seg_num
        pts = longer.evaluate(np.arange(0.0, duration + 1e-4, dt))
        ctrl = parameterize_to_bspline(dt, pts, derivatives)
        reparam = UniformBspline(ctrl, 3, dt)
        step = reparam.duration / (ctrl.shape[0] - 3)
        ref = reparam.evaluate(np.arange(0.0, reparam.duration + 1e-4, step))
        result = self.optimizer.optimize_refine(ctrl, dt, ref)
        return result.success, UniformBspline(result.control_points, 3, dt)

    def _record(
        self,
        success: bool,
        t0: float,
        t1: float | None = None,
        t2: float | None = None,
        *,
        reason: str = "",
        refined: bool = False,
    ) -> bool:
        t3 = time.perf_counter()
        t1 = t3 if t1 is None else t1
        t2 = t3 if t2 is None else t2
        self.records.append(
            ReplanRecord(success, t3 - t0, t1 - t0, t2 - t1, t3 - t2, reason, refined)
        )
        return success


def warm_up(params: PlannerParams | None = None) -> float:
    """Run every numba kernel of planning once on a tiny map (compile or load their caches).

    numba compiles a kernel on its first call in a process, or loads it from the
    on-disk cache (tens of milliseconds each). A planner node calls this at start
    so that its first replans in flight take their usual time.

    Returns:
        The wall time spent (s).
    """
    from visnav.mapping.grid_map import GridMap, GridMapParams  # noqa: PLC0415

    t0 = time.perf_counter()
    gm = GridMap(GridMapParams(map_size=(8.0, 4.0, 2.0), virtual_ceil_height=1.8))
    sensor = np.array([-3.0, 0.0, 1.0])
    gm.update_from_points(np.array([[0.0, 0.05, 1.0]]), sensor_origin=sensor)
    pose = np.eye(4)
    pose[:3, :3] = [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
    pose[:3, 3] = sensor
    for depth in (np.full((8, 8), 2.0, np.float32), np.full((8, 8), 2000, np.uint16)):
        gm.update_from_depth(depth, intrinsics=(4.0, 4.0, 4.0, 4.0), T_world_camera=pose)
    th = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    column = [
        (0.3 * np.cos(a), 0.05 + 0.3 * np.sin(a), z) for a in th for z in np.arange(0.0, 2.0, 0.1)
    ]
    gm.mark_occupied(column)
    gm.occupancy(column[:2])
    manager = PlannerManager(gm, params, astar_pool=(40, 40, 20))
    start, goal = np.array([-3.0, 0.0, 1.0]), np.array([3.0, 0.0, 1.0])
    zero = np.zeros(3)
    manager.rebound_replan(start, zero, zero, goal, zero, now_ns=0, poly_init=True)
    local = manager.local
    if local is not None:
        manager.rebound_replan(
            local.position.evaluate(0.5),
            local.velocity.evaluate(0.5),
            zero,
            goal,
            zero,
            now_ns=500_000_000,
            poly_init=False,
        )
    # the rebound of a polygon through the column, and the refinement
    line = np.linspace(start, goal, 14)
    ctrl = parameterize_to_bspline(0.4, line, np.zeros((4, 3)))
    opt = manager.optimizer
    opt.init_control_points(ctrl, first=True)
    opt.counts[:] = 0  # pretend the pairs are unknown, so that a rebound is needed
    opt.add_rebound_pairs(ctrl.copy())
    knots = np.arange(ctrl.shape[0] - 2) * 0.4
    opt.optimize_refine(ctrl, 0.4, UniformBspline(ctrl, 3, 0.4).evaluate(knots))
    manager.emergency_stop(start, now_ns=0)
    return time.perf_counter() - t0
