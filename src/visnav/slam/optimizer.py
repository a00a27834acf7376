"""Bundle adjustment and pose-graph optimisation with gtsam.

* :func:`bundle_adjustment`: keyframe poses and map points on reprojection
  factors; observations with depth use a virtual-stereo factor (gtsam's
  ``GenericStereoFactor3D``, as ORB-SLAM2 treats RGB-D), the others a monocular
  projection factor; Huber kernels, sigma of one pixel times the octave scale.
  Local BA optimises a window of covisible keyframes with the other keyframes
  that see the window's points held fixed; global BA optimises everything but
  the first keyframe.
* :func:`optimize_pose_graph`: keyframe poses only, on relative-pose factors
  from the spanning tree, strong covisibility and loop closures
  (``BetweenFactorPose3``), the first keyframe fixed.

gtsam poses are camera poses ``T_wc`` (camera -> world); the map keeps ``T_cw``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.geometry import CHI2_MONO, CHI2_STEREO, inverse, transform
from visnav.slam.slam_map import SlamMap

__all__ = [
    "BaResult",
    "LoopConstraint",
    "apply_point_corrections",
    "bundle_adjustment",
    "optimize_pose_graph",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_POINT_KEY = 1 << 40


@dataclass(frozen=True)
class LoopConstraint:
    """A measured relative pose ``T_ij`` (pose of keyframe j in keyframe i's frame).

    ``covariance`` (6x6, twist order rho, phi, perturbing keyframe j) weighs it in
    the pose graph; None uses a fixed 5 mm / 0.3 degree.
    """

    i: int
    j: int
    t_ij: FloatArray
    covariance: FloatArray | None = None


@dataclass(frozen=True)
class BaResult:
    """What a bundle adjustment did.

    ``error`` is the solver's failure text (gtsam raised: an indeterminate system, a
    point behind a camera...); the map is then left as it was.
    """

    keyframes: int
    fixed: int
    points: int
    observations: int
    outliers: int
    error_before: float
    error_after: float
    error: str = ""

    @property
    def ok(self) -> bool:
        """True when the solver ran to the end."""
        return not self.error


def _gtsam() -> Any:
    import gtsam  # noqa: PLC0415 - heavy; loaded when a graph is optimised

    return gtsam


_HOLD_SIGMA = 1e-6
"""Standard deviation (m, rad) of the prior that holds a fixed pose."""


def _hold(gtsam: Any, key: int, pose: Any) -> Any:
    """A factor holding ``key`` at ``pose``: a prior with a 1e-6 sigma.

    Not ``NonlinearEqualityPose3``: a hard constraint makes gtsam eliminate every clique
    that touches it by QR instead of Cholesky, and in bundle adjustment the held poses
    share the root clique with all the others, which made local BA 5-8x slower (1 s
    instead of 0.15 s with 6 held keyframes and 8,000 observations) for the same result.
    """
    noise = gtsam.noiseModel.Isotropic.Sigma(6, _HOLD_SIGMA)
    return gtsam.PriorFactorPose3(key, pose, noise)


class _Models:
    def __init__(self, gtsam: Any, inv_sigma2_levels: FloatArray) -> None:
        self.mono = []
        self.stereo = []
        for inv_s2 in inv_sigma2_levels:
            sigma = float(1.0 / np.sqrt(inv_s2))
            huber_m = gtsam.noiseModel.mEstimator.Huber.Create(float(np.sqrt(CHI2_MONO)))
            huber_s = gtsam.noiseModel.mEstimator.Huber.Create(float(np.sqrt(CHI2_STEREO)))
            self.mono.append(
                gtsam.noiseModel.Robust.Create(huber_m, gtsam.noiseModel.Isotropic.Sigma(2, sigma))
            )
            self.stereo.append(
                gtsam.noiseModel.Robust.Create(huber_s, gtsam.noiseModel.Isotropic.Sigma(3, sigma))
            )


def bundle_adjustment(
    slam_map: SlamMap,
    cam: CameraIntrinsics,
    keyframe_ids: list[int],
    *,
    inv_sigma2_levels: FloatArray,
    fixed_ids: list[int] | None = None,
    iterations: int = 10,
    min_observations: int = 1,
) -> BaResult:
    """Optimise the poses of ``keyframe_ids`` and the points they observe, in place.

    Args:
        slam_map: the map (poses and points are updated, outlier observations erased).
        cam: intrinsics.
        keyframe_ids: keyframes to optimise.
        inv_sigma2_levels: per pyramid level, ``1 / scale^2``.
        fixed_ids: keyframes whose poses are held (default: every other keyframe that
            observes one of the points; keyframe 0 is always held).
        iterations: Levenberg-Marquardt iterations.
        min_observations: points with fewer observations in the problem are left out.

    Returns:
        Sizes, outliers removed and the error before/after; a solver failure is in
        ``error`` (the map is then unchanged).
    """
    gtsam = _gtsam()
    local = sorted({k for k in keyframe_ids if not slam_map.keyframes[k].bad})
    points = slam_map.local_points(local)
    obs_list: list[tuple[int, int, int]] = []  # (kf, kp, point)
    involved: set[int] = set(local)
    for p in points.tolist():
        obs = slam_map.observations[p]
        if len(obs) < min_observations:
            continue
        for k, kp in obs.items():
            if slam_map.keyframes[k].bad:
                continue
            obs_list.append((k, kp, p))
            involved.add(k)
    fixed = set(fixed_ids) if fixed_ids is not None else (involved - set(local))
    fixed |= {0} & involved
    if involved and not fixed:
        fixed.add(min(involved))
    if not obs_list:
        return BaResult(len(local), len(fixed), 0, 0, 0, 0.0, 0.0)
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    models = _Models(gtsam, inv_sigma2_levels)
    k_mono = gtsam.Cal3_S2(cam.fx, cam.fy, 0.0, cam.cx, cam.cy)
    k_stereo = gtsam.Cal3_S2Stereo(cam.fx, cam.fy, 0.0, cam.cx, cam.cy, cam.baseline)
    for k in sorted(involved):
        pose = gtsam.Pose3(slam_map.keyframes[k].t_wc)
        values.insert(k, pose)
        if k in fixed:
            graph.add(_hold(gtsam, k, pose))
    used_points = sorted({p for _, _, p in obs_list})
    for p in used_points:
        values.insert(_POINT_KEY + p, gtsam.Point3(*slam_map.positions[p]))
    for k, kp, p in obs_list:
        f = slam_map.keyframes[k].frame
        lvl = int(f.octave[kp])
        u, v = float(f.uv[kp, 0]), float(f.uv[kp, 1])
        ur = float(f.u_right[kp])
        if np.isfinite(ur):
            graph.add(
                gtsam.GenericStereoFactor3D(
                    gtsam.StereoPoint2(u, ur, v), models.stereo[lvl], k, _POINT_KEY + p, k_stereo
                )
            )
        else:
            graph.add(
                gtsam.GenericProjectionFactorCal3_S2(
                    np.array([u, v]), models.mono[lvl], k, _POINT_KEY + p, k_mono
                )
            )
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(int(iterations))
    params.setVerbosityLM("SILENT")
    before = float(graph.error(values))
    try:
        result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    except RuntimeError as exc:
        text = f"bundle adjustment of {len(local)} keyframes failed in gtsam: {exc}"
        return BaResult(
            len(local), len(fixed), len(used_points), len(obs_list), 0, before, before, text
        )
    after = float(graph.error(result))
    for k in sorted(involved - fixed):
        slam_map.keyframes[k].t_cw = inverse(result.atPose3(k).matrix())
    for p in used_points:
        slam_map.positions[p] = result.atPoint3(_POINT_KEY + p)
    outliers = _erase_outliers(slam_map, cam, obs_list)
    slam_map.update_point_normals(np.asarray(used_points, dtype=np.int64))
    return BaResult(
        len(local), len(fixed), len(used_points), len(obs_list), outliers, before, after
    )


def _erase_outliers(
    slam_map: SlamMap, cam: CameraIntrinsics, obs_list: list[tuple[int, int, int]]
) -> int:
    arr = np.asarray(obs_list, dtype=np.int64)
    outliers = 0
    for k in np.unique(arr[:, 0]).tolist():
        rows = arr[arr[:, 0] == k]
        kf = slam_map.keyframes[k]
        f = kf.frame
        kp = rows[:, 1]
        pc = transform(kf.t_cw, slam_map.positions[rows[:, 2]])
        z = pc[:, 2]
        zs = np.where(z > 1e-6, z, 1e-6)
        u = cam.fx * pc[:, 0] / zs + cam.cx
        v = cam.fy * pc[:, 1] / zs + cam.cy
        ur = u - cam.bf / zs
        stereo = np.isfinite(f.u_right[kp])
        e2 = (u - f.uv[kp, 0]) ** 2 + (v - f.uv[kp, 1]) ** 2
        e2 += np.where(stereo, (ur - np.where(stereo, f.u_right[kp], 0.0)) ** 2, 0.0)
        chi2 = e2 * f.inv_sigma2[kp]
        bad = (chi2 > np.where(stereo, CHI2_STEREO, CHI2_MONO)) | (z <= 0)
        for p in rows[bad, 2].tolist():
            slam_map.erase_observation(int(p), k)
            outliers += 1
    return outliers


def optimize_pose_graph(
    slam_map: SlamMap,
    loops: list[LoopConstraint],
    *,
    min_covisibility: int = 100,
    iterations: int = 20,
    fixed: int = 0,
    max_error_ratio: float = 0.0,
) -> dict[int, FloatArray] | None:
    """Optimise keyframe poses on relative-pose constraints; return corrections.

    Edges: each keyframe to its spanning-tree parent, keyframe pairs sharing at least
    ``min_covisibility`` points, and the loop constraints; all measured from the
    current poses except loops. Keyframe poses are updated in place.

    With ``max_error_ratio`` > 0 the result is refused (poses left as they were, None
    returned) when any edge's error after optimisation exceeds that many standard
    deviations (the whitened error norm), as RTAB-Map's ``RGBD/OptimizeMaxError``: a
    false loop (a look-alike room) can only be satisfied by bending the keyframe chain
    far beyond its uncertainty, a true one by a little everywhere.

    Returns:
        Per keyframe id, the world-frame correction ``T_new_old`` (4x4) to apply to
        the map points it anchors; None when refused.
    """
    gtsam = _gtsam()
    kfs = [kf for kf in slam_map.keyframes if not kf.bad]
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.01, 0.01, 0.01, 0.02, 0.02, 0.02]))
    loop_noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.005, 0.005, 0.005, 0.01, 0.01, 0.01]))
    old: dict[int, FloatArray] = {kf.id: kf.t_wc for kf in kfs}
    for kf in kfs:
        values.insert(kf.id, gtsam.Pose3(old[kf.id]))
    graph.add(_hold(gtsam, fixed, gtsam.Pose3(old[fixed])))
    seen: set[tuple[int, int]] = set()

    def between(i: int, j: int, model: Any, t_ij: FloatArray | None = None) -> None:
        key = (min(i, j), max(i, j))
        if t_ij is None:
            if key in seen:
                return
            seen.add(key)
            t_ij = inverse(old[i]) @ old[j]
        graph.add(gtsam.BetweenFactorPose3(i, j, gtsam.Pose3(t_ij), model))

    for kf in kfs:
        if kf.parent >= 0 and kf.parent in old:
            between(kf.parent, kf.id, noise)
        for other, w in kf.connections.items():
            if w >= min_covisibility and other in old:
                between(kf.id, other, noise)
    for lc in loops:
        if lc.i in old and lc.j in old:
            model = loop_noise
            if lc.covariance is not None:
                # gtsam orders Pose3 tangents rotation first
                perm = [3, 4, 5, 0, 1, 2]
                cov = lc.covariance[np.ix_(perm, perm)] + np.eye(6) * 1e-8
                model = gtsam.noiseModel.Gaussian.Covariance(cov)
            between(lc.i, lc.j, model, lc.t_ij)
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(int(iterations))
    params.setVerbosityLM("SILENT")
    result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    if max_error_ratio > 0 and _max_whitened_error(graph, result) > max_error_ratio:
        return None
    corrections: dict[int, FloatArray] = {}
    for kf in kfs:
        new = result.atPose3(kf.id).matrix()
        corrections[kf.id] = new @ inverse(old[kf.id])
        kf.t_cw = inverse(new)
    return corrections


def _max_whitened_error(graph: Any, values: Any) -> float:
    """The largest factor error in standard deviations (``sqrt(2 * error)``)."""
    worst = 0.0
    for i in range(graph.size()):
        factor = graph.at(i)
        if factor is not None:
            worst = max(worst, float(np.sqrt(2.0 * factor.error(values))))
    return worst


def apply_point_corrections(slam_map: SlamMap, corrections: dict[int, FloatArray]) -> None:
    """Move every good map point with the correction of its reference keyframe."""
    ids = slam_map.good_points()
    refs = slam_map.ref_kf[ids]
    for k in np.unique(refs).tolist():
        c = corrections.get(int(k))
        if c is None:
            continue
        sel = ids[refs == k]
        slam_map.positions[sel] = transform(c, slam_map.positions[sel])
