"""The compiled bundle adjustment as it was before the linearisation was reused across
damping values: every try (accepted or rejected) re-ran residuals, Jacobians and the
accumulation. The reference ``test_ba_compiled`` compares the current solver with (same
arguments, same results); it also counts the rejected tries so the tests can show that
the re-damping path ran."""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from visnav.slam._ba_kernels import _exp, _huber, _inv3, _jacobians, _residual, ba_cost

__all__ = ["relinearising_lm"]


@numba.njit(cache=True)
def _step(
    poses: NDArray[np.float64],
    points: NDArray[np.float64],
    obs_kf: NDArray[np.int64],
    obs_pt: NDArray[np.int64],
    meas: NDArray[np.float64],
    stereo: NDArray[np.bool_],
    info: NDArray[np.float64],
    cam: NDArray[np.float64],
    k_mono: float,
    k_stereo: float,
    free: NDArray[np.int64],
    n_free: int,
    order: NDArray[np.int64],
    starts: NDArray[np.int64],
    lam: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:
    """One damped Gauss-Newton step: ``(pose twists (F, 6), point steps (P, 3), ok)``."""
    n_obs = len(obs_kf)
    n_pts = len(points)
    dim = 6 * n_free
    hpp = np.zeros((dim, dim))
    hpp_diag = np.zeros(dim)
    bp = np.zeros(dim)
    hpl = np.zeros((n_obs, 6, 3))
    valid = np.zeros(n_obs, dtype=np.bool_)
    hll_inv = np.zeros((n_pts, 3, 3))
    bl = np.zeros((n_pts, 3))
    pc = np.empty(3)
    e = np.empty(3)
    jp = np.zeros((3, 6))
    jl = np.zeros((3, 3))
    dc = np.zeros((3, 3))
    hll = np.zeros((3, 3))
    a = np.zeros((6, 3))
    for pt in range(n_pts):
        hll[:] = 0.0
        for idx in range(starts[pt], starts[pt + 1]):
            o = order[idx]
            st = stereo[o]
            if not _residual(poses[obs_kf[o]], points[pt], meas[o], st, cam, pc, e):
                continue
            valid[o] = True
            chi2 = info[o] * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
            w = info[o] * _huber(chi2, k_stereo if st else k_mono)[1]
            _jacobians(poses[obs_kf[o]], pc, st, cam, jp, jl, dc)
            for i in range(3):
                for j in range(3):
                    s = 0.0
                    for r in range(3):
                        s += jl[r, i] * jl[r, j]
                    hll[i, j] += w * s
                bl[pt, i] -= w * (jl[0, i] * e[0] + jl[1, i] * e[1] + jl[2, i] * e[2])
            f = free[obs_kf[o]]
            if f < 0:
                continue
            base = 6 * f
            for i in range(6):
                for j in range(6):
                    s = 0.0
                    for r in range(3):
                        s += jp[r, i] * jp[r, j]
                    hpp[base + i, base + j] += w * s
                bp[base + i] -= w * (jp[0, i] * e[0] + jp[1, i] * e[1] + jp[2, i] * e[2])
                for j in range(3):
                    s = 0.0
                    for r in range(3):
                        s += jp[r, i] * jl[r, j]
                    hpl[o, i, j] = w * s
        for r in range(3):
            hll[r, r] += lam * hll[r, r] + 1e-12
        _inv3(hll, hll_inv[pt])  # a point nothing constrains has a zero right-hand side: no step
    for i in range(dim):
        hpp_diag[i] = hpp[i, i]
    # Schur complement: S = Hpp - sum_pt Hpl Hll^-1 Hpl^T, b = bp - sum_pt Hpl Hll^-1 bl
    for pt in range(n_pts):
        for i1 in range(starts[pt], starts[pt + 1]):
            o1 = order[i1]
            f1 = free[obs_kf[o1]]
            if not valid[o1] or f1 < 0:
                continue
            hinv = hll_inv[pt]
            h1 = hpl[o1]
            for r in range(6):  # a = Hpl_1 Hll^-1
                for c in range(3):
                    a[r, c] = h1[r, 0] * hinv[0, c] + h1[r, 1] * hinv[1, c] + h1[r, 2] * hinv[2, c]
            b1 = 6 * f1
            blv = bl[pt]
            for r in range(6):
                bp[b1 + r] -= a[r, 0] * blv[0] + a[r, 1] * blv[1] + a[r, 2] * blv[2]
            for i2 in range(starts[pt], starts[pt + 1]):
                o2 = order[i2]
                f2 = free[obs_kf[o2]]
                if not valid[o2] or f2 < 0:
                    continue
                h2 = hpl[o2]
                b2 = 6 * f2
                for r in range(6):
                    for c in range(6):
                        hpp[b1 + r, b2 + c] -= (
                            a[r, 0] * h2[c, 0] + a[r, 1] * h2[c, 1] + a[r, 2] * h2[c, 2]
                        )
    for i in range(dim):
        hpp[i, i] += lam * hpp_diag[i] + 1e-12
    dposes = np.zeros((n_free, 6))
    dpoints = np.zeros((n_pts, 3))
    if dim > 0:
        try:
            chol = np.linalg.cholesky(hpp)
        except Exception:  # noqa: BLE001 - numba: an indefinite system, damp more
            return dposes, dpoints, False
        y = np.linalg.solve(chol, bp)
        dx = np.linalg.solve(chol.T, y)
        for f in range(n_free):
            for r in range(6):
                dposes[f, r] = dx[6 * f + r]
    for pt in range(n_pts):
        r0, r1, r2 = bl[pt, 0], bl[pt, 1], bl[pt, 2]
        for idx in range(starts[pt], starts[pt + 1]):
            o = order[idx]
            f = free[obs_kf[o]]
            if not valid[o] or f < 0:
                continue
            h, d = hpl[o], dposes[f]
            for r in range(6):
                r0 -= h[r, 0] * d[r]
                r1 -= h[r, 1] * d[r]
                r2 -= h[r, 2] * d[r]
        hinv = hll_inv[pt]
        for c in range(3):
            dpoints[pt, c] = hinv[c, 0] * r0 + hinv[c, 1] * r1 + hinv[c, 2] * r2
    return dposes, dpoints, True


@numba.njit(cache=True)
def relinearising_lm(
    poses: NDArray[np.float64],
    points: NDArray[np.float64],
    obs_kf: NDArray[np.int64],
    obs_pt: NDArray[np.int64],
    meas: NDArray[np.float64],
    stereo: NDArray[np.bool_],
    info: NDArray[np.float64],
    cam: NDArray[np.float64],
    k_mono: float,
    k_stereo: float,
    fixed: NDArray[np.bool_],
    iterations: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float, int]:
    """``levenberg_marquardt`` as it was, plus the number of rejected tries.

    The inputs are not modified. ``iterations`` counts accepted or final steps; a
    rejected step raises the damping tenfold and is tried again (at most 10 times per
    iteration, as gtsam's inner loop). Stops early when the cost falls by less than
    1e-5 of itself (gtsam's ``relativeErrorTol``).
    """
    n_kf = len(poses)
    free = np.full(n_kf, -1, dtype=np.int64)
    n_free = 0
    for k in range(n_kf):
        if not fixed[k]:
            free[k] = n_free
            n_free += 1
    order = np.argsort(obs_pt, kind="mergesort")
    starts = np.zeros(len(points) + 1, dtype=np.int64)
    for o in range(len(obs_pt)):
        starts[obs_pt[o] + 1] += 1
    for p in range(len(points)):
        starts[p + 1] += starts[p]
    cur_poses = poses.copy()
    cur_points = points.copy()
    args = (obs_kf, obs_pt, meas, stereo, info, cam, k_mono, k_stereo)
    cost0 = ba_cost(cur_poses, cur_points, *args)
    cost = cost0
    lam = 1e-5
    rejected = 0
    for _ in range(iterations):
        accepted = False
        decrease = 0.0
        for _try in range(10):
            dposes, dpoints, ok = _step(
                cur_poses, cur_points, *args, free, n_free, order, starts, lam
            )
            new_poses = cur_poses.copy()
            for k in range(n_kf):
                if free[k] >= 0:
                    new_poses[k] = _exp(dposes[free[k]]) @ cur_poses[k]
            new_points = cur_points + dpoints
            new_cost = ba_cost(new_poses, new_points, *args)
            if ok and new_cost <= cost:
                accepted = True
                decrease = cost - new_cost
                cur_poses, cur_points, cost = new_poses, new_points, new_cost
                lam = max(lam * 0.1, 1e-9)
                break
            lam *= 10.0
            rejected += 1
        if not accepted or decrease <= 1e-5 * cost:
            break
    return cur_poses, cur_points, cost0, cost, rejected
