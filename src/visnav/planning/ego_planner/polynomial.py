"""Piecewise quintic trajectories (ego-planner's ``PolynomialTraj``) for initial and global paths.

* :meth:`PolynomialTraj.one_segment` - the quintic meeting position, velocity and
  acceleration at both ends in a given time (``one_segment_traj_gen``).
* :meth:`PolynomialTraj.min_snap` - quintic pieces through waypoints with fixed
  times, continuous in position, velocity and acceleration, whose interior
  velocities and accelerations minimise the integral of squared snap (the closed
  form of Richter, Bry and Roy, as ``minSnapTraj``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from visnav.planning.errors import PlanningError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["PolynomialError", "PolynomialTraj"]

_N_COEF = 6  # quintic


class PolynomialError(PlanningError):
    """Invalid polynomial trajectory inputs."""


def _boundary_matrix(duration: float) -> NDArray[np.float64]:
    """``A`` with ``[p0, v0, a0, pT, vT, aT] = A @ c`` for ``c`` in the power basis."""
    t = duration
    a = np.zeros((6, 6))
    a[0, 0] = 1.0
    a[1, 1] = 1.0
    a[2, 2] = 2.0
    for i in range(6):
        a[3, i] = t**i
        if i >= 1:
            a[4, i] = i * t ** (i - 1)
        if i >= 2:
            a[5, i] = i * (i - 1) * t ** (i - 2)
    return a


def _snap_cost_matrix(duration: float) -> NDArray[np.float64]:
    """``Q`` with ``c @ Q @ c`` = integral of the squared fourth derivative over the piece."""
    q = np.zeros((6, 6))
    for i in range(4, 6):
        for k in range(4, 6):
            fi = math.factorial(i) / math.factorial(i - 4)
            fk = math.factorial(k) / math.factorial(k - 4)
            power = i + k - 7
            q[i, k] = fi * fk * duration**power / power
    return q


class PolynomialTraj:
    """Quintic pieces ``(S, D, 6)`` (power basis, lowest order first) with durations ``(S,)``."""

    def __init__(self, coefficients: ArrayLike, durations: ArrayLike) -> None:
        coef = np.asarray(coefficients, dtype=np.float64)
        times = np.asarray(durations, dtype=np.float64).reshape(-1)
        if coef.ndim != 3 or coef.shape[0] != times.shape[0] or coef.shape[2] != _N_COEF:
            msg = (
                f"polynomial coefficients have shape {coef.shape} for {times.shape[0]} "
                "durations: expected (S, D, 6)"
            )
            raise PolynomialError(msg)
        if not np.all(times > 0):
            msg = f"polynomial durations {times.tolist()}: expected every piece to last > 0 s"
            raise PolynomialError(msg)
        self.coefficients = coef
        self.durations = times
        self.boundaries = np.concatenate([[0.0], np.cumsum(times)])

    @property
    def duration(self) -> float:
        """Total duration (s)."""
        return float(self.boundaries[-1])

    def _eval(self, t: ArrayLike, order: int) -> NDArray[np.float64]:
        times = np.atleast_1d(np.asarray(t, dtype=np.float64))
        tt = np.clip(times, 0.0, self.duration)
        seg = np.clip(
            np.searchsorted(self.boundaries, tt, side="right") - 1, 0, len(self.durations) - 1
        )
        local = tt - self.boundaries[seg]
        coef = self.coefficients[seg]  # (M, D, 6)
        factors = np.array(
            [math.factorial(i) / math.factorial(i - order) for i in range(order, _N_COEF)]
        )
        powers = local[:, None] ** np.arange(_N_COEF - order)  # (M, 6 - order)
        out: NDArray[np.float64] = np.einsum("mdn,mn->md", coef[:, :, order:] * factors, powers)
        return out[0] if np.ndim(t) == 0 else out

    def evaluate(self, t: ArrayLike) -> NDArray[np.float64]:
        """Position at time(s) ``t`` (clamped to ``[0, duration]``)."""
        return self._eval(t, 0)

    def evaluate_vel(self, t: ArrayLike) -> NDArray[np.float64]:
        """Velocity at time(s) ``t``."""
        return self._eval(t, 1)

    def evaluate_acc(self, t: ArrayLike) -> NDArray[np.float64]:
        """Acceleration at time(s) ``t``."""
        return self._eval(t, 2)

    @classmethod
    def one_segment(
        cls,
        start_pos: ArrayLike,
        start_vel: ArrayLike,
        start_acc: ArrayLike,
        end_pos: ArrayLike,
        end_vel: ArrayLike,
        end_acc: ArrayLike,
        duration: float,
    ) -> PolynomialTraj:
        """The quintic meeting the given end states in ``duration`` seconds.

        Raises:
            PolynomialError: A non-positive duration.
        """
        if not (math.isfinite(duration) and duration > 0):
            msg = f"one_segment: duration is {duration}; expected > 0 s"
            raise PolynomialError(msg)
        d = np.array([start_pos, start_vel, start_acc, end_pos, end_vel, end_acc], dtype=np.float64)
        coef = np.linalg.solve(_boundary_matrix(duration), d)  # (6, D)
        return cls(coef.T[None], [duration])

    @classmethod
    def min_snap(
        cls,
        waypoints: ArrayLike,
        start_vel: ArrayLike,
        end_vel: ArrayLike,
        start_acc: ArrayLike,
        end_acc: ArrayLike,
        durations: ArrayLike,
    ) -> PolynomialTraj:
        """Minimum-snap quintic pieces through ``(K, D)`` waypoints with ``K - 1`` durations.

        Raises:
            PolynomialError: Shapes that do not match or non-positive durations.
        """
        pos = np.asarray(waypoints, dtype=np.float64)
        times = np.asarray(durations, dtype=np.float64).reshape(-1)
        if pos.ndim != 2 or pos.shape[0] < 2 or times.shape[0] != pos.shape[0] - 1:
            msg = (
                f"min_snap: {pos.shape} waypoints and {times.shape[0]} durations: expected "
                "(K >= 2, D) waypoints and K - 1 durations"
            )
            raise PolynomialError(msg)
        if not np.all(times > 0):
            msg = f"min_snap: durations {times.tolist()}; expected every piece > 0 s"
            raise PolynomialError(msg)
        k, dim = pos.shape
        n_seg = k - 1
        n_var = 3 * k  # position, velocity, acceleration at each waypoint
        # cost in the waypoint derivatives: sum_j d_j^T (A_j^-T Q_j A_j^-1) d_j
        cost = np.zeros((n_var, n_var))
        inverses = []
        for j in range(n_seg):
            a_inv = np.linalg.inv(_boundary_matrix(times[j]))
            inverses.append(a_inv)
            r = a_inv.T @ _snap_cost_matrix(times[j]) @ a_inv
            idx = np.r_[3 * j : 3 * j + 6]
            cost[np.ix_(idx, idx)] += r
        fixed = [0, 1, 2, 3 * (k - 1), 3 * (k - 1) + 1, 3 * (k - 1) + 2]
        fixed += [3 * i for i in range(1, k - 1)]
        fixed_idx = np.array(sorted(fixed))
        free_idx = np.array([i for i in range(n_var) if i not in set(fixed)], dtype=np.int64)
        values = np.zeros((n_var, dim))
        values[0::3] = pos
        values[1] = np.asarray(start_vel, dtype=np.float64)
        values[2] = np.asarray(start_acc, dtype=np.float64)
        values[3 * (k - 1) + 1] = np.asarray(end_vel, dtype=np.float64)
        values[3 * (k - 1) + 2] = np.asarray(end_acc, dtype=np.float64)
        if free_idx.size:
            r_pp = cost[np.ix_(free_idx, free_idx)]
            r_fp = cost[np.ix_(fixed_idx, free_idx)]
            values[free_idx] = -np.linalg.solve(r_pp, r_fp.T @ values[fixed_idx])
        coef = np.empty((n_seg, dim, _N_COEF))
        for j in range(n_seg):
            coef[j] = (inverses[j] @ values[3 * j : 3 * j + 6]).T
        return cls(coef, times)
