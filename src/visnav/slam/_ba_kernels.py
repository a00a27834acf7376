"""Compiled sparse bundle adjustment: Levenberg-Marquardt on the reduced camera system.

The structure is the classic one of SBA / g2o / ORB-SLAM's local mapping: every
observation links one keyframe pose (6 parameters, a left twist ``(rho, phi)`` on
``T_cw``) and one point (3); the points are eliminated by the Schur complement, the
dense reduced system over the free poses (a local window has at most a few dozen) is
solved by Cholesky, and the points follow by back-substitution. Observations with
depth are virtual-stereo ``(u, v, u_right)`` measurements, the others monocular
``(u, v)``; each is whitened by ``inv_sigma2`` of its pyramid level and robustified
by a Huber kernel on the whitened error (thresholds ``sqrt(chi2 95 %)``), weights
recomputed at every linearisation (IRLS). Damping is Marquardt's: ``lambda`` times
the diagonal of the normal equations, raised tenfold on a rejected step. The normal
equations are built once per linearisation point (:func:`_linearise`); a rejected step
only re-damps and re-solves them (:func:`_damped_step`), as gtsam's inner loop does.

:func:`levenberg_marquardt_odometry` adds relative-pose factors between poses (wheel
odometry between consecutive keyframes, :mod:`visnav.slam.odometry_prior`) to the
reduced system; they link poses only, so the Schur complement is unchanged.

The kernels are sequential, so the result is deterministic. Everything is in float64.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numba
import numpy as np

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["ba_cost", "levenberg_marquardt", "levenberg_marquardt_odometry", "odometry_cost"]

_MIN_Z = 1e-3
"""Points closer than this (m, or behind the camera) are not linearised (a fixed cost)."""


@numba.njit(cache=True)
def _exp(xi: NDArray[np.float64]) -> NDArray[np.float64]:  # pragma: no cover - compiled
    """SE(3) exponential of a twist ``(rho, phi)`` (as ``geometry.se3_exp``)."""
    rho0, rho1, rho2, p0, p1, p2 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    theta = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    k = np.zeros((3, 3))
    k[0, 1], k[0, 2], k[1, 0], k[1, 2], k[2, 0], k[2, 1] = -p2, p1, p2, -p0, -p1, p0
    kk = k @ k
    eye = np.eye(3)
    if theta < 1e-10:
        r = eye + k
        v = eye + 0.5 * k
    else:
        a = np.sin(theta) / theta
        b = (1.0 - np.cos(theta)) / (theta * theta)
        c = (theta - np.sin(theta)) / (theta * theta * theta)
        r = eye + a * k + b * kk
        v = eye + b * k + c * kk
    out = np.eye(4)
    out[:3, :3] = r
    out[0, 3] = v[0, 0] * rho0 + v[0, 1] * rho1 + v[0, 2] * rho2
    out[1, 3] = v[1, 0] * rho0 + v[1, 1] * rho1 + v[1, 2] * rho2
    out[2, 3] = v[2, 0] * rho0 + v[2, 1] * rho1 + v[2, 2] * rho2
    return out


@numba.njit(cache=True)
def _residual(
    pose: NDArray[np.float64],
    point: NDArray[np.float64],
    meas: NDArray[np.float64],
    stereo: bool,
    cam: NDArray[np.float64],
    out_pc: NDArray[np.float64],
    out_e: NDArray[np.float64],
) -> bool:  # pragma: no cover - compiled
    """Camera-frame point and residual (predicted - measured); False when not in front."""
    fx, fy, cx, cy, bf = cam[0], cam[1], cam[2], cam[3], cam[4]
    for i in range(3):
        out_pc[i] = (
            pose[i, 0] * point[0] + pose[i, 1] * point[1] + pose[i, 2] * point[2] + pose[i, 3]
        )
    z = out_pc[2]
    if z <= _MIN_Z:
        return False
    iz = 1.0 / z
    u = fx * out_pc[0] * iz + cx
    out_e[0] = u - meas[0]
    out_e[1] = fy * out_pc[1] * iz + cy - meas[1]
    out_e[2] = (u - bf * iz - meas[2]) if stereo else 0.0
    return True


@numba.njit(cache=True)
def _huber(chi2: float, k: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """``(rho(s), weight)`` of the Huber kernel at whitened error ``s = sqrt(chi2)``."""
    s = np.sqrt(chi2)
    if s <= k:
        return 0.5 * chi2, 1.0
    return k * s - 0.5 * k * k, k / s


@numba.njit(cache=True)
def ba_cost(
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
) -> float:  # pragma: no cover - compiled
    """Total robust cost ``sum rho(chi2)`` of the observations.

    An observation of a point behind its camera (or closer than 1 mm) costs what gtsam's
    projection factors return then, ``2 fx`` per residual component, so no step can lower
    the cost by moving points behind the cameras; it adds nothing to the normal equations.

    Args:
        poses: (K, 4, 4) ``T_cw``.
        points: (P, 3) world points.
        obs_kf: (O,) pose index of each observation.
        obs_pt: (O,) point index.
        meas: (O, 3) ``u, v, u_right`` (``u_right`` ignored where not stereo).
        stereo: (O,) whether ``u_right`` is measured.
        info: (O,) ``1 / sigma^2`` of the observation's level.
        cam: ``fx, fy, cx, cy, bf``.
        k_mono: Huber threshold of a monocular observation (whitened pixels).
        k_stereo: Huber threshold of a stereo observation.
    """
    pc = np.empty(3)
    e = np.empty(3)
    total = 0.0
    behind = 4.0 * cam[0] * cam[0]  # gtsam's error of a point behind: 2 fx per component
    for o in range(len(obs_kf)):
        if _residual(poses[obs_kf[o]], points[obs_pt[o]], meas[o], stereo[o], cam, pc, e):
            chi2 = info[o] * (e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        else:
            chi2 = info[o] * behind * (3.0 if stereo[o] else 2.0)
        total += _huber(chi2, k_stereo if stereo[o] else k_mono)[0]
    return total


@numba.njit(cache=True)
def _jacobians(
    pose: NDArray[np.float64],
    pc: NDArray[np.float64],
    stereo: bool,
    cam: NDArray[np.float64],
    jp: NDArray[np.float64],
    jl: NDArray[np.float64],
    dc: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """(3, 6) residual Jacobian w.r.t. the pose twist and (3, 3) w.r.t. the world point.

    ``dc`` is scratch space for d(u, v, ur) / d(camera point).
    """
    fx, fy, bf = cam[0], cam[1], cam[4]
    x, y, z = pc[0], pc[1], pc[2]
    iz = 1.0 / z
    iz2 = iz * iz
    dc[:] = 0.0
    dc[0, 0] = fx * iz
    dc[0, 2] = -fx * x * iz2
    dc[1, 1] = fy * iz
    dc[1, 2] = -fy * y * iz2
    if stereo:
        dc[2, 0] = fx * iz
        dc[2, 2] = (-fx * x + bf) * iz2
    # d(camera point) / d(rho, phi) = [I | -[pc]x]
    for r in range(3):
        jp[r, 0] = dc[r, 0]
        jp[r, 1] = dc[r, 1]
        jp[r, 2] = dc[r, 2]
        jp[r, 3] = -dc[r, 1] * z + dc[r, 2] * y
        jp[r, 4] = dc[r, 0] * z - dc[r, 2] * x
        jp[r, 5] = -dc[r, 0] * y + dc[r, 1] * x
        for c in range(3):
            jl[r, c] = dc[r, 0] * pose[0, c] + dc[r, 1] * pose[1, c] + dc[r, 2] * pose[2, c]


@numba.njit(cache=True)
def _inv3(m: NDArray[np.float64], out: NDArray[np.float64]) -> None:  # pragma: no cover
    """Inverse of a symmetric 3x3 matrix by cofactors (zero when it is singular)."""
    c00 = m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]
    c01 = m[1, 2] * m[2, 0] - m[1, 0] * m[2, 2]
    c02 = m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]
    det = m[0, 0] * c00 + m[0, 1] * c01 + m[0, 2] * c02
    if abs(det) < 1e-300:
        out[:] = 0.0
        return
    inv = 1.0 / det
    out[0, 0] = c00 * inv
    out[1, 0] = c01 * inv
    out[2, 0] = c02 * inv
    out[0, 1] = (m[0, 2] * m[2, 1] - m[0, 1] * m[2, 2]) * inv
    out[1, 1] = (m[0, 0] * m[2, 2] - m[0, 2] * m[2, 0]) * inv
    out[2, 1] = (m[0, 1] * m[2, 0] - m[0, 0] * m[2, 1]) * inv
    out[0, 2] = (m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1]) * inv
    out[1, 2] = (m[0, 2] * m[1, 0] - m[0, 0] * m[1, 2]) * inv
    out[2, 2] = (m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]) * inv


@numba.njit(cache=True)
def _linearise(
    poses: NDArray[np.float64],
    points: NDArray[np.float64],
    obs_kf: NDArray[np.int64],
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
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.bool_],
    NDArray[np.float64],
    NDArray[np.float64],
]:  # pragma: no cover - compiled
    """The undamped normal equations at one linearisation point (IRLS weights included).

    Returns ``(hpp (6F, 6F), bp (6F,), hpl (O, 6, 3), valid (O,), hll (P, 3, 3), bl (P, 3))``:
    the pose block, the pose/point blocks per observation, the point blocks and the
    right-hand sides (``-J^T W e``). ``valid`` marks observations in front of their camera.
    """
    n_obs = len(obs_kf)
    n_pts = len(points)
    dim = 6 * n_free
    hpp = np.zeros((dim, dim))
    bp = np.zeros(dim)
    hpl = np.zeros((n_obs, 6, 3))
    valid = np.zeros(n_obs, dtype=np.bool_)
    hll = np.zeros((n_pts, 3, 3))
    bl = np.zeros((n_pts, 3))
    pc = np.empty(3)
    e = np.empty(3)
    jp = np.zeros((3, 6))
    jl = np.zeros((3, 3))
    dc = np.zeros((3, 3))
    for pt in range(n_pts):
        h = hll[pt]
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
                    h[i, j] += w * s
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
    return hpp, bp, hpl, valid, hll, bl


@numba.njit(cache=True)
def _damped_step(
    hpp0: NDArray[np.float64],
    bp0: NDArray[np.float64],
    hpl: NDArray[np.float64],
    valid: NDArray[np.bool_],
    hll: NDArray[np.float64],
    bl: NDArray[np.float64],
    obs_kf: NDArray[np.int64],
    free: NDArray[np.int64],
    n_free: int,
    order: NDArray[np.int64],
    starts: NDArray[np.int64],
    lam: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:  # pragma: no cover - compiled
    """Damp the normal equations of :func:`_linearise` by ``lam`` and solve them.

    Returns ``(pose twists (F, 6), point steps (P, 3), ok)``; the inputs are not modified,
    so one linearisation serves every damping value tried at that point.
    """
    n_pts = len(hll)
    dim = 6 * n_free
    hpp = hpp0.copy()
    bp = bp0.copy()
    hll_inv = np.zeros((n_pts, 3, 3))
    hd = np.zeros((3, 3))
    a = np.zeros((6, 3))
    for pt in range(n_pts):
        hd[:] = hll[pt]
        for r in range(3):
            hd[r, r] += lam * hd[r, r] + 1e-12
        _inv3(hd, hll_inv[pt])  # a point nothing constrains has a zero right-hand side: no step
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
        hpp[i, i] += lam * hpp0[i, i] + 1e-12
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
def _adjoint(t: NDArray[np.float64]) -> NDArray[np.float64]:  # pragma: no cover - compiled
    """(6, 6) adjoint of a transform for twists ``(rho, phi)``: ``[[R, [t]x R], [0, R]]``."""
    out = np.zeros((6, 6))
    r = np.ascontiguousarray(t[:3, :3])
    tx = np.zeros((3, 3))
    tx[0, 1], tx[0, 2], tx[1, 0] = -t[2, 3], t[1, 3], t[2, 3]
    tx[1, 2], tx[2, 0], tx[2, 1] = -t[0, 3], -t[1, 3], t[0, 3]
    out[:3, :3] = r
    out[:3, 3:] = tx @ r
    out[3:, 3:] = r
    return out


@numba.njit(cache=True)
def _residual_jacobian(r: NDArray[np.float64]) -> NDArray[np.float64]:  # pragma: no cover
    """(6, 6) derivative of the twist ``r`` of ``E`` by a left twist of ``E``.

    ``exp(xi) E`` moves the translation by ``rho - [t]x phi`` and the rotation vector by
    ``J_l^-1(phi_E) phi`` (the inverse left Jacobian of SO(3)).
    """
    out = np.zeros((6, 6))
    tx = np.zeros((3, 3))
    tx[0, 1], tx[0, 2], tx[1, 0] = -r[2], r[1], r[2]
    tx[1, 2], tx[2, 0], tx[2, 1] = -r[0], -r[1], r[0]
    px = np.zeros((3, 3))
    px[0, 1], px[0, 2], px[1, 0] = -r[5], r[4], r[5]
    px[1, 2], px[2, 0], px[2, 1] = -r[3], -r[4], r[3]
    theta = np.sqrt(r[3] * r[3] + r[4] * r[4] + r[5] * r[5])
    if theta < 1e-4:
        c = 1.0 / 12.0
    else:
        c = 1.0 / theta**2 - (1.0 + np.cos(theta)) / (2.0 * theta * np.sin(theta))
    for i in range(3):
        out[i, i] = 1.0
    out[:3, 3:] = -tx
    out[3:, 3:] = np.eye(3) - 0.5 * px + c * (px @ px)
    return out


@numba.njit(cache=True)
def _edge_error(
    pose_a: NDArray[np.float64], pose_b: NDArray[np.float64], z_inv: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:  # pragma: no cover - compiled
    """``(r, E)``: ``E = Z^-1 T_a T_b^-1`` and its twist ``r`` (translation, rotation vector).

    ``Z`` is the measured pose of camera ``b`` in camera ``a``'s frame; ``T`` are ``T_cw``.
    """
    inv_b = np.eye(4)
    rt = np.ascontiguousarray(pose_b[:3, :3].T)  # contiguous: numba's '@' warns otherwise
    inv_b[:3, :3] = rt
    inv_b[:3, 3] = -(rt @ np.ascontiguousarray(pose_b[:3, 3]))
    e = z_inv @ pose_a @ inv_b
    r = np.empty(6)
    r[0], r[1], r[2] = e[0, 3], e[1, 3], e[2, 3]
    v0, v1, v2 = 0.5 * (e[2, 1] - e[1, 2]), 0.5 * (e[0, 2] - e[2, 0]), 0.5 * (e[1, 0] - e[0, 1])
    sin = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    cos = 0.5 * (e[0, 0] + e[1, 1] + e[2, 2] - 1.0)
    f = np.arctan2(sin, cos) / sin if sin > 1e-12 else 1.0
    r[3], r[4], r[5] = v0 * f, v1 * f, v2 * f
    return r, e


@numba.njit(cache=True)
def odometry_cost(
    poses: NDArray[np.float64],
    edge_a: NDArray[np.int64],
    edge_b: NDArray[np.int64],
    edge_zinv: NDArray[np.float64],
    edge_w: NDArray[np.float64],
) -> float:  # pragma: no cover - compiled
    """Cost ``sum r^T W r / 2`` of relative-pose (odometry) factors.

    Args:
        poses: (K, 4, 4) ``T_cw``.
        edge_a: (E,) pose index of each factor's first camera.
        edge_b: (E,) pose index of its second camera.
        edge_zinv: (E, 4, 4) inverse of the measured pose of ``b`` in ``a``'s frame.
        edge_w: (E, 6, 6) information of the factor's twist (rho, phi).
    """
    total = 0.0
    for n in range(len(edge_a)):
        r, _ = _edge_error(poses[edge_a[n]], poses[edge_b[n]], edge_zinv[n])
        total += 0.5 * (r @ (edge_w[n] @ r))
    return total


@numba.njit(cache=True)
def _add_odometry(
    poses: NDArray[np.float64],
    edge_a: NDArray[np.int64],
    edge_b: NDArray[np.int64],
    edge_zinv: NDArray[np.float64],
    edge_w: NDArray[np.float64],
    free: NDArray[np.int64],
    hpp: NDArray[np.float64],
    bp: NDArray[np.float64],
) -> None:  # pragma: no cover - compiled
    """Add the relative-pose factors' normal equations to the pose block, in place.

    With left twists ``T <- exp(xi) T`` the error ``E = Z^-1 T_a T_b^-1`` moves by
    ``Ad(Z^-1) xi_a`` and by ``-Ad(E) xi_b`` (first order), and its twist by
    :func:`_residual_jacobian` of that.
    """
    for n in range(len(edge_a)):
        fa, fb = free[edge_a[n]], free[edge_b[n]]
        if fa < 0 and fb < 0:
            continue
        r, e = _edge_error(poses[edge_a[n]], poses[edge_b[n]], edge_zinv[n])
        d = _residual_jacobian(r)
        ja = d @ _adjoint(edge_zinv[n])
        jb = -(d @ _adjoint(e))
        w = edge_w[n]
        wr = w @ r
        for fi, ji in ((fa, ja), (fb, jb)):
            if fi < 0:
                continue
            bi = 6 * fi
            bp[bi : bi + 6] -= ji.T @ wr
            for fj, jj in ((fa, ja), (fb, jb)):
                if fj < 0:
                    continue
                bj = 6 * fj
                hpp[bi : bi + 6, bj : bj + 6] += ji.T @ (w @ jj)


@numba.njit(cache=True)
def levenberg_marquardt_odometry(
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
    edge_a: NDArray[np.int64],
    edge_b: NDArray[np.int64],
    edge_zinv: NDArray[np.float64],
    edge_w: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:  # pragma: no cover
    """:func:`levenberg_marquardt` with relative-pose (odometry) factors between poses.

    The factors are those of :func:`odometry_cost`; they have no robust kernel.

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
    edges = (edge_a, edge_b, edge_zinv, edge_w)
    cost0 = ba_cost(cur_poses, cur_points, *args) + odometry_cost(cur_poses, *edges)
    cost = cost0
    lam = 1e-5
    for _ in range(iterations):
        accepted = False
        decrease = 0.0
        hpp, bp, hpl, valid, hll, bl = _linearise(
            cur_poses, cur_points, obs_kf, meas, stereo, info, cam, k_mono, k_stereo,
            free, n_free, order, starts,
        )  # fmt: skip
        _add_odometry(cur_poses, *edges, free, hpp, bp)
        for _try in range(10):
            dposes, dpoints, ok = _damped_step(
                hpp, bp, hpl, valid, hll, bl, obs_kf, free, n_free, order, starts, lam
            )
            if not ok:  # an indefinite system: damp more at the same linearisation point
                lam *= 10.0
                continue
            new_poses = cur_poses.copy()
            for k in range(n_kf):
                if free[k] >= 0:
                    new_poses[k] = _exp(dposes[free[k]]) @ cur_poses[k]
            new_points = cur_points + dpoints
            new_cost = ba_cost(new_poses, new_points, *args) + odometry_cost(new_poses, *edges)
            if new_cost <= cost:
                accepted = True
                decrease = cost - new_cost
                cur_poses, cur_points, cost = new_poses, new_points, new_cost
                lam = max(lam * 0.1, 1e-9)
                break
            lam *= 10.0
        if not accepted or decrease <= 1e-5 * cost:
            break
    return cur_poses, cur_points, cost0, cost


@numba.njit(cache=True)
def levenberg_marquardt(
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
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:  # pragma: no cover
    """Optimise the poses not ``fixed`` and every point; ``(poses, points, cost0, cost)``.

    The inputs are not modified. ``iterations`` counts accepted or final steps; a
    rejected step raises the damping tenfold and is tried again (at most 10 times per
    iteration, as gtsam's inner loop). Stops early when the cost falls by less than
    1e-5 of itself (gtsam's ``relativeErrorTol``).
    """
    no_edges = np.zeros(0, dtype=np.int64)
    return levenberg_marquardt_odometry(
        poses, points, obs_kf, obs_pt, meas, stereo, info, cam, k_mono, k_stereo, fixed,
        iterations, no_edges, no_edges, np.zeros((0, 4, 4)), np.zeros((0, 6, 6)),
    )  # fmt: skip
