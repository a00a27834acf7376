"""Dense refinement of a tracked pose: point-to-plane ICP against a keyframe's depth.

Feature tracking pins a pose down to the precision of its keypoints (pyramid-level
pixels, depth sampled at one pixel each), which leaves about a millimetre of
frame-to-frame jitter. Dense RGB-D odometry uses every depth pixel instead. Here
the pose found by the features is refined on the depth image against the
reference keyframe's depth: projective data association and the point-to-plane
error of KinectFusion (Newcombe et al., ISMAR 2011; the linearisation of Low, 2004),
which is also what OpenCV's ``RgbdICPOdometry`` minimises. The feature pose's
Gauss-Newton information is kept as a prior, so directions the depth does not
constrain (a camera sliding along one flat wall) stay where the features put them;
a refinement that moves too far from the feature pose or finds too few
correspondences is refused (the feature pose stands).

The keyframe side (:class:`DepthModel`) is a vertex and a normal map at half
resolution (full resolution below 400 pixels wide: a coarser grid biases the
nearest-pixel association); the frame side is its depth sampled every ``stride``
pixels.

Each Gauss-Newton iteration (association, residual, weight and the 6x6 normal
equations) is one compiled pass over the frame's points (:func:`_icp_normal_equations`,
numba): the numpy version made ~40 array passes per iteration and cost the car's SLAM
worker ~8 ms a frame. The sums run in point order, so results differ from the numpy
version's BLAS sums only in the last bits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.config import SlamConfig
from visnav.slam.geometry import inverse, orthonormalize, se3_exp

__all__ = [
    "DenseResult",
    "DenseTracker",
    "DepthModel",
    "depth_model",
    "refine_pose_icp",
    "sample_points",
]

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]


@dataclass(frozen=True)
class DepthModel:
    """Vertex and normal maps of one depth image, subsampled (the ICP target).

    Attributes:
        vertices: (h, w, 3) float32 camera-frame points (NaN: no depth).
        normals: (h, w, 3) float32 unit normals facing the camera (NaN: none).
        fx, fy, cx, cy: intrinsics of the subsampled grid.
    """

    vertices: F32
    normals: F32
    fx: float
    fy: float
    cx: float
    cy: float


@dataclass(frozen=True)
class DenseResult:
    """Outcome of :func:`refine_pose_icp`.

    Attributes:
        t_cw: the refined world -> camera pose (the input when not ``ok``).
        ok: the refinement was accepted.
        inliers: correspondences used in the last iteration.
        information: (6, 6) Gauss-Newton information of the depth term (twist
            order rho, phi; left perturbation of ``t_cw``).
    """

    t_cw: FloatArray
    ok: bool
    inliers: int
    information: FloatArray


def _grid(
    depth_m: NDArray[np.float32], cam: CameraIntrinsics, step: int, min_d: float, max_d: float
) -> tuple[F32, float, float, float, float]:
    d = np.asarray(depth_m[::step, ::step], dtype=np.float32)
    d = np.where((d >= min_d) & (d <= max_d), d, np.float32(np.nan))
    h, w = d.shape
    fx, fy, cx, cy = cam.fx / step, cam.fy / step, cam.cx / step, cam.cy / step
    u = (np.arange(w, dtype=np.float32) - np.float32(cx)) / np.float32(fx)
    v = (np.arange(h, dtype=np.float32) - np.float32(cy)) / np.float32(fy)
    pts = np.empty((h, w, 3), dtype=np.float32)
    pts[:, :, 0] = u[None, :] * d
    pts[:, :, 1] = v[:, None] * d
    pts[:, :, 2] = d
    return pts, fx, fy, cx, cy


def depth_model(
    depth_m: NDArray[np.float32],
    cam: CameraIntrinsics,
    *,
    step: int = 2,
    span: int = 2,
    min_depth: float = 0.1,
    max_depth: float = 8.0,
) -> DepthModel:
    """Vertex and normal maps of a keyframe's depth (every ``step``-th pixel).

    Normals are the cross product of central differences ``span`` grid cells
    apart (wider than one cell, so depth noise tilts them less); a normal whose
    differences jump by more than 10 % of the depth (an occlusion edge) is NaN.

    Args:
        depth_m: (H, W) float32 metres (NaN: none), registered to the image.
        cam: intrinsics of the full-resolution image.
        step: subsampling of the grid.
        span: half-width of the normal's differences, in grid cells.
        min_depth: depths below this are ignored.
        max_depth: depths above this are ignored.
    """
    v, fx, fy, cx, cy = _grid(depth_m, cam, step, min_depth, max_depth)
    s = int(span)
    normals = np.full_like(v, np.nan)
    dx = v[s:-s, 2 * s :] - v[s:-s, : -2 * s]
    dy = v[2 * s :, s:-s] - v[: -2 * s, s:-s]
    n = np.cross(dx, dy)
    norm = np.linalg.norm(n, axis=2, keepdims=True)
    z = v[s:-s, s:-s, 2:3]
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / norm
        edge = (np.abs(dx[:, :, 2:3]) > 0.1 * z) | (np.abs(dy[:, :, 2:3]) > 0.1 * z)
        n = np.where(edge, np.float32(np.nan), n)
        facing = np.sum(n * v[s:-s, s:-s], axis=2, keepdims=True) > 0
    normals[s:-s, s:-s] = np.where(facing, -n, n)
    return DepthModel(v, normals.astype(np.float32), fx, fy, cx, cy)


def sample_points(
    depth_m: NDArray[np.float32],
    cam: CameraIntrinsics,
    *,
    stride: int = 4,
    min_depth: float = 0.1,
    max_depth: float = 8.0,
) -> FloatArray:
    """Camera-frame points of every ``stride``-th depth pixel that has a valid depth: (N, 3)."""
    v, *_ = _grid(depth_m, cam, stride, min_depth, max_depth)
    pts = v.reshape(-1, 3)
    out: FloatArray = pts[np.isfinite(pts[:, 2])].astype(np.float64)
    return out


@numba.njit(cache=True)
def _icp_normal_equations(
    p_c: FloatArray,
    t_rc: FloatArray,
    verts: F32,
    norms: F32,
    intrinsics: FloatArray,
    shape: tuple[int, int],
    limit: float,
    depth_sigma: float,
) -> tuple[FloatArray, FloatArray, int]:  # pragma: no cover - compiled; tests check results
    """One iteration's ``J^T W J``, ``J^T W r`` and inlier count (see refine_pose_icp)."""
    h, w = shape
    fx, fy, cx, cy = intrinsics[0], intrinsics[1], intrinsics[2], intrinsics[3]
    info = np.zeros((6, 6))
    g = np.zeros(6)
    jac = np.empty(6)
    n_in = 0
    limit2 = limit * limit
    for k in range(p_c.shape[0]):
        px, py, pz = p_c[k, 0], p_c[k, 1], p_c[k, 2]
        x = t_rc[0, 0] * px + t_rc[0, 1] * py + t_rc[0, 2] * pz + t_rc[0, 3]
        y = t_rc[1, 0] * px + t_rc[1, 1] * py + t_rc[1, 2] * pz + t_rc[1, 3]
        z = t_rc[2, 0] * px + t_rc[2, 1] * py + t_rc[2, 2] * pz + t_rc[2, 3]
        if not z > 1e-3:
            continue
        u = np.rint(fx * x / z + cx)
        v = np.rint(fy * y / z + cy)
        if not (u >= 0 and u < w and v >= 0 and v < h):
            continue
        flat = int(v) * w + int(u)
        n0, n1, n2 = float(norms[flat, 0]), float(norms[flat, 1]), float(norms[flat, 2])
        if not np.isfinite(n0):
            continue
        d0 = x - float(verts[flat, 0])
        d1 = y - float(verts[flat, 1])
        d2 = z - float(verts[flat, 2])
        if not d0 * d0 + d1 * d1 + d2 * d2 < limit2:
            continue
        n_in += 1
        r = n0 * d0 + n1 * d1 + n2 * d2
        sigma = depth_sigma * (z * z + pz * pz) * 0.5 + 1e-4
        e = abs(r / sigma)
        wgt = (1.0 if e <= 2.0 else 2.0 / max(e, 1e-12)) / (sigma * sigma)
        # the normal in the frame's camera coordinates: m = R_rc^T n
        m0 = n0 * t_rc[0, 0] + n1 * t_rc[1, 0] + n2 * t_rc[2, 0]
        m1 = n0 * t_rc[0, 1] + n1 * t_rc[1, 1] + n2 * t_rc[2, 1]
        m2 = n0 * t_rc[0, 2] + n1 * t_rc[1, 2] + n2 * t_rc[2, 2]
        jac[0], jac[1], jac[2] = -m0, -m1, -m2
        jac[3] = m1 * pz - m2 * py  # m x p
        jac[4] = m2 * px - m0 * pz
        jac[5] = m0 * py - m1 * px
        for i in range(6):
            wi = wgt * jac[i]
            g[i] += wi * r
            for j in range(i, 6):
                info[i, j] += wi * jac[j]
    for i in range(6):
        for j in range(i):
            info[i, j] = info[j, i]
    return info, g, n_in


