"""SE(3) helpers and the motion-only pose optimisation used by tracking.

Poses inside the SLAM core are ``T_cw`` (4x4, world -> camera, so projecting a
map point is one matrix product); the public API reports ``T_wc`` (the camera
pose in the map frame). Perturbations are on the left: ``T <- exp(xi) T`` with
``xi = (rho, phi)``, translation first.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.tf.transforms import yaw_from_matrix

__all__ = [
    "CHI2_MONO",
    "CHI2_STEREO",
    "PoseObservations",
    "PosePrior",
    "inverse",
    "level_pose",
    "optimize_pose",
    "orthonormalize",
    "pose_covariance",
    "pose_information",
    "project",
    "rotation_angle",
    "se3_exp",
    "so3_log",
    "transform",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

CHI2_MONO = 5.991
"""95 % chi-square quantile, 2 degrees of freedom (u, v)."""
CHI2_STEREO = 7.815
"""95 % chi-square quantile, 3 degrees of freedom (u, v, u_right)."""


def inverse(t: FloatArray) -> FloatArray:
    """Invert a rigid 4x4 transform."""
    out = np.eye(4)
    r = t[:3, :3].T
    out[:3, :3] = r
    out[:3, 3] = -r @ t[:3, 3]
    return out


def transform(t: FloatArray, points: FloatArray) -> FloatArray:
    """Apply a 4x4 transform to (N, 3) points."""
    out: FloatArray = points @ t[:3, :3].T + t[:3, 3]
    return out


def _hat(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def se3_exp(xi: FloatArray) -> FloatArray:
    """Exponential map of a twist ``(rho, phi)`` to a 4x4 transform."""
    rho, phi = xi[:3], xi[3:]
    theta = float(np.linalg.norm(phi))
    k = _hat(phi)
    if theta < 1e-10:
        r = np.eye(3) + k
        v = np.eye(3) + 0.5 * k
    else:
        a = np.sin(theta) / theta
        b = (1.0 - np.cos(theta)) / theta**2
        c = (theta - np.sin(theta)) / theta**3
        r = np.eye(3) + a * k + b * (k @ k)
        v = np.eye(3) + b * k + c * (k @ k)
    out = np.eye(4)
    out[:3, :3] = r
    out[:3, 3] = v @ rho
    return out


def so3_log(r: FloatArray) -> FloatArray:
    """Rotation vector (axis times angle, rad) of a 3x3 rotation, accurate near 0."""
    v = 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    sin = float(np.linalg.norm(v))
    cos = 0.5 * (float(np.trace(r)) - 1.0)
    theta = float(np.arctan2(sin, cos))
    if sin < 1e-12:
        if cos > 0.0:
            return v  # the identity (and its first-order neighbourhood)
        # theta = pi: the axis is the column of R + I with the largest norm
        m = r + np.eye(3)
        axis = m[:, int(np.argmax(np.linalg.norm(m, axis=0)))]
        half_turn: FloatArray = np.pi * axis / np.linalg.norm(axis)
        return half_turn
    out: FloatArray = v * (theta / sin)
    return out


def orthonormalize(t: FloatArray) -> FloatArray:
    """Return ``t`` with its rotation part projected onto SO(3) (SVD).

    Products of many transforms drift off SO(3) by rounding; the constant-velocity
    prediction multiplies by an inverse computed as a transpose, which amplifies
    that drift, so tracking re-projects every estimated pose.
    """
    u, _, vt = np.linalg.svd(t[:3, :3])
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, 2] *= -1.0
        r = u @ vt
    out = t.copy()
    out[:3, :3] = r
    out[3] = (0.0, 0.0, 0.0, 1.0)
    result: FloatArray = out
    return result


def rotation_angle(t: FloatArray) -> float:
    """Rotation angle (rad) of a transform's rotation part."""
    r = t[:3, :3]
    v = (r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1])
    sin = 0.5 * float(np.linalg.norm(v))
    cos = 0.5 * (float(np.trace(r)) - 1.0)
    return float(np.arctan2(sin, cos))  # accurate near 0, unlike arccos


