"""Monocular SLAM: two-view map initialisation with metric scale, and point triangulation.

A single camera measures no depth, so the map starts from two views (as ORB-SLAM's
``Initializer``): the first frame with enough keypoints becomes the reference; each
later frame is matched to it (brute-force ORB matches with a ratio test, within a
window), the essential matrix is estimated by RANSAC (OpenCV's five-point solver,
whose RANSAC is seeded with a fixed constant, so the same input gives the same
model) and decomposed with the cheirality check (``cv2.recoverPose``). The inliers
are triangulated and kept when in front of both cameras, reprojected within the
chi-square bound of their octave and seen under some parallax; the frame pair is
accepted when the median parallax reaches ``init_min_parallax_deg`` with at least
``init_min_points`` points, otherwise initialisation keeps trying with the next
frame (a new reference is taken when the matches run out).

Only the essential-matrix model is used: ORB-SLAM also fits a homography and picks
by score, which matters for planar scenes seen under pure rotation; the five-point
solver copes with planar scenes under translation, and a rotation without
translation shows here as too little parallax (initialisation waits).

The two-view reconstruction has unit baseline; the metric scale comes from

* ``depth``: the median, over the reference keypoints with a valid depth pixel, of
  the depth image's depth divided by the triangulated depth (robust to holes and
  outliers; depth is used at initialisation only);
* ``odometry``: the odometry translation between the two frames (the estimate's
  is 1).

After initialisation the map grows by :func:`triangulate_new_points` (ORB-SLAM's
``CreateNewMapPoints``): unmatched keypoints of a new keyframe are matched to
those of its covisible neighbours along epipolar lines and triangulated; a point
is kept with positive depth in both views, enough parallax, small reprojection
errors and distances consistent with the two octaves. Nothing is read from a depth
image. Monocular SLAM drifts in scale (ORB-SLAM too): the scale is fixed once, at
initialisation, and bundle adjustment and tracking carry it on only approximately.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.config import check_mono_settings
from visnav.slam.errors import SlamInputError
from visnav.slam.features import Frame
from visnav.slam.geometry import CHI2_MONO, inverse, transform
from visnav.slam.matching import TH_LOW, match_descriptors
from visnav.slam.optimizer import BaResult, bundle_adjustment
from visnav.slam.slam_map import Keyframe, SlamMap

__all__ = [
    "MonoInitializer",
    "TwoView",
    "create_initial_map",
    "mono_ba_window",
    "triangulate_new_points",
    "two_view_geometry",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

MonoScale = Literal["depth", "odometry"]

_CHI2_1DOF = 3.841
"""95 % chi-square quantile, 1 degree of freedom (distance to an epipolar line)."""


@dataclass(frozen=True)
class TwoView:
    """A two-view reconstruction (reference frame ``r``, current frame ``c``).

    Attributes:
        t_cr: reference -> current camera transform; metric once scaled.
        ref_kp: reference keypoint index of each point.
        cur_kp: current keypoint index of each point.
        points_r: (N, 3) points in the reference camera frame.
        parallax_deg: median parallax of the points.
        matches: descriptor matches tried.
        inliers: RANSAC inliers of the essential matrix.
    """

    t_cr: FloatArray
    ref_kp: IntArray
    cur_kp: IntArray
    points_r: FloatArray
    parallax_deg: float
    matches: int
    inliers: int

    def scaled(self, scale: float) -> TwoView:
        """The same reconstruction with baseline and points multiplied by ``scale``."""
        t = self.t_cr.copy()
        t[:3, 3] *= scale
        return TwoView(
            t,
            self.ref_kp,
            self.cur_kp,
            self.points_r * scale,
            self.parallax_deg,
            self.matches,
            self.inliers,
        )


def _triangulate(
    p1: FloatArray, p2: FloatArray, xn1: FloatArray, xn2: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Linear (DLT) triangulation of normalised points with 3x4 poses ``p1``, ``p2``."""
    a = np.empty((len(xn1), 4, 4))
    a[:, 0] = xn1[:, 0, None] * p1[2] - p1[0]
    a[:, 1] = xn1[:, 1, None] * p1[2] - p1[1]
    a[:, 2] = xn2[:, 0, None] * p2[2] - p2[0]
    a[:, 3] = xn2[:, 1, None] * p2[2] - p2[1]
    if len(a) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=bool)
    _, _, vt = np.linalg.svd(a)
    h = vt[:, -1, :]
    ok = np.abs(h[:, 3]) > 1e-12
    x = h[:, :3] / np.where(ok, h[:, 3], 1.0)[:, None]
    return x, ok & np.all(np.isfinite(x), axis=1)