def refine_pose_icp(
    model: DepthModel,
    t_rw: FloatArray,
    points_c: FloatArray,
    t_cw: FloatArray,
    *,
    prior: FloatArray | None = None,
    depth_sigma: float = 0.003,
    iterations: int = 5,
    max_distance: float = 0.05,
    max_correction: float = 0.03,
    max_rotation: float = 0.03,
    min_inliers: int = 500,
) -> DenseResult:
    """Refine ``t_cw`` so that the frame's points lie on the keyframe's surfaces.

    Gauss-Newton on the point-to-plane errors ``n . (T_rc p - q)`` (``q``, ``n``: the
    keyframe vertex and normal the transformed point projects to), weighted by the
    depth noise ``depth_sigma * z^2`` with a Huber kernel at two sigma, plus
    ``prior`` (the feature pose's information) on the deviation from the input pose.

    Args:
        model: the keyframe's :class:`DepthModel`.
        t_rw: the keyframe's world -> camera pose.
        points_c: (N, 3) frame points in the camera frame (:func:`sample_points`).
        t_cw: the frame's pose from the features (the starting point).
        prior: (6, 6) information of ``t_cw`` (twist rho, phi; None: none).
        depth_sigma: depth noise coefficient (m per m^2).
        iterations: Gauss-Newton iterations.
        max_distance: correspondences farther apart (m) are rejected.
        max_correction: largest accepted translation change (m).
        max_rotation: largest accepted rotation change (rad).
        min_inliers: fewer correspondences refuse the refinement.

    Returns:
        The refined pose, whether it was accepted, inliers and the depth information.
    """
    h, w = model.vertices.shape[:2]
    verts = np.ascontiguousarray(model.vertices.reshape(-1, 3))
    norms = np.ascontiguousarray(model.normals.reshape(-1, 3))
    intrinsics = np.array([model.fx, model.fy, model.cx, model.cy], dtype=np.float64)
    lam = np.zeros((6, 6)) if prior is None else np.asarray(prior, dtype=np.float64)
    t = t_cw.copy()
    delta = np.zeros(6)
    info = np.zeros((6, 6))
    n_in = 0
    p_c = np.ascontiguousarray(points_c, dtype=np.float64).reshape(-1, 3)
    for it in range(iterations):
        t_rc = np.ascontiguousarray(t_rw @ inverse(t), dtype=np.float64)
        limit = max_distance if it == 0 else max(max_distance / 2, 0.01)
        sums: tuple[FloatArray, FloatArray, int] = _icp_normal_equations(
            p_c, t_rc, verts, norms, intrinsics, (h, w), float(limit), float(depth_sigma)
        )
        info, g, n_in = sums
        if n_in < min_inliers:
            return DenseResult(t_cw.copy(), False, n_in, np.zeros((6, 6)))
        try:
            step = np.linalg.solve(info + lam + 1e-9 * np.eye(6), g + lam @ delta)
            dx = -np.asarray(step, dtype=np.float64)
        except np.linalg.LinAlgError:
            return DenseResult(t_cw.copy(), False, n_in, np.zeros((6, 6)))
        t = se3_exp(dx) @ t
        delta = delta + dx
        if float(np.abs(dx).max()) < 2e-5:  # 20 micrometres / microradians
            break
    change = t @ inverse(t_cw)
    angle = float(np.arccos(np.clip((np.trace(change[:3, :3]) - 1) / 2, -1.0, 1.0)))
    if float(np.linalg.norm(change[:3, 3])) > max_correction or angle > max_rotation:
        return DenseResult(t_cw.copy(), False, n_in, np.zeros((6, 6)))
    return DenseResult(orthonormalize(t), True, n_in, info)


