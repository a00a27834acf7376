"""Bundle adjustment (compiled, gtsam for large problems) and pose-graph optimisation (gtsam).

* :func:`bundle_adjustment`: keyframe poses and map points on reprojection
  factors; observations with depth use a virtual-stereo factor (gtsam's
  ``GenericStereoFactor3D``, as ORB-SLAM2 treats RGB-D), the others a monocular
  projection factor; Huber kernels, sigma of one pixel times the octave scale.
  Local BA optimises a window of covisible keyframes with the other keyframes
  that see the window's points held fixed; global BA optimises everything but
  the first keyframe. Up to :data:`MAX_DENSE_KEYFRAMES` free poses the compiled
  solver of :mod:`visnav.slam._ba_kernels` runs (same factors and kernels, held
  poses exactly fixed instead of gtsam's 1e-6 prior), larger problems gtsam.
* :func:`optimize_pose_graph`: keyframe poses only, on relative-pose factors
  from the spanning tree, strong covisibility and loop closures
  (``BetweenFactorPose3``), the first keyframe fixed.

gtsam poses are camera poses ``T_wc`` (camera -> world); the map keeps ``T_cw``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.slam._ba_kernels import levenberg_marquardt_odometry
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.geometry import CHI2_MONO, CHI2_STEREO, inverse, orthonormalize, transform
from visnav.slam.odometry_prior import OdometryEdge
from visnav.slam.slam_map import SlamMap

__all__ = [
    "MAX_DENSE_KEYFRAMES",
    "BaProblem",
    "BaResult",
    "BaSolution",
    "LoopConstraint",
    "apply_point_corrections",
    "ba_problem",
    "bundle_adjustment",
    "erase_outliers",
    "optimize_pose_graph",
    "solve_ba",
    "store_ba",
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

    ``error`` is the solver's failure text (gtsam raised, e.g. on an indeterminate
    system; the compiled solver's result was not finite); the map is then left as it was.
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


MAX_DENSE_KEYFRAMES = 60
"""Free poses up to which bundle adjustment solves the dense reduced system (compiled)."""


def bundle_adjustment(
    slam_map: SlamMap,
    cam: CameraIntrinsics,
    keyframe_ids: list[int],
    *,
    inv_sigma2_levels: FloatArray,
    fixed_ids: list[int] | None = None,
    iterations: int = 10,
    min_observations: int = 1,
    max_dense_keyframes: int | None = None,
    odometry: Sequence[OdometryEdge] = (),
) -> BaResult:
    """Optimise the poses of ``keyframe_ids`` and the points they observe, in place.

    Up to ``max_dense_keyframes`` free poses (every local window) the compiled solver of
    :mod:`visnav.slam._ba_kernels` runs (Schur complement, dense reduced system); larger
    problems (global BA over a long run) go to gtsam's sparse elimination.

    Args:
        slam_map: the map (poses and points are updated, outlier observations erased).
        cam: intrinsics.
        keyframe_ids: keyframes to optimise.
        inv_sigma2_levels: per pyramid level, ``1 / scale^2``.
        fixed_ids: keyframes whose poses are held (default: every other keyframe that
            observes one of the points; keyframe 0 is always held).
        iterations: Levenberg-Marquardt iterations.
        min_observations: points with fewer observations in the problem are left out.
        max_dense_keyframes: the most free poses the compiled solver takes (None:
            :data:`MAX_DENSE_KEYFRAMES`).
        odometry: relative-pose factors between keyframes from the robot's odometry
            (those with a keyframe outside the problem, or both held, are left out).

    Returns:
        Sizes, outliers removed and the error before/after; a solver failure is in
        ``error`` (the map is then unchanged).
    """
    problem = ba_problem(
        slam_map,
        keyframe_ids,
        fixed_ids=fixed_ids,
        min_observations=min_observations,
        odometry=odometry,
    )
    if isinstance(problem, BaResult):
        return problem
    solution = solve_ba(problem, cam, inv_sigma2_levels, iterations, max_dense_keyframes)
    return store_ba(slam_map, cam, problem, solution)


@dataclass(frozen=True)
class BaSolution:
    """A solver's output for a :class:`BaProblem` (``error``: why it failed)."""

    t_cw: FloatArray
    positions: FloatArray
    error_before: float
    error_after: float
    error: str = ""


def ba_problem(
    slam_map: SlamMap,
    keyframe_ids: list[int],
    *,
    fixed_ids: list[int] | None = None,
    min_observations: int = 1,
    odometry: Sequence[OdometryEdge] = (),
) -> BaProblem | BaResult:
    """Gather a bundle adjustment's variables and observations from the map (a snapshot).

    Arguments as :func:`bundle_adjustment`'s. Returns the problem, or an empty
    :class:`BaResult` when there is nothing to optimise.
    """
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
    return BaProblem(slam_map, sorted(involved), fixed, obs_list, odometry, n_local=len(local))