def project(
    cam: CameraIntrinsics, t_cw: FloatArray, points_w: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Project world points; return ``(uv (N, 2), depth (N,))`` (depth <= 0 behind)."""
    pc = transform(t_cw, points_w)
    z = pc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / z
    uv = np.empty((len(pc), 2))
    uv[:, 0] = cam.fx * pc[:, 0] * inv + cam.cx
    uv[:, 1] = cam.fy * pc[:, 1] * inv + cam.cy
    return uv, z


@dataclass
class PoseObservations:
    """Matched observations for pose optimisation.

    Attributes:
        points_w: (N, 3) map points in the world frame.
        uv: (N, 2) observed pixels.
        u_right: (N,) virtual right-image u (NaN where the feature has no depth).
        inv_sigma2: (N,) information weight per observation (1 / scale^2 of its octave).
    """

    points_w: FloatArray
    uv: FloatArray
    u_right: FloatArray
    inv_sigma2: FloatArray


@dataclass(frozen=True)
class PosePrior:
    """A Gaussian prior on a camera pose (wheel odometry's prediction, for example).

    Its residual at a pose ``T`` is the left twist ``log(T T_prior^-1)`` (translation
    first, in the camera frame, as the optimisation's perturbations), to first order.

    Attributes:
        t_cw: the predicted world -> camera pose.
        information: (6, 6) inverse covariance of that twist.
    """

    t_cw: FloatArray
    information: FloatArray

    def residual(self, t_cw: FloatArray) -> FloatArray:
        """The twist from the prior to ``t_cw`` (6,)."""
        e = t_cw @ inverse(self.t_cw)
        return np.concatenate([e[:3, 3], so3_log(e[:3, :3])])


def _residuals(
    cam: CameraIntrinsics,
    t: FloatArray,
    obs: PoseObservations,
    stereo: BoolArray,
    ur_obs: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return camera-frame points, residuals (n, 3) and chi-square values."""
    pc = transform(t, obs.points_w)
    z = pc[:, 2]
    inv_z = 1.0 / np.where(z > 1e-3, z, 1.0)
    u = cam.fx * pc[:, 0] * inv_z + cam.cx
    v = cam.fy * pc[:, 1] * inv_z + cam.cy
    e = np.empty((len(pc), 3))
    e[:, 0] = u - obs.uv[:, 0]
    e[:, 1] = v - obs.uv[:, 1]
    e[:, 2] = np.where(stereo, u - cam.bf * inv_z - ur_obs, 0.0)
    chi2 = obs.inv_sigma2 * np.einsum("ij,ij->i", e, e)
    return pc, e, chi2


def _jacobian(cam: CameraIntrinsics, pc: FloatArray, stereo: BoolArray) -> FloatArray:
    """(n, 3, 6) Jacobian of (u, v, u_right) w.r.t. a left twist (rho, phi)."""
    x, y, z = pc[:, 0], pc[:, 1], np.where(pc[:, 2] > 1e-3, pc[:, 2], 1.0)
    iz = 1.0 / z
    iz2 = iz * iz
    fx, fy, bf = cam.fx, cam.fy, cam.bf
    j = np.zeros((len(pc), 3, 6))
    j[:, 0, 0] = fx * iz
    j[:, 0, 2] = -fx * x * iz2
    j[:, 0, 3] = -fx * x * y * iz2
    j[:, 0, 4] = fx + fx * x * x * iz2
    j[:, 0, 5] = -fx * y * iz
    j[:, 1, 1] = fy * iz
    j[:, 1, 2] = -fy * y * iz2
    j[:, 1, 3] = -fy - fy * y * y * iz2
    j[:, 1, 4] = fy * x * y * iz2
    j[:, 1, 5] = fy * x * iz
    a2 = -fx * x * iz2 + bf * iz2
    j[:, 2, 0] = fx * iz
    j[:, 2, 2] = a2
    j[:, 2, 3] = a2 * y
    j[:, 2, 4] = fx - a2 * x
    j[:, 2, 5] = -fx * y * iz
    j[~stereo, 2, :] = 0.0
    return j


def optimize_pose(
    cam: CameraIntrinsics,
    t_cw: FloatArray,
    obs: PoseObservations,
    *,
    rounds: int = 4,
    iterations: int = 5,
    prior: PosePrior | None = None,
) -> tuple[FloatArray, BoolArray]:
    """Refine a camera pose on 3D-2D(-depth) matches, rejecting outliers.

    Gauss-Newton on reprojection (and virtual-disparity) errors with a Huber
    kernel, in ``rounds`` rounds; after each round observations whose chi-square
    error exceeds the 95 % quantile are excluded from the next (and re-included
    if they come back), as ORB-SLAM's motion-only bundle adjustment does. The
    last round has no kernel.

    Args:
        cam: intrinsics.
        t_cw: initial world -> camera pose.
        obs: the matches.
        rounds: outlier classification rounds.
        iterations: Gauss-Newton iterations per round (fewer when converged).
        prior: an optional Gaussian prior on the pose (never an outlier): it holds the
            directions the matches leave weak, e.g. a sideways shift traded against a
            turn when every matched point is far away.

    Returns:
        ``(t_cw, inliers)``: the refined pose and an (N,) inlier mask.
    """
    n = len(obs.uv)
    if n < 3:
        return t_cw.copy(), np.zeros(n, dtype=bool)
    inlier = np.ones(n, dtype=bool)
    stereo = np.isfinite(obs.u_right)
    ur_obs = np.where(stereo, obs.u_right, 0.0)
    thr = np.where(stereo, CHI2_STEREO, CHI2_MONO)
    delta = np.sqrt(thr)
    t = t_cw.copy()
    for rnd in range(rounds):
        robust = rnd < rounds - 1
        for _ in range(iterations):
            pc, e, chi2 = _residuals(cam, t, obs, stereo, ur_obs)
            ok = inlier & (pc[:, 2] > 1e-3)
            if int(ok.sum()) < 3:
                return t, np.zeros(n, dtype=bool)
            w = obs.inv_sigma2.copy()
            if robust:
                err = np.sqrt(chi2)
                w *= np.where(err <= delta, 1.0, delta / np.maximum(err, 1e-12))
            w[~ok] = 0.0
            jac = _jacobian(cam, pc, stereo).reshape(-1, 6)
            w_rows = np.repeat(w, 3)
            h = (jac * w_rows[:, None]).T @ jac
            g = jac.T @ (w_rows * e.reshape(-1))
            if prior is not None:
                h = h + prior.information
                g = g + prior.information @ prior.residual(t)
            try:
                dx = -np.linalg.solve(h + 1e-9 * np.eye(6), g)
            except np.linalg.LinAlgError:
                return t, np.zeros(n, dtype=bool)
            t = se3_exp(dx) @ t
            if float(np.abs(dx).max()) < 1e-6:
                break
        pc, _, chi2 = _residuals(cam, t, obs, stereo, ur_obs)
        inlier = (chi2 <= thr) & (pc[:, 2] > 1e-3)
        if int(inlier.sum()) < 3:
            break
    return orthonormalize(t), inlier


def pose_information(
    cam: CameraIntrinsics, t_cw: FloatArray, obs: PoseObservations, inliers: BoolArray
) -> FloatArray:
    """Gauss-Newton information (6x6, twist rho, phi) of the inlier matches of a pose.

    One pixel standard deviation at pyramid level 0 (:func:`pose_covariance` inverts it).
    """
    stereo = np.isfinite(obs.u_right)
    pc = transform(t_cw, obs.points_w[inliers])
    jac = _jacobian(cam, pc, stereo[inliers]).reshape(-1, 6)
    w_rows = np.repeat(obs.inv_sigma2[inliers], 3)
    h: FloatArray = (jac * w_rows[:, None]).T @ jac
    return h


def pose_covariance(
    cam: CameraIntrinsics, t_cw: FloatArray, obs: PoseObservations, inliers: BoolArray
) -> FloatArray:
    """Covariance (6x6, twist order rho, phi) of a pose refined by :func:`optimize_pose`.

    The inverse Gauss-Newton information of the inlier observations, with one pixel
    standard deviation at pyramid level 0; a large value along some direction means
    the matches do not pin the pose down (few points, all far or on one plane).
    """
    h = pose_information(cam, t_cw, obs, inliers)
    try:
        cov: FloatArray = np.linalg.inv(h + 1e-12 * np.eye(6)).astype(np.float64)
    except np.linalg.LinAlgError:
        return np.full((6, 6), np.inf)
    return cov


def level_pose(t_map_base: FloatArray, z: float) -> FloatArray:
    """Keep only x, y and yaw of a ground robot's pose, at height ``z`` (roll, pitch 0).

    Args:
        t_map_base: a 4x4 pose (x forward, z up, REP 103).
        z: the height to put it at.

    Returns:
        The level 4x4 pose; its yaw is ``atan2(R10, R00)`` of ``t_map_base``.
    """
    yaw = yaw_from_matrix(t_map_base)
    out = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    out[:2, :2] = [[c, -s], [s, c]]
    out[:2, 3] = t_map_base[:2, 3]
    out[2, 3] = z
    return out