def _normalised(cam: CameraIntrinsics, uv: FloatArray) -> FloatArray:
    out = np.empty((len(uv), 2))
    out[:, 0] = (uv[:, 0] - cam.cx) / cam.fx
    out[:, 1] = (uv[:, 1] - cam.cy) / cam.fy
    return out


def _reprojection_ok(
    cam: CameraIntrinsics, pc: FloatArray, uv: FloatArray, inv_sigma2: FloatArray
) -> NDArray[np.bool_]:
    z = np.where(pc[:, 2] > 1e-9, pc[:, 2], 1e-9)
    du = cam.fx * pc[:, 0] / z + cam.cx - uv[:, 0]
    dv = cam.fy * pc[:, 1] / z + cam.cy - uv[:, 1]
    ok: NDArray[np.bool_] = (du * du + dv * dv) * inv_sigma2 <= CHI2_MONO
    return ok


def _parallax_cos(x: FloatArray, c1: FloatArray, c2: FloatArray) -> FloatArray:
    r1 = x - c1
    r2 = x - c2
    n = np.linalg.norm(r1, axis=1) * np.linalg.norm(r2, axis=1)
    cos: FloatArray = np.einsum("ij,ij->i", r1, r2) / np.maximum(n, 1e-12)
    return cos


def two_view_geometry(
    ref: Frame,
    cur: Frame,
    cam: CameraIntrinsics,
    *,
    min_parallax_deg: float = 1.0,
    min_points: int = 50,
    search_fraction: float = 0.3,
    min_point_parallax_deg: float = 0.5,
) -> tuple[TwoView | None, str]:
    """Relative pose (unit baseline) and triangulated points of two frames.

    Args:
        ref: the reference frame.
        cur: the current frame.
        cam: intrinsics (rectified).
        min_parallax_deg: required median parallax of the triangulated points.
        min_points: required number of triangulated points (and of matches).
        min_point_parallax_deg: points seen under less parallax are dropped (their
            depth is too uncertain).
        search_fraction: matches moving more than this fraction of the image width
            are dropped.

    Returns:
        ``(reconstruction, "")`` or ``(None, why not)``; the reason starts with
        ``"reset:"`` when the reference no longer overlaps the frame (too few matches).
    """
    q, t = match_descriptors(ref.descriptors, cur.descriptors, ratio=0.9, max_distance=TH_LOW)
    if len(q):
        moved = np.linalg.norm(ref.uv[q] - cur.uv[t], axis=1)
        keep = moved <= search_fraction * cam.width
        q, t = q[keep], t[keep]
    n_matches = len(q)
    if n_matches < min_points:
        return None, f"reset: {n_matches} matches with the reference frame (need {min_points})"
    p1 = np.ascontiguousarray(ref.uv[q], dtype=np.float64)
    p2 = np.ascontiguousarray(cur.uv[t], dtype=np.float64)
    k = cam.matrix()
    e, mask = cv2.findEssentialMat(p1, p2, k, method=cv2.RANSAC, prob=0.999, threshold=1.0)
    if e is None or mask is None or e.shape[0] < 3:
        return None, f"no essential matrix from {n_matches} matches"
    e = np.ascontiguousarray(e[:3], dtype=np.float64)
    inl = mask.reshape(-1).astype(bool)
    n_inliers = int(inl.sum())
    _, r, tvec, _ = cv2.recoverPose(e, p1[inl], p2[inl], k)
    t_cr = np.eye(4)
    t_cr[:3, :3] = r
    t_cr[:3, 3] = np.asarray(tvec, dtype=np.float64).reshape(3)
    t_cr[:3, 3] /= max(float(np.linalg.norm(t_cr[:3, 3])), 1e-12)
    qi, ti = q[inl], t[inl]
    xn1 = _normalised(cam, ref.uv[qi])
    xn2 = _normalised(cam, cur.uv[ti])
    x, ok = _triangulate(np.eye(4)[:3], t_cr[:3], xn1, xn2)
    pc2 = transform(t_cr, x)
    centre2 = inverse(t_cr)[:3, 3]
    cos = _parallax_cos(x, np.zeros(3), centre2)
    good = (
        ok
        & (x[:, 2] > 0)
        & (pc2[:, 2] > 0)
        & _reprojection_ok(cam, x, ref.uv[qi], ref.inv_sigma2[qi])
        & _reprojection_ok(cam, pc2, cur.uv[ti], cur.inv_sigma2[ti])
        & (cos < np.cos(np.radians(min_point_parallax_deg)))
    )
    n_good = int(good.sum())
    if n_good == 0:
        return None, f"no point triangulated from {n_inliers} inliers (too little parallax)"
    parallax = float(np.degrees(np.median(np.arccos(np.clip(cos[good], -1.0, 1.0)))))
    if parallax < min_parallax_deg:
        return None, (
            f"median parallax {parallax:.2f} deg < {min_parallax_deg:g} deg "
            f"({n_good} points); keep moving the camera (translation, not only rotation)"
        )
    if n_good < min_points:
        return None, f"{n_good} points triangulated of {n_inliers} inliers (need {min_points})"
    view = TwoView(t_cr, qi[good], ti[good], x[good], parallax, n_matches, n_inliers)
    return view, ""