def solve_ba(
    problem: BaProblem,
    cam: CameraIntrinsics,
    inv_sigma2_levels: FloatArray,
    iterations: int,
    max_dense_keyframes: int | None = None,
) -> BaSolution:
    """Solve a problem (compiled up to ``max_dense_keyframes`` free poses, else gtsam).

    A pure function of its arguments (no map): it can run in another process.
    """
    limit = MAX_DENSE_KEYFRAMES if max_dense_keyframes is None else max_dense_keyframes
    if int((~problem.fixed).sum()) <= limit:
        return _solve_compiled(problem, cam, inv_sigma2_levels, iterations)
    return _solve_gtsam(problem, cam, inv_sigma2_levels, iterations)


def store_ba(
    slam_map: SlamMap, cam: CameraIntrinsics, problem: BaProblem, solution: BaSolution
) -> BaResult:
    """Write a solution into the map, erase the outlier observations, report."""
    sizes = problem.sizes()
    if solution.error:
        e = solution.error_before
        return BaResult(*sizes, 0, e, e, solution.error)
    problem.store(slam_map, solution.t_cw, solution.positions)
    outliers = erase_outliers(slam_map, cam, problem.obs_list)
    slam_map.update_point_normals(problem.points)
    return BaResult(*sizes, outliers, solution.error_before, solution.error_after)


class BaProblem:
    """A bundle adjustment's variables and observations as arrays (map indices kept).

    A snapshot: the poses and point positions are copied when it is made, and it keeps
    no reference to the map, so it can be pickled and solved in another process while
    the map goes on changing (:mod:`visnav.slam.background_ba`).
    """

    def __init__(
        self,
        slam_map: SlamMap,
        keyframes: list[int],
        fixed: set[int],
        obs_list: list[tuple[int, int, int]],
        odometry: Sequence[OdometryEdge] = (),
        *,
        n_local: int = 0,
    ) -> None:
        self.keyframes = np.asarray(keyframes, dtype=np.int64)
        self.fixed = np.asarray([k in fixed for k in keyframes], dtype=bool)
        self.n_local = n_local
        index = {k: n for n, k in enumerate(keyframes)}
        self.odometry = [
            (index[e.i], index[e.j], e)
            for e in odometry
            if e.i in index and e.j in index and not (e.i in fixed and e.j in fixed)
        ]
        arr = np.asarray(obs_list, dtype=np.int64)
        self.obs_list = arr
        self.points, self.obs_pt = np.unique(arr[:, 2], return_inverse=True)
        self.obs_kf = np.searchsorted(self.keyframes, arr[:, 0])
        n = len(arr)
        self.uv = np.empty((n, 2))
        self.u_right = np.empty(n)
        self.octave = np.empty(n, dtype=np.int64)
        for k in np.unique(arr[:, 0]).tolist():  # one gather per keyframe
            rows = np.flatnonzero(arr[:, 0] == k)
            f = slam_map.keyframes[k].frame
            kp = arr[rows, 1]
            self.uv[rows] = f.uv[kp]
            self.u_right[rows] = f.u_right[kp]
            self.octave[rows] = f.octave[kp]
        self.stereo = np.isfinite(self.u_right)
        self.t_cw = np.stack([slam_map.keyframes[k].t_cw for k in keyframes])
        self.positions = slam_map.positions[self.points].astype(np.float64)

    def sizes(self) -> tuple[int, int, int, int]:
        """Free keyframes asked for, held keyframes, points, observations."""
        return self.n_local, int(self.fixed.sum()), len(self.points), len(self.obs_list)

    def store(self, slam_map: SlamMap, t_cw: FloatArray, positions: FloatArray) -> None:
        """Write optimised free poses and every point back into the map."""
        for i in np.flatnonzero(~self.fixed).tolist():
            slam_map.keyframes[int(self.keyframes[i])].t_cw = orthonormalize(t_cw[i])
        slam_map.positions[self.points] = positions


