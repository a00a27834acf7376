"""ego-planner's B-spline optimiser (``bspline_optimizer.cpp``): rebound and refinement runs.

* :meth:`BsplineOptimizer.optimize_rebound` minimises
  ``lambda_smooth * smoothness + lambda_collision * distance + lambda_feasibility *
  feasibility`` over the free control points (all but ``order`` at each end) with
  L-BFGS (memory 16, 200 iterations, gradient tolerance 0.01). Once the
  trajectory is smooth (smoothness per free point below 0.1, after three
  evaluations) every evaluation looks for obstacles the ``{p, v}`` pairs do not
  know; finding one cancels the run, adds pairs by A* (a *rebound*) and restarts
  (at most 20 rebounds). A result whose first two thirds still hit the inflated
  map gets new pairs and a doubled collision weight (at most 3 restarts); a hit
  within the first interval fails the plan.
* :meth:`BsplineOptimizer.optimize_refine` (after time re-allocation) minimises
  ``lambda_smooth * smoothness + lambda_fitness * fitness + lambda_feasibility *
  feasibility`` (tolerance 0.001) and fails when the result hits the map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

from visnav.planning.ego_planner import lbfgs, rebound
from visnav.planning.ego_planner.bspline import UniformBspline
from visnav.planning.ego_planner.costs import (
    distance_cost,
    feasibility_cost,
    fitness_cost,
    smoothness_cost,
)
from visnav.planning.errors import PlanningError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from visnav.mapping.grid_map import GridMap
    from visnav.planning.ego_planner.astar import AStar

__all__ = ["BsplineOptimizer", "OptimizeResult", "OptimizerError", "OptimizerParams"]


class OptimizerError(PlanningError):
    """Invalid optimiser parameters or inputs."""


@dataclass(frozen=True, kw_only=True)
class OptimizerParams:
    """ego-planner's ``optimization/...`` parameters, plus the solver settings it hard-codes.

    Attributes:
        lambda_smooth: Weight of the jerk smoothness term.
        lambda_collision: Weight of the rebound collision term.
        lambda_feasibility: Weight of the velocity/acceleration term.
        lambda_fitness: Weight of the refinement's fitting term.
        dist0: Clearance ``s_f`` each control point keeps beyond its obstacles (m).
        max_vel: Velocity limit per axis (m/s).
        max_acc: Acceleration limit per axis (m/s^2).
        order: B-spline degree.
        mem_size: L-BFGS memory.
        max_iterations: L-BFGS iterations per run.
        g_epsilon_rebound: Gradient tolerance of the rebound runs.
        g_epsilon_refine: Gradient tolerance of the refinement.
        max_linesearch: Evaluations per line search.
        max_restarts: Restarts after a colliding result.
        max_rebounds: Rebounds per optimisation.
        max_pairs: Pairs kept per control point (visnav's fixed capacity).
        max_astar_expansions: Node budget of each A* search.
    """

    lambda_smooth: float = 1.0
    lambda_collision: float = 0.5
    lambda_feasibility: float = 0.1
    lambda_fitness: float = 1.0
    dist0: float = 0.5
    max_vel: float = 2.0
    max_acc: float = 3.0
    order: int = 3
    mem_size: int = 16
    max_iterations: int = 200
    g_epsilon_rebound: float = 0.01
    g_epsilon_refine: float = 0.001
    max_linesearch: int = 40
    max_restarts: int = 3
    max_rebounds: int = 20
    max_pairs: int = 64
    max_astar_expansions: int = 200_000

    def __post_init__(self) -> None:
        positive = ("dist0", "max_vel", "max_acc")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                msg = f"optimization: {name} is {value!r}; expected a value > 0"
                raise OptimizerError(msg)
        for name in ("lambda_smooth", "lambda_collision", "lambda_feasibility", "lambda_fitness"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                msg = f"optimization: {name} is {value!r}; expected a weight >= 0"
                raise OptimizerError(msg)
        if self.order != 3:
            msg = f"optimization: order is {self.order}; only cubic B-splines (3) are supported"
            raise OptimizerError(msg)


@dataclass(frozen=True)
class OptimizeResult:
    """Outcome of one optimisation.

    Attributes:
        success: Whether the result is usable.
        control_points: The optimised ``(N, 3)`` control points.
        reason: Why it failed ("" on success).
        evaluations: Cost evaluations over all runs.
        rebounds: Runs cancelled to add pairs.
        restarts: Runs restarted after a colliding result.
    """

    success: bool
    control_points: NDArray[np.float64]
    reason: str = ""
    evaluations: int = 0
    rebounds: int = 0
    restarts: int = 0


@numba.njit(cache=True)
def _set_free(q: np.ndarray, x: np.ndarray, order: int) -> None:
    k = 0
    for i in range(order, q.shape[0] - order):
        for c in range(3):
            q[i, c] = x[k]
            k += 1


@numba.njit(cache=True)
def _get_free(g: np.ndarray, out: np.ndarray, order: int) -> None:
    k = 0
    for i in range(order, g.shape[0] - order):
        for c in range(3):
            out[k] = g[i, c]
            k += 1


@numba.njit(cache=True)
def _rebound_cost(x: np.ndarray, grad: np.ndarray, data: tuple, n_eval: int) -> tuple[float, int]:  # type: ignore[type-arg]
    (
        q,
        gbuf,
        order,
        ts,
        w_s,
        w_c,
        w_f,
        max_vel,
        max_acc,
        clearance,
        base,
        dirs,
        counts,
        inflate,
        origin,
        res,
        dims,
    ) = data
    _set_free(q, x, order)
    gbuf[:] = 0.0
    f_s = smoothness_cost(q, gbuf, w_s)
    if n_eval > 3 and f_s / (q.shape[0] - 2 * order) < 0.1:
        status = rebound.detect_new_obstacle(
            q, order, base, dirs, counts, inflate, origin, res, dims
        )
        if status != 0:
            return np.inf, status
    f_d = distance_cost(q, gbuf, w_c, base, dirs, counts, clearance, order)
    f_f = feasibility_cost(q, gbuf, w_f, ts, max_vel, max_acc)
    _get_free(gbuf, grad, order)
    return w_s * f_s + w_c * f_d + w_f * f_f, 0


@numba.njit(cache=True)
def _refine_cost(x: np.ndarray, grad: np.ndarray, data: tuple, n_eval: int) -> tuple[float, int]:  # type: ignore[type-arg]
    q, gbuf, order, ts, w_s, w_fit, w_f, max_vel, max_acc, ref_pts = data
    _set_free(q, x, order)
    gbuf[:] = 0.0
    f_s = smoothness_cost(q, gbuf, w_s)
    f_fit = fitness_cost(q, gbuf, w_fit, ref_pts, order)
    f_f = feasibility_cost(q, gbuf, w_f, ts, max_vel, max_acc)
    _get_free(gbuf, grad, order)
    return w_s * f_s + w_fit * f_fit + w_f * f_f, 0


@numba.njit(cache=True)
def _minimize_rebound(
    x: np.ndarray,
    data: tuple,  # type: ignore[type-arg]
    mem: int,
    max_it: int,
    g_eps: float,
    max_ls: int,
) -> tuple[float, int, int, int]:
    """L-BFGS on :func:`_rebound_cost`: ``(f, status, evaluations, iterations)``."""
    n = x.shape[0]
    ws = lbfgs.workspace(n, mem)
    g = np.empty(n)
    f, stop = _rebound_cost(x, g, data, 0)
    evals = 1
    if stop != 0:
        return f, lbfgs.CANCELED, evals, 0
    action = lbfgs.start(ws, x, f, g, g_eps)
    while action == lbfgs.EVALUATE:
        f, stop = _rebound_cost(x, g, data, evals)
        evals += 1
        if stop != 0:
            return f, lbfgs.CANCELED, evals, lbfgs.result_iterations(ws)
        action = lbfgs.iterate(ws, x, f, g, max_it, g_eps, max_ls)
    return lbfgs.result_f(ws), lbfgs.result_status(ws), evals, lbfgs.result_iterations(ws)


@numba.njit(cache=True)
def _minimize_refine(
    x: np.ndarray,
    data: tuple,  # type: ignore[type-arg]
    mem: int,
    max_it: int,
    g_eps: float,
    max_ls: int,
) -> tuple[float, int, int, int]:
    """L-BFGS on :func:`_refine_cost`: ``(f, status, evaluations, iterations)``."""
    n = x.shape[0]
    ws = lbfgs.workspace(n, mem)
    g = np.empty(n)
    f, _stop = _refine_cost(x, g, data, 0)
    evals = 1
    action = lbfgs.start(ws, x, f, g, g_eps)
    while action == lbfgs.EVALUATE:
        f, _stop = _refine_cost(x, g, data, evals)
        evals += 1
        action = lbfgs.iterate(ws, x, f, g, max_it, g_eps, max_ls)
    return lbfgs.result_f(ws), lbfgs.result_status(ws), evals, lbfgs.result_iterations(ws)


class BsplineOptimizer:
    """The optimiser and its ``{p, v}`` pairs, on a grid map with an A* searcher.

    Args:
        grid_map: The map (its inflated buffer is read live).
        astar: The A* searcher (its buffers are reused).
        params: Parameters.
    """

    def __init__(
        self, grid_map: GridMap, astar: AStar, params: OptimizerParams | None = None
    ) -> None:
        self.grid_map = grid_map
        self.astar = astar
        self.params = params or OptimizerParams()
        self.base_points = np.zeros((0, self.params.max_pairs, 3))
        self.directions = np.zeros((0, self.params.max_pairs, 3))
        self.counts = np.zeros(0, dtype=np.int64)
        self._flag = np.zeros(0, dtype=np.bool_)
        self.clearance = self.params.dist0

    def _grid(self) -> tuple[NDArray[np.uint8], NDArray[np.float64], float, NDArray[np.int64]]:
        v = self.grid_map.view()
        return v.inflate, v.origin, v.resolution, v.dims

    def _astar(
        self,
    ) -> tuple[
        NDArray[np.int64],
        NDArray[np.float64],
        NDArray[np.int64],
        NDArray[np.int64],
        NDArray[np.int64],
        int,
        int,
    ]:
        a = self.astar
        return a.pool, a.g_score, a.parent, a.seen, a.closed, a.round_id, a.max_expansions

    # ------------------------------------------------------------------ pairs
    def init_control_points(self, control_points: ArrayLike, *, first: bool = True) -> int:
        """Add pairs for the colliding stretches of ``control_points`` (``initControlPoints``).

        Args:
            control_points: ``(N, 3)`` control points.
            first: Forget earlier pairs first (a new trajectory).

        Returns:
            How many stretches got pairs.
        """
        q = _control_points(control_points)
        if first or self.counts.shape[0] != q.shape[0]:
            n = q.shape[0]
            self.base_points = np.zeros((n, self.params.max_pairs, 3))
            self.directions = np.zeros((n, self.params.max_pairs, 3))
            self.counts = np.zeros(n, dtype=np.int64)
            self._flag = np.zeros(n, dtype=np.bool_)
            self.clearance = self.params.dist0
        pool, g, parent, seen, closed, round_id, max_exp = self._astar()
        used, round_id = rebound.init_control_points(
            q,
            self.params.order,
            self.base_points,
            self.directions,
            self.counts,
            self._flag,
            pool,
            g,
            parent,
            seen,
            closed,
            round_id,
            max_exp,
            *self._grid(),
        )
        self.astar.round_id = int(round_id)
        return int(used)

    def add_rebound_pairs(self, control_points: NDArray[np.float64]) -> int:
        """Add pairs for obstacles the pairs do not know yet (``check_collision_and_rebound``).

        Returns:
            0 nothing new, 1 pairs added, 2 the trajectory ends inside an obstacle,
            3 no A* path around the new obstacles.
        """
        q = _control_points(control_points)
        if self.counts.shape[0] != q.shape[0]:
            msg = (
                f"rebound: {q.shape[0]} control points but pairs for {self.counts.shape[0]}; "
                "call init_control_points() for a new trajectory first"
            )
            raise OptimizerError(msg)
        pool, g, parent, seen, closed, round_id, max_exp = self._astar()
        status, round_id = rebound.rebound(
            q,
            self.params.order,
            self.base_points,
            self.directions,
            self.counts,
            self._flag,
            pool,
            g,
            parent,
            seen,
            closed,
            round_id,
            max_exp,
            *self._grid(),
        )
        self.astar.round_id = int(round_id)
        return int(status)

    # ------------------------------------------------------------------ checks
    def first_collision_time(self, traj: UniformBspline) -> float | None:
        """Earliest time in the first two thirds of ``traj`` that hits the inflated map.

        Samples are about one resolution apart along the chord (ego-planner's step).
        """
        duration = traj.duration
        ends = traj.evaluate(np.array([0.0, duration]))
        chord = float(np.linalg.norm(ends[1] - ends[0]))
        res = self.grid_map.resolution
        n = max(2, math.ceil(chord / res))
        times = np.arange(0.0, duration * 2.0 / 3.0, duration / n)
        if times.size == 0:
            return None
        hits = self.grid_map.inflate_occupancy(traj.evaluate(times))
        if not hits.any():
            return None
        return float(times[int(np.argmax(hits))])

    # ------------------------------------------------------------------ runs
    def optimize_rebound(self, control_points: ArrayLike, ts: float) -> OptimizeResult:
        """The rebound optimisation of ``control_points`` (pairs from :meth:`init_control_points`).

        Returns:
            The result; ``control_points`` holds the last iterate even on failure.
        """
        p = self.params
        q = _control_points(control_points).copy()
        if self.counts.shape[0] != q.shape[0]:
            self.init_control_points(q, first=True)
        order = p.order
        gbuf = np.zeros_like(q)
        w_c = p.lambda_collision
        restarts = rebounds = evals = 0
        while True:
            data = (
                q,
                gbuf,
                order,
                float(ts),
                p.lambda_smooth,
                w_c,
                p.lambda_feasibility,
                p.max_vel,
                p.max_acc,
                self.clearance,
                self.base_points,
                self.directions,
                self.counts,
                *self._grid(),
            )
            x = np.ascontiguousarray(q[order : q.shape[0] - order].ravel())
            _f, status, n_eval, _it = _minimize_rebound(
                x,
                data,
                p.mem_size,
                p.max_iterations,
                p.g_epsilon_rebound,
                p.max_linesearch,
            )
            evals += int(n_eval)
            q[order : q.shape[0] - order] = x.reshape(-1, 3)
            if status == lbfgs.CANCELED:
                rebounds += 1
                outcome = self.add_rebound_pairs(q)
                if outcome == rebound.TERMINAL_IN_OBSTACLE:
                    why = "the trajectory ends inside an obstacle"
                    return OptimizeResult(False, q, why, evals, rebounds, restarts)
                if outcome == rebound.NO_WAY_AROUND:
                    why = "no A* path around a new obstacle"
                    return OptimizeResult(False, q, why, evals, rebounds, restarts)
                if rebounds > p.max_rebounds:
                    return OptimizeResult(
                        False, q, f"more than {p.max_rebounds} rebounds", evals, rebounds, restarts
                    )
                continue
            if status not in (lbfgs.CONVERGENCE, lbfgs.MAXIMUM_ITERATION, lbfgs.ALREADY_MINIMIZED):
                return OptimizeResult(
                    False, q, f"solver: {lbfgs.status_text(status)}", evals, rebounds, restarts
                )
            hit = self.first_collision_time(UniformBspline(q, order, ts))
            if hit is None:
                return OptimizeResult(True, q, "", evals, rebounds, restarts)
            if hit <= ts:
                return OptimizeResult(
                    False, q, "the first control points are in obstacles", evals, rebounds, restarts
                )
            restarts += 1
            if restarts >= p.max_restarts:
                return OptimizeResult(
                    False, q, "still colliding after restarts", evals, rebounds, restarts
                )
            self.init_control_points(q, first=False)
            w_c *= 2.0

    def optimize_refine(
        self, control_points: ArrayLike, ts: float, ref_pts: ArrayLike
    ) -> OptimizeResult:
        """The refinement: fit ``ref_pts`` (one per knot) smoothly within the limits.

        Returns:
            The result; unsuccessful when the refined trajectory hits the map.
        """
        p = self.params
        q = _control_points(control_points).copy()
        ref = np.ascontiguousarray(np.asarray(ref_pts, dtype=np.float64))
        if ref.ndim != 2 or ref.shape[1] != 3 or ref.shape[0] < q.shape[0] - 2:
            msg = f"refine: ref_pts have shape {ref.shape}; expected ({q.shape[0] - 2}, 3) or more"
            raise OptimizerError(msg)
        order = p.order
        gbuf = np.zeros_like(q)
        data = (
            q,
            gbuf,
            order,
            float(ts),
            p.lambda_smooth,
            p.lambda_fitness,
            p.lambda_feasibility,
            p.max_vel,
            p.max_acc,
            ref,
        )
        x = np.ascontiguousarray(q[order : q.shape[0] - order].ravel())
        _f, status, n_eval, _it = _minimize_refine(
            x,
            data,
            p.mem_size,
            p.max_iterations,
            p.g_epsilon_refine,
            p.max_linesearch,
        )
        q[order : q.shape[0] - order] = x.reshape(-1, 3)
        hit = self.first_collision_time(UniformBspline(q, order, ts))
        if hit is not None:
            return OptimizeResult(False, q, "the refined trajectory hits obstacles", int(n_eval))
        if status not in (lbfgs.CONVERGENCE, lbfgs.MAXIMUM_ITERATION, lbfgs.ALREADY_MINIMIZED):
            # upstream only logs solver errors here; the result is used when it is clear
            return OptimizeResult(True, q, f"solver: {lbfgs.status_text(status)}", int(n_eval))
        return OptimizeResult(True, q, "", int(n_eval))


def _control_points(points: ArrayLike) -> NDArray[np.float64]:
    q = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
    if q.ndim != 2 or q.shape[1] != 3 or q.shape[0] < 7:
        msg = f"control points have shape {q.shape}: expected (N >= 7, 3)"
        raise OptimizerError(msg)
    return q
