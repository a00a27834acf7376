"""B-splines of ego-planner (``bspline_opt/uniform_bspline.cpp``): evaluation, derivatives, limits.

A B-spline of order ``p`` with control points ``P_0 .. P_n`` and knots
``u_0 .. u_{n+p+1}`` is defined on ``[u_p, u_{n+1}]``; ego-planner's knots are
uniform, ``u_i = (i - p) * ts``, so the curve starts at time 0 and lasts
``(n + 1 - p) * ts``. :meth:`UniformBspline.lengthen_time` makes them
non-uniform (the middle knots stretch), and every method handles that.

On a uniform cubic B-spline the velocity, acceleration and jerk control points
are ``(P_{i+1} - P_i) / ts``, ``(P_{i+2} - 2 P_{i+1} + P_i) / ts^2`` and the third
difference over ``ts^3``; the curve stays inside the convex hull of the ``p + 1``
control points of each span, which is what makes control-point costs bound the
whole trajectory.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, overload

import numba
import numpy as np

from visnav.planning.errors import PlanningError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["BsplineError", "UniformBspline", "parameterize_to_bspline"]


class BsplineError(PlanningError):
    """Invalid B-spline inputs."""


@numba.njit(cache=True)
def _deboor(ctrl: np.ndarray, knots: np.ndarray, p: int, times: np.ndarray) -> np.ndarray:
    """Evaluate at absolute parameters ``times`` (clamped to the valid span) by de Boor."""
    n_ctrl, dim = ctrl.shape
    m = n_ctrl + p  # index of the last knot
    lo, hi = knots[p], knots[m - p]
    out = np.empty((times.shape[0], dim))
    d = np.empty((p + 1, dim))
    for j in range(times.shape[0]):
        u = min(max(times[j], lo), hi)
        k = p
        while knots[k + 1] < u and k < m - p - 1:
            k += 1
        for i in range(p + 1):
            d[i] = ctrl[k - p + i]
        for r in range(1, p + 1):
            for i in range(p, r - 1, -1):
                den = knots[i + 1 + k - r] - knots[i + k - p]
                alpha = 0.0 if den == 0.0 else (u - knots[i + k - p]) / den
                for c in range(dim):
                    d[i, c] = (1.0 - alpha) * d[i - 1, c] + alpha * d[i, c]
        out[j] = d[p]
    return out


class UniformBspline:
    """A B-spline trajectory (ego-planner's ``UniformBspline``), time starting at 0.

    Args:
        control_points: ``(N, D)`` control points, ``N > order``.
        order: Degree ``p`` (3 for ego-planner's cubic splines).
        interval: Knot spacing ``ts`` (s).
        knots: Explicit knot vector of ``N + order + 1`` non-decreasing values
            (overrides ``interval``); the curve's time 0 is ``knots[order]``.

    Raises:
        BsplineError: Too few control points, a non-positive interval or bad knots.
    """

    def __init__(
        self,
        control_points: ArrayLike,
        order: int = 3,
        interval: float = 0.1,
        *,
        knots: ArrayLike | None = None,
    ) -> None:
        ctrl = np.asarray(control_points, dtype=np.float64)
        if ctrl.ndim == 1:
            ctrl = ctrl[:, None]
        if ctrl.ndim != 2 or ctrl.shape[0] <= order or order < 0:
            msg = (
                f"B-spline of order {order} got control points of shape {ctrl.shape}: "
                f"expected (N, D) with N > {order}"
            )
            raise BsplineError(msg)
        self.control_points = np.ascontiguousarray(ctrl)
        self.order = int(order)
        n_knots = ctrl.shape[0] + order + 1
        if knots is None:
            if not (math.isfinite(interval) and interval > 0):
                msg = f"B-spline interval is {interval}: expected a time step > 0 s"
                raise BsplineError(msg)
            self.knots = (np.arange(n_knots, dtype=np.float64) - order) * float(interval)
            self.interval = float(interval)
        else:
            k = np.asarray(knots, dtype=np.float64)
            if k.shape != (n_knots,) or np.any(np.diff(k) < 0):
                msg = (
                    f"B-spline knots have shape {k.shape}: expected {n_knots} non-decreasing values"
                )
                raise BsplineError(msg)
            self.knots = np.ascontiguousarray(k)
            self.interval = float(interval)

    # ------------------------------------------------------------------ span
    @property
    def t_start(self) -> float:
        """Absolute parameter of the curve's time 0 (``knots[order]``)."""
        return float(self.knots[self.order])

    @property
    def duration(self) -> float:
        """Length of the valid span (s), ego-planner's ``getTimeSum``."""
        return float(self.knots[-1 - self.order] - self.knots[self.order])

    # ------------------------------------------------------------------ evaluation
    @overload
    def evaluate(self, t: float) -> NDArray[np.float64]: ...
    @overload
    def evaluate(self, t: NDArray[np.float64]) -> NDArray[np.float64]: ...

    def evaluate(self, t: float | NDArray[np.float64]) -> NDArray[np.float64]:
        """Value at time ``t`` from the start (``evaluateDeBoorT``), clamped to the span.

        Args:
            t: A time or an array of times (s).

        Returns:
            ``(D,)`` for a scalar time, ``(M, D)`` for ``M`` times.
        """
        times = np.atleast_1d(np.asarray(t, dtype=np.float64)) + self.t_start
        out: NDArray[np.float64] = _deboor(
            self.control_points, self.knots, self.order, times.ravel()
        )
        if np.ndim(t) == 0:
            first: NDArray[np.float64] = out[0]
            return first
        return out

    def derivative(self) -> UniformBspline:
        """The derivative B-spline (order - 1), ego-planner's ``getDerivative``."""
        p = self.order
        if p < 1:
            msg = "a B-spline of order 0 has no derivative B-spline"
            raise BsplineError(msg)
        ctrl = self.control_points
        u = self.knots
        n = ctrl.shape[0]
        den = u[p + 1 : n + p] - u[1:n]
        with np.errstate(divide="ignore", invalid="ignore"):
            q = p * (ctrl[1:] - ctrl[:-1]) / den[:, None]
        q = np.where(np.isfinite(q), q, 0.0)
        return UniformBspline(q, p - 1, self.interval, knots=u[1:-1])

    def length(self, resolution: float = 0.01) -> float:
        """Arc length by summing chords every ``resolution`` seconds."""
        times = np.arange(0.0, self.duration + 1e-4, resolution)
        pts = self.evaluate(times)
        return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())

    # ------------------------------------------------------------------ limits
    def check_feasibility(
        self, max_vel: float, max_acc: float, tolerance: float = 0.0
    ) -> tuple[bool, float]:
        """Check per-axis velocity and acceleration control points against the limits.

        A control point exceeds a limit when one axis is beyond
        ``limit * (1 + tolerance) + 1e-4`` (ego-planner's ``checkFeasibility``).

        Returns:
            ``(feasible, ratio)``: ``ratio = max(v / max_vel, sqrt(a / max_acc))``
            over the infeasible control points, by which the time must grow.
        """
        p = self.order
        ctrl = self.control_points
        u = self.knots
        n = ctrl.shape[0]
        vel = p * (ctrl[1:] - ctrl[:-1]) / (u[p + 1 : n + p] - u[1:n])[:, None]
        vel_lim = max_vel * (1.0 + tolerance) + 1e-4
        bad_v = np.any(np.abs(vel) > vel_lim, axis=1)
        acc = (
            p
            * (p - 1)
            * (
                (ctrl[2:] - ctrl[1:-1]) / (u[p + 2 : n + p] - u[2:n])[:, None]
                - (ctrl[1:-1] - ctrl[:-2]) / (u[p + 1 : n + p - 1] - u[1 : n - 1])[:, None]
            )
            / (u[p + 1 : n + p - 1] - u[2:n])[:, None]
        )
        acc_lim = max_acc * (1.0 + tolerance) + 1e-4
        bad_a = np.any(np.abs(acc) > acc_lim, axis=1)
        worst_v = float(np.abs(vel[bad_v]).max()) if bad_v.any() else -1.0
        worst_a = float(np.abs(acc[bad_a]).max()) if bad_a.any() else -1.0
        ratio = max(worst_v / max_vel, math.sqrt(abs(worst_a) / max_acc))
        return not (bad_v.any() or bad_a.any()), ratio

    def lengthen_time(self, ratio: float) -> UniformBspline:
        """Stretch the middle of the time span by ``ratio`` (ego-planner's ``lengthenTime``).

        Knots 6 .. n - 6 spread linearly so that the span between knots 5 and
        ``len - 6`` grows by ``ratio``; later knots shift by the added time.

        Returns:
            A new B-spline with non-uniform knots.
        """
        u = self.knots.copy()
        num1 = 5
        num2 = u.shape[0] - 1 - 5
        if num2 <= num1:
            msg = f"lengthen_time needs more than 11 knots, got {u.shape[0]}"
            raise BsplineError(msg)
        delta = (ratio - 1.0) * (u[num2] - u[num1])
        inc = delta / (num2 - num1)
        idx = np.arange(num1 + 1, num2 + 1)
        u[num1 + 1 : num2 + 1] += (idx - num1) * inc
        u[num2 + 1 :] += delta
        return UniformBspline(self.control_points, self.order, self.interval, knots=u)


def parameterize_to_bspline(
    ts: float, points: ArrayLike, start_end_derivatives: ArrayLike
) -> NDArray[np.float64]:
    """Control points of a uniform cubic B-spline through points (``parameterizeToBspline``).

    Solves, in the least-squares sense, ``(P_i + 4 P_{i+1} + P_{i+2}) / 6 = point_i``
    for the ``K`` points, with the start and end velocity ``(P_2 - P_0) / (2 ts)``
    and acceleration ``(P_0 - 2 P_1 + P_2) / ts^2`` as given.

    Args:
        ts: Knot spacing (s).
        points: ``(K, 3)`` points, ``K >= 4``, visited every ``ts``.
        start_end_derivatives: ``(4, 3)``: start velocity, end velocity, start
            acceleration, end acceleration (ego-planner's order).

    Returns:
        ``(K + 2, 3)`` control points.

    Raises:
        BsplineError: ``ts <= 0``, fewer than 4 points or not 4 derivatives.
    """
    pts = np.asarray(points, dtype=np.float64)
    der = np.asarray(start_end_derivatives, dtype=np.float64)
    if not (math.isfinite(ts) and ts > 0):
        msg = f"parameterize_to_bspline: ts is {ts}; expected a time step > 0 s"
        raise BsplineError(msg)
    if pts.ndim != 2 or pts.shape[0] < 4:
        msg = f"parameterize_to_bspline: points have shape {pts.shape}; expected (K >= 4, D)"
        raise BsplineError(msg)
    if der.shape != (4, pts.shape[1]):
        msg = (
            f"parameterize_to_bspline: derivatives have shape {der.shape}; expected "
            f"(4, {pts.shape[1]}): start vel, end vel, start acc, end acc"
        )
        raise BsplineError(msg)
    k = pts.shape[0]
    a = np.zeros((k + 4, k + 2))
    rows = np.arange(k)
    a[rows, rows] = 1.0 / 6.0
    a[rows, rows + 1] = 4.0 / 6.0
    a[rows, rows + 2] = 1.0 / 6.0
    vrow = np.array([-1.0, 0.0, 1.0]) / (2.0 * ts)
    arow = np.array([1.0, -2.0, 1.0]) / (ts * ts)
    a[k, 0:3] = vrow
    a[k + 1, k - 1 : k + 2] = vrow
    a[k + 2, 0:3] = arow
    a[k + 3, k - 1 : k + 2] = arow
    b = np.vstack([pts, der])
    ctrl, *_ = np.linalg.lstsq(a, b, rcond=None)
    return np.ascontiguousarray(ctrl)
