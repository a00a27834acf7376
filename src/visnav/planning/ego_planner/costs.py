"""The cost terms of ego-planner's B-spline optimisation (``bspline_optimizer.cpp``), in numba.

Every term reads the ``(N, 3)`` control points ``q``, adds ``weight`` times its
gradient into ``grad`` (same shape) and returns its unweighted value:

* :func:`smoothness_cost` - sum of squared third differences (jerk) of the
  control points, ``|q_{i+3} - 3 q_{i+2} + 3 q_{i+1} - q_i|^2`` (no time scaling,
  as upstream);
* :func:`distance_cost` - the rebound collision term of the paper: for each
  ``{p, v}`` pair of control point ``i`` (``order <= i < N - order``) the distance
  ``d = (q_i - p) . v`` is kept above the clearance ``s_f``; with ``c = s_f - d``
  the cost is 0 for ``c <= 0``, ``c^3`` for ``0 < c <= s_f`` and
  ``3 s_f c^2 - 3 s_f^2 c + s_f^3`` beyond (C2 continuous);
* :func:`feasibility_cost` - per axis, squared excess of the velocity control
  points ``(q_{i+1} - q_i) / ts`` over ``max_vel`` (scaled by ``1 / ts^2``, as
  upstream) and of the acceleration control points over ``max_acc``;
* :func:`fitness_cost` - the refinement's anisotropic fit of the curve's knot
  points ``(q_{i-1} + 4 q_i + q_{i+1}) / 6`` to reference points: with ``x`` the
  error and ``v`` the reference direction, ``(x . v)^2 / 25 + |x x v|^2``.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["distance_cost", "feasibility_cost", "fitness_cost", "smoothness_cost"]


@numba.njit(cache=True)
def smoothness_cost(q: np.ndarray, grad: np.ndarray, weight: float) -> float:
    """Jerk smoothness: sum over ``i`` of ``|q[i+3] - 3 q[i+2] + 3 q[i+1] - q[i]|^2``."""
    cost = 0.0
    for i in range(q.shape[0] - 3):
        for c in range(3):
            jerk = q[i + 3, c] - 3.0 * q[i + 2, c] + 3.0 * q[i + 1, c] - q[i, c]
            cost += jerk * jerk
            t = 2.0 * jerk * weight
            grad[i, c] -= t
            grad[i + 1, c] += 3.0 * t
            grad[i + 2, c] -= 3.0 * t
            grad[i + 3, c] += t
    return cost


@numba.njit(cache=True)
def distance_cost(
    q: np.ndarray,
    grad: np.ndarray,
    weight: float,
    base_points: np.ndarray,
    directions: np.ndarray,
    counts: np.ndarray,
    clearance: float,
    order: int,
) -> float:
    """Rebound collision cost of the ``{p, v}`` pairs (see the module docstring)."""
    cost = 0.0
    sf = clearance
    a = 3.0 * sf
    b = -3.0 * sf * sf
    c3 = sf * sf * sf
    for i in range(order, q.shape[0] - order):
        for k in range(counts[i]):
            d = 0.0
            for c in range(3):
                d += (q[i, c] - base_points[i, k, c]) * directions[i, k, c]
            err = sf - d
            if err <= 0.0:
                continue
            if err < sf:
                cost += err * err * err
                g = -3.0 * err * err
            else:
                cost += a * err * err + b * err + c3
                g = -(2.0 * a * err + b)
            for c in range(3):
                grad[i, c] += weight * g * directions[i, k, c]
    return cost


@numba.njit(cache=True)
def feasibility_cost(
    q: np.ndarray, grad: np.ndarray, weight: float, ts: float, max_vel: float, max_acc: float
) -> float:
    """Squared per-axis excess of velocity and acceleration control points."""
    cost = 0.0
    inv2 = 1.0 / (ts * ts)
    for i in range(q.shape[0] - 1):
        for c in range(3):
            v = (q[i + 1, c] - q[i, c]) / ts
            if v > max_vel:
                e = v - max_vel
            elif v < -max_vel:
                e = v + max_vel
            else:
                continue
            cost += e * e * inv2
            g = weight * 2.0 * e / ts * inv2
            grad[i, c] -= g
            grad[i + 1, c] += g
    for i in range(q.shape[0] - 2):
        for c in range(3):
            acc = (q[i + 2, c] - 2.0 * q[i + 1, c] + q[i, c]) * inv2
            if acc > max_acc:
                e = acc - max_acc
            elif acc < -max_acc:
                e = acc + max_acc
            else:
                continue
            cost += e * e
            g = weight * 2.0 * e * inv2
            grad[i, c] += g
            grad[i + 1, c] -= 2.0 * g
            grad[i + 2, c] += g
    return cost


@numba.njit(cache=True)
def fitness_cost(
    q: np.ndarray, grad: np.ndarray, weight: float, ref_pts: np.ndarray, order: int
) -> float:
    """Anisotropic fit of the knot points to ``ref_pts`` (``N - 2`` points, one per knot)."""
    cost = 0.0
    a2 = 25.0
    b2 = 1.0
    x = np.empty(3)
    v = np.empty(3)
    for i in range(order - 1, q.shape[0] - order + 1):
        for c in range(3):
            x[c] = (q[i - 1, c] + 4.0 * q[i, c] + q[i + 1, c]) / 6.0 - ref_pts[i - 1, c]
            v[c] = ref_pts[i, c] - ref_pts[i - 2, c]
        norm = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if norm > 0.0:
            v /= norm
        xdv = x[0] * v[0] + x[1] * v[1] + x[2] * v[2]
        cx = x[1] * v[2] - x[2] * v[1]
        cy = x[2] * v[0] - x[0] * v[2]
        cz = x[0] * v[1] - x[1] * v[0]
        cost += xdv * xdv / a2 + (cx * cx + cy * cy + cz * cz) / b2
        # d|x x v|^2/dx = 2 (v x (x x v)) ; d(x.v)^2/dx = 2 (x.v) v
        gx = 2.0 * xdv / a2 * v[0] + 2.0 / b2 * (v[1] * cz - v[2] * cy)
        gy = 2.0 * xdv / a2 * v[1] + 2.0 / b2 * (v[2] * cx - v[0] * cz)
        gz = 2.0 * xdv / a2 * v[2] + 2.0 / b2 * (v[0] * cy - v[1] * cx)
        for c, gc in enumerate((gx, gy, gz)):
            grad[i - 1, c] += weight * gc / 6.0
            grad[i, c] += weight * 4.0 * gc / 6.0
            grad[i + 1, c] += weight * gc / 6.0
    return cost