def _solve_compiled(
    problem: BaProblem, cam: CameraIntrinsics, inv_sigma2_levels: FloatArray, iterations: int
) -> BaSolution:
    pr = problem
    meas = np.column_stack([pr.uv, np.where(pr.stereo, pr.u_right, 0.0)])
    info = np.asarray(inv_sigma2_levels, dtype=np.float64)[pr.octave]
    camv = np.array([cam.fx, cam.fy, cam.cx, cam.cy, cam.bf])
    n_edges = len(pr.odometry)
    edge_a = np.array([a for a, _, _ in pr.odometry], dtype=np.int64).reshape(n_edges)
    edge_b = np.array([b for _, b, _ in pr.odometry], dtype=np.int64).reshape(n_edges)
    edge_zinv = np.ascontiguousarray(
        np.array([inverse(e.t_ij) for _, _, e in pr.odometry]).reshape(n_edges, 4, 4)
    )
    infos = [e.information for _, _, e in pr.odometry]
    edge_w = np.ascontiguousarray(np.array(infos, dtype=np.float64).reshape(n_edges, 6, 6))
    t_cw, positions, before, after = levenberg_marquardt_odometry(
        pr.t_cw,
        pr.positions,
        pr.obs_kf,
        pr.obs_pt,
        meas,
        pr.stereo,
        info,
        camv,
        float(np.sqrt(CHI2_MONO)),
        float(np.sqrt(CHI2_STEREO)),
        pr.fixed,
        int(iterations),
        edge_a,
        edge_b,
        edge_zinv,
        edge_w,
    )
    if not (np.isfinite(after) and np.isfinite(t_cw).all() and np.isfinite(positions).all()):
        text = f"bundle adjustment of {len(pr.keyframes)} keyframes diverged"
        return BaSolution(pr.t_cw, pr.positions, before, before, text)
    return BaSolution(t_cw, positions, before, after)  # half the robust sum of squares


def _solve_gtsam(
    problem: BaProblem, cam: CameraIntrinsics, inv_sigma2_levels: FloatArray, iterations: int
) -> BaSolution:
    gtsam = _gtsam()
    pr = problem
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    models = _Models(gtsam, inv_sigma2_levels)
    k_mono = gtsam.Cal3_S2(cam.fx, cam.fy, 0.0, cam.cx, cam.cy)
    k_stereo = gtsam.Cal3_S2Stereo(cam.fx, cam.fy, 0.0, cam.cx, cam.cy, cam.baseline)
    for i, t_cw in enumerate(pr.t_cw):
        pose = gtsam.Pose3(inverse(t_cw))
        values.insert(i, pose)
        if pr.fixed[i]:
            graph.add(_hold(gtsam, i, pose))
    for j, p in enumerate(pr.positions):
        values.insert(_POINT_KEY + j, gtsam.Point3(*p))
    for o in range(len(pr.obs_kf)):
        k, key = int(pr.obs_kf[o]), _POINT_KEY + int(pr.obs_pt[o])
        lvl = int(pr.octave[o])
        u, v = float(pr.uv[o, 0]), float(pr.uv[o, 1])
        if pr.stereo[o]:
            meas = gtsam.StereoPoint2(u, float(pr.u_right[o]), v)
            graph.add(gtsam.GenericStereoFactor3D(meas, models.stereo[lvl], k, key, k_stereo))
        else:
            meas2 = np.array([u, v])
            graph.add(gtsam.GenericProjectionFactorCal3_S2(meas2, models.mono[lvl], k, key, k_mono))
    swap = np.r_[3:6, 0:3]
    for a, b, edge in pr.odometry:  # gtsam's Pose3 tangent is (rotation, translation)
        model = gtsam.noiseModel.Gaussian.Information(edge.information[np.ix_(swap, swap)])
        graph.add(gtsam.BetweenFactorPose3(a, b, gtsam.Pose3(edge.t_ij), model))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(int(iterations))
    params.setVerbosityLM("SILENT")
    before = float(graph.error(values))
    try:
        result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    except RuntimeError as exc:
        text = f"bundle adjustment of {len(pr.keyframes)} keyframes failed in gtsam: {exc}"
        return BaSolution(pr.t_cw, pr.positions, before, before, text)
    after = float(graph.error(result))
    t_cw = np.stack([inverse(result.atPose3(i).matrix()) for i in range(len(pr.keyframes))])
    positions = np.stack([result.atPoint3(_POINT_KEY + j) for j in range(len(pr.points))])
    return BaSolution(t_cw, positions, before, after)


def erase_outliers(slam_map: SlamMap, cam: CameraIntrinsics, obs: IntArray) -> int:
    """Erase the observations (rows ``kf, keypoint, point``) that the map's poses reject.

    Rows no longer in the map (a background adjustment's snapshot is older) are skipped.

    Returns:
        How many were erased.
    """
    arr = np.asarray(obs, dtype=np.int64).reshape(-1, 3)
    arr = arr[np.argsort(arr[:, 0], kind="stable")]  # one slice per keyframe, rows in order
    ks, starts = np.unique(arr[:, 0], return_index=True)
    ends = [*starts[1:].tolist(), len(arr)]
    outliers = 0
    for k, a, b in zip(ks.tolist(), starts.tolist(), ends, strict=True):
        rows = arr[a:b]
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
        for kp_p, p in rows[bad, 1:].tolist():
            if slam_map.observations[p].get(k) == kp_p:  # still as it was (a snapshot's row)
                slam_map.erase_observation(p, k)
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