class DenseTracker:
    """The depth models of the most recent keyframes and the refinement against them.

    Args:
        camera: intrinsics of the full-resolution images.
        stride: frame depth sampling (pixels) for :func:`sample_points`.
        keep: keyframe models kept (oldest dropped first; about 1.8 MB each at 640x480).
        min_depth: depths below this are ignored.
        max_depth: depths above this are ignored.
    """

    def __init__(
        self,
        camera: CameraIntrinsics,
        *,
        stride: int = 6,
        keep: int = 8,
        min_depth: float = 0.1,
        max_depth: float = 8.0,
    ) -> None:
        self.camera = camera
        self.stride = int(stride)
        self.keep = int(keep)
        self.min_depth = float(min_depth)
        self.max_depth = float(max_depth)
        self.step = 2 if camera.width >= 400 else 1  # half resolution from 640 x 480 up
        self._models: dict[int, DepthModel] = {}

    @classmethod
    def from_config(cls, camera: CameraIntrinsics, config: SlamConfig) -> DenseTracker | None:
        """The tracker ``config`` asks for (None when ``icp_refinement`` is off)."""
        if not config.icp_refinement:
            return None
        return cls(
            camera,
            stride=config.icp_stride,
            keep=config.icp_keyframes,
            min_depth=config.min_depth,
            max_depth=config.max_depth,
        )

    def add_keyframe(self, kf_id: int, depth_m: NDArray[np.float32]) -> None:
        """Keep the depth model of keyframe ``kf_id`` (dropping the oldest beyond ``keep``)."""
        self._models[kf_id] = depth_model(
            depth_m,
            self.camera,
            step=self.step,
            min_depth=self.min_depth,
            max_depth=self.max_depth,
        )
        while len(self._models) > self.keep:
            del self._models[next(iter(self._models))]

    def has(self, kf_id: int) -> bool:
        """True when keyframe ``kf_id``'s depth model is kept."""
        return kf_id in self._models

    def refine(
        self,
        kf_id: int,
        t_rw: FloatArray,
        depth_m: NDArray[np.float32],
        t_cw: FloatArray,
        prior: FloatArray | None,
    ) -> DenseResult:
        """Refine a frame's ``t_cw`` against keyframe ``kf_id`` (:func:`refine_pose_icp`).

        Refused (``ok`` False, the pose unchanged) without a kept model for ``kf_id``,
        or with correspondences for fewer than a quarter of the frame's samples.
        """
        model = self._models.get(kf_id)
        if model is None:
            return DenseResult(t_cw.copy(), False, 0, np.zeros((6, 6)))
        pts = sample_points(
            depth_m,
            self.camera,
            stride=self.stride,
            min_depth=self.min_depth,
            max_depth=self.max_depth,
        )
        min_inliers = max(100, len(pts) // 4)  # a quarter of the samples, at least 100
        return refine_pose_icp(model, t_rw, pts, t_cw, prior=prior, min_inliers=min_inliers)