def _depth_at(
    depth_m: NDArray[np.float32], uv: FloatArray, *, min_depth: float, max_depth: float
) -> FloatArray:
    h, w = depth_m.shape[:2]
    ui = np.clip(np.rint(uv[:, 0]).astype(np.int64), 0, w - 1)
    vi = np.clip(np.rint(uv[:, 1]).astype(np.int64), 0, h - 1)
    d = depth_m[vi, ui].astype(np.float64)
    d[~((d >= min_depth) & (d <= max_depth))] = np.nan
    return d


class MonoInitializer:
    """Two-view initialisation with metric scale (state: the reference frame).

    Args:
        camera: intrinsics.
        scale: ``"depth"`` or ``"odometry"``.
        min_parallax_deg: required median parallax.
        min_points: required triangulated points.
        min_depth: depth pixels below this are ignored (m).
        max_depth: depth pixels above this are ignored (m).
    """

    def __init__(
        self,
        camera: CameraIntrinsics,
        *,
        scale: MonoScale = "depth",
        min_parallax_deg: float = 1.0,
        min_points: int = 50,
        min_depth: float = 0.1,
        max_depth: float = 8.0,
    ) -> None:
        check_mono_settings("mono", scale)
        self.camera = camera
        self.scale: MonoScale = scale
        self.min_parallax_deg = float(min_parallax_deg)
        self.min_points = int(min_points)
        self.min_depth = float(min_depth)
        self.max_depth = float(max_depth)
        self.ref: Frame | None = None
        self.ref_depth: NDArray[np.float32] | None = None
        self.ref_odom: FloatArray | None = None
        self.first_odom: FloatArray | None = None
        self.attempts = 0
        self.resets = 0
        self.last_scale = float("nan")

    def _set_reference(
        self, frame: Frame, depth_m: NDArray[np.float32] | None, odom: FloatArray | None
    ) -> str:
        if len(frame) < 2 * self.min_points:
            self.ref = None
            return (
                f"{len(frame)} keypoints, need {2 * self.min_points} for a reference frame "
                "(point the camera at texture)"
            )
        self.ref, self.ref_depth, self.ref_odom = frame, depth_m, odom
        return (
            "reference frame set; move the camera (translation) until the views have "
            "enough parallax"
        )

    def step(
        self,
        frame: Frame,
        *,
        depth_m: NDArray[np.float32] | None,
        odom_pose: FloatArray | None,
    ) -> tuple[TwoView | None, str]:
        """Try to initialise with ``frame``; return the metric reconstruction or why not.

        Args:
            frame: the new frame (keypoints without depth).
            depth_m: its depth image in metres (needed with ``scale="depth"``).
            odom_pose: its ``T_odom_camera`` (needed with ``scale="odometry"``).

        Raises:
            SlamInputError: the input the scale needs is missing.
        """
        if self.scale == "odometry" and odom_pose is None:
            text = (
                "monocular SLAM with mono_scale 'odometry' got a frame without odometry "
                "(odom_pose None): pass odom_pose (T_odom_camera) for every frame until the map "
                "is initialised, or use mono_scale 'depth' with a depth image"
            )
            raise SlamInputError(text)
        if self.scale == "depth" and depth_m is None:
            text = (
                "monocular SLAM with mono_scale 'depth' got a frame without depth: pass the "
                "registered depth image until the map is initialised (it sets the scale), or use "
                "mono_scale 'odometry'"
            )
            raise SlamInputError(text)
        odom = None if odom_pose is None else np.asarray(odom_pose, dtype=np.float64)
        if self.first_odom is None and odom is not None:
            self.first_odom = odom
        if self.ref is None:
            return None, f"monocular initialisation: {self._set_reference(frame, depth_m, odom)}"
        self.attempts += 1
        view, why = two_view_geometry(
            self.ref,
            frame,
            self.camera,
            min_parallax_deg=self.min_parallax_deg,
            min_points=self.min_points,
        )
        if view is None:
            if why.startswith("reset: "):
                self.resets += 1
                new_ref = self._set_reference(frame, depth_m, odom)
                return None, f"monocular initialisation: {why[7:]}; new {new_ref}"
            return None, f"monocular initialisation: {why}"
        scale, why = self._scale(view, odom)
        if scale is None:
            return None, f"monocular initialisation: {why}"
        self.last_scale = scale
        return view.scaled(scale), ""

    def _scale(self, view: TwoView, odom: FloatArray | None) -> tuple[float | None, str]:
        if self.scale == "odometry":
            assert self.ref_odom is not None  # step() checked odom for every frame
            assert odom is not None
            moved = float(np.linalg.norm((inverse(self.ref_odom) @ odom)[:3, 3]))
            if moved < 1e-3:
                return None, (
                    f"odometry moved {moved * 1e3:.2f} mm between the initial frames while the "
                    "images show parallax: cannot scale (is the odometry frozen?)"
                )
            return moved, ""  # the estimate's baseline is 1
        assert self.ref is not None
        if self.ref_depth is None:
            return None, "the reference frame has no depth image"
        d = _depth_at(
            self.ref_depth,
            self.ref.uv[view.ref_kp],
            min_depth=self.min_depth,
            max_depth=self.max_depth,
        )
        valid = np.isfinite(d)
        n_valid = int(valid.sum())
        need = max(10, len(d) // 5)
        if n_valid < need:
            return None, (
                f"{n_valid} of {len(d)} triangulated keypoints have a valid depth pixel "
                f"(need {need}) to set the scale"
            )
        ratio = d[valid] / view.points_r[valid, 2]
        return float(np.median(ratio)), ""

    def origin(self, initial_pose: FloatArray) -> FloatArray:
        """``T_map_camera`` of the reference frame.

        With odometry, the map frame stays where ``initial_pose`` put the first frame
        seen even when a later frame became the reference.
        """
        if self.first_odom is not None and self.ref_odom is not None:
            out: FloatArray = initial_pose @ inverse(self.first_odom) @ self.ref_odom
            return out
        return initial_pose


def create_initial_map(
    slam_map: SlamMap,
    cam: CameraIntrinsics,
    ref: Frame,
    cur: Frame,
    view: TwoView,
    t_wc_ref: FloatArray,
    *,
    inv_sigma2_levels: FloatArray,
    iterations: int = 20,
    depth_m: NDArray[np.float32] | None = None,
    min_depth: float = 0.1,
    max_depth: float = 8.0,
    on_ba: Callable[[BaResult], None] | None = None,
) -> tuple[Keyframe, Keyframe]:
    """Add the two initial keyframes and their points, bundle-adjust, set the scale.

    ``on_ba`` receives the two-view bundle adjustment's result (a failed solver leaves
    the two-view geometry as it was; the caller counts and reports it).

    The bundle adjustment holds the reference keyframe; afterwards the map is
    rescaled about it (bundle adjustment cannot observe scale): with ``depth_m``
    (the reference frame's depth image) by the median ratio of sensor depth to map
    depth at the reference keypoints (measured after the adjustment, which corrects
    much of the two-view error: with a degree of rotation error on two degrees of
    parallax the depths before it are off by a factor of two), else so that the
    baseline keeps the metric length ``view`` has (scale from odometry).

    Returns:
        The reference and current keyframes (``cur.t_cw`` is set).
    """
    ref.map_points[:] = -1
    cur.map_points[:] = -1
    t_cw0 = inverse(t_wc_ref)
    ref.t_cw = t_cw0
    parent = slam_map.keyframes[-1].id if slam_map.keyframes else -1
    kf0 = slam_map.add_keyframe(ref, t_cw0, parent=parent)
    kf1 = slam_map.add_keyframe(cur, view.t_cr @ t_cw0, parent=kf0.id)
    ids = slam_map.add_points(
        transform(t_wc_ref, view.points_r), ref.descriptors[view.ref_kp], kf0, view.ref_kp
    )
    for p, k in zip(ids.tolist(), view.cur_kp.tolist(), strict=True):
        slam_map.add_observation(p, kf1, k)
    slam_map.update_point_normals(ids)
    slam_map.update_connections(kf0)
    slam_map.update_connections(kf1)
    baseline = float(np.linalg.norm(view.t_cr[:3, 3]))
    ba = bundle_adjustment(
        slam_map,
        cam,
        [kf0.id, kf1.id],
        inv_sigma2_levels=inv_sigma2_levels,
        fixed_ids=[kf0.id],
        iterations=iterations,
    )
    if on_ba is not None:
        on_ba(ba)
    centre0 = t_wc_ref[:3, 3]
    centre1 = kf1.t_wc[:3, 3]
    after = float(np.linalg.norm(centre1 - centre0))
    good = ids[~slam_map.bad[ids]]
    s = baseline / after if after > 1e-12 else 1.0
    if depth_m is not None:
        seen = [p for p in good.tolist() if kf0.id in slam_map.observations[p]]
        kp = np.asarray([slam_map.observations[p][kf0.id] for p in seen], dtype=np.int64)
        good = np.asarray(seen, dtype=np.int64)
        d = _depth_at(depth_m, ref.uv[kp], min_depth=min_depth, max_depth=max_depth)
        z = transform(t_cw0, slam_map.positions[good])[:, 2]
        valid = np.isfinite(d) & (z > 1e-9)
        if int(valid.sum()) >= 10:
            s = float(np.median(d[valid] / z[valid]))
    if after > 1e-12 and baseline > 0:
        moved = ids[~slam_map.bad[ids]]
        slam_map.positions[moved] = centre0 + s * (slam_map.positions[moved] - centre0)
        t_wc1 = kf1.t_wc
        t_wc1[:3, 3] = centre0 + s * (centre1 - centre0)
        kf1.t_cw = inverse(t_wc1)
    slam_map.update_connections(kf0)
    slam_map.update_connections(kf1)
    cur.t_cw = kf1.t_cw.copy()
    return kf0, kf1


def mono_ba_window(window: list[int]) -> list[int]:
    """The keyframes a monocular local BA optimises: the window but its two oldest.

    Bundle adjustment on projections alone cannot observe scale: with only one held
    pose (keyframe 0 early on) gtsam's steps move freely along the scale direction
    (+-30 % per run was measured). The two oldest window keyframes become held poses
    (as every keyframe outside the window that sees its points), which fixes the
    scale; the newest keyframe is always optimised.
    """
    if len(window) <= 2:
        return window[:1]
    oldest = set(sorted(window)[:2])
    return [k for k in window if k not in oldest or k == window[0]]


def _skew(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _epipolar_candidates(
    cam: CameraIntrinsics, kf1: Keyframe, kf2: Keyframe, kp1: IntArray, kp2: IntArray
) -> NDArray[np.uint8]:
    """(len(kp1), len(kp2)) mask: keypoint 2 near keypoint 1's epipolar line, off the epipole."""
    f1, f2 = kf1.frame, kf2.frame
    t21 = kf2.t_cw @ kf1.t_wc
    kinv = np.linalg.inv(cam.matrix())
    f21 = kinv.T @ _skew(t21[:3, 3]) @ t21[:3, :3] @ kinv
    x1 = np.column_stack([f1.uv[kp1], np.ones(len(kp1))])
    x2 = np.column_stack([f2.uv[kp2], np.ones(len(kp2))])
    lines = x1 @ f21.T
    num = lines @ x2.T
    den = np.maximum(lines[:, 0] ** 2 + lines[:, 1] ** 2, 1e-18)
    sigma2 = 1.0 / f2.inv_sigma2[kp2]
    near = (num * num) / den[:, None] < _CHI2_1DOF * sigma2[None, :]
    # ORB-SLAM skips keypoints next to the epipole (the depth is undetermined there)
    c1_in_2 = t21[:3, 3]
    if c1_in_2[2] > 1e-9:
        ex = cam.fx * c1_in_2[0] / c1_in_2[2] + cam.cx
        ey = cam.fy * c1_in_2[1] / c1_in_2[2] + cam.cy
        d2 = (f2.uv[kp2, 0] - ex) ** 2 + (f2.uv[kp2, 1] - ey) ** 2
        near &= (d2 >= 100.0 * np.sqrt(sigma2))[None, :]
    out: NDArray[np.uint8] = near.astype(np.uint8)
    return out


def _match_epipolar(
    kf1: Keyframe,
    kf2: Keyframe,
    mask: NDArray[np.uint8],
    kp1: IntArray,
    kp2: IntArray,
    *,
    ratio: float,
) -> tuple[IntArray, IntArray]:
    matcher: Any = cv2.BFMatcher(cv2.NORM_HAMMING)
    knn = matcher.knnMatch(kf1.frame.descriptors[kp1], kf2.frame.descriptors[kp2], k=2, mask=mask)
    qi: list[int] = []
    ti: list[int] = []
    di: list[float] = []
    for pair in knn:
        if not pair or pair[0].distance > TH_LOW:
            continue
        if len(pair) > 1 and pair[0].distance >= ratio * pair[1].distance:
            continue
        qi.append(pair[0].queryIdx)
        ti.append(pair[0].trainIdx)
        di.append(pair[0].distance)
    if not qi:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    q = np.asarray(qi, dtype=np.int64)
    t = np.asarray(ti, dtype=np.int64)
    o = np.lexsort((q, np.asarray(di), t))
    q, t = q[o], t[o]
    first = np.ones(len(t), dtype=bool)
    first[1:] = t[1:] != t[:-1]
    return kp1[q[first]], kp2[t[first]]


def triangulate_new_points(
    slam_map: SlamMap,
    cam: CameraIntrinsics,
    kf: Keyframe,
    neighbours: list[int],
    *,
    scale_factor: float = 1.2,
    scales: FloatArray,
    ratio: float = 0.8,
    min_baseline_ratio: float = 0.04,
    min_parallax_deg: float = 4.0,
) -> int:
    """Create map points by triangulating ``kf``'s unmatched keypoints with its neighbours'.

    Per neighbour (skipped when the baseline is under ``min_baseline_ratio`` of its
    median scene depth): ORB matches restricted to the epipolar band (chi-square 1
    dof, sigma of the octave) with a ratio test, linear triangulation, then the
    checks of ORB-SLAM's ``CreateNewMapPoints``: rays not parallel (``min_parallax_deg``),
    positive depth in both cameras, reprojection chi-square < 5.991 in both, and the
    distance ratio consistent with the octave ratio.

    Args:
        slam_map: the map (points added).
        cam: intrinsics.
        kf: the new keyframe.
        neighbours: covisible keyframe ids, best first.
        scale_factor: ORB pyramid scale factor.
        scales: scale of each pyramid level.
        ratio: best / second-best descriptor distance ratio.
        min_baseline_ratio: baseline / median depth below which a neighbour is skipped.
        min_parallax_deg: smallest angle between the two rays (ORB-SLAM: cos 0.9998).

    Returns:
        The number of points created.
    """
    f1 = kf.frame
    t1_wc = kf.t_wc
    c1 = t1_wc[:3, 3]
    created = 0
    ratio_factor = 1.5 * scale_factor
    for n in neighbours:
        kf2 = slam_map.keyframes[n]
        if kf2.bad or n == kf.id:
            continue
        f2 = kf2.frame
        t2_wc = kf2.t_wc
        c2 = t2_wc[:3, 3]
        _, pts2 = slam_map.keyframe_points(kf2)
        if len(pts2) == 0:
            continue
        z2 = transform(kf2.t_cw, slam_map.positions[pts2])[:, 2]
        median_depth = float(np.median(z2))
        if median_depth <= 0 or np.linalg.norm(c2 - c1) / median_depth < min_baseline_ratio:
            continue
        kp1 = np.flatnonzero(f1.map_points < 0)
        kp2 = np.flatnonzero(f2.map_points < 0)
        if len(kp1) == 0 or len(kp2) < 2:
            continue
        mask = _epipolar_candidates(cam, kf, kf2, kp1, kp2)
        if not mask.any():
            continue
        m1, m2 = _match_epipolar(kf, kf2, mask, kp1, kp2, ratio=ratio)
        if len(m1) == 0:
            continue
        xn1 = _normalised(cam, f1.uv[m1])
        xn2 = _normalised(cam, f2.uv[m2])
        x, ok = _triangulate(kf.t_cw[:3], kf2.t_cw[:3], xn1, xn2)
        pc1 = transform(kf.t_cw, x)
        pc2 = transform(kf2.t_cw, x)
        cos = _parallax_cos(x, c1, c2)
        d1 = np.linalg.norm(x - c1, axis=1)
        d2 = np.linalg.norm(x - c2, axis=1)
        ratio_dist = d2 / np.maximum(d1, 1e-12)
        ratio_octave = scales[f1.octave[m1]] / scales[f2.octave[m2]]
        good = (
            ok
            & (cos > 0)
            & (cos < np.cos(np.radians(min_parallax_deg)))
            & (pc1[:, 2] > 0)
            & (pc2[:, 2] > 0)
            & _reprojection_ok(cam, pc1, f1.uv[m1], f1.inv_sigma2[m1])
            & _reprojection_ok(cam, pc2, f2.uv[m2], f2.inv_sigma2[m2])
            & (ratio_dist * ratio_factor >= ratio_octave)
            & (ratio_dist <= ratio_octave * ratio_factor)
        )
        if not good.any():
            continue
        ids = slam_map.add_points(x[good], f1.descriptors[m1[good]], kf, m1[good])
        for p, k in zip(ids.tolist(), m2[good].tolist(), strict=True):
            slam_map.add_observation(p, kf2, k)
        slam_map.update_point_normals(ids)
        created += len(ids)
    return created
