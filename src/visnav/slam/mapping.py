"""Local mapping steps run when a keyframe is inserted (ORB-SLAM's LocalMapping).

* :func:`create_points`: back-project the keyframe's unmatched keypoints that
  have depth into new map points (close ones first; far ones only while the keyframe
  has few points, as ORB-SLAM2's ``Tracking::CreateNewKeyFrame``);
* :func:`cull_recent_points`: drop young points that tracking rarely finds or
  that no second keyframe observes;
* :func:`fuse_points`: project points into a keyframe and merge duplicates (or
  add observations), which keeps one map point per physical point.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.geometry import transform
from visnav.slam.matching import TH_LOW, search_by_projection
from visnav.slam.slam_map import Keyframe, SlamMap

__all__ = ["create_points", "cull_recent_points", "fuse_points"]

IntArray = NDArray[np.int64]


def create_points(
    slam_map: SlamMap, kf: Keyframe, *, close_depth: float | None = None, min_points: int = 100
) -> IntArray:
    """Create map points from ``kf``'s keypoints that have depth and no map point.

    Args:
        slam_map: the map the points join.
        kf: the keyframe whose keypoints are back-projected.
        close_depth: None: every keypoint with depth. Else ORB-SLAM2's rule for a new
            keyframe: keypoints are taken nearest first, and past ``close_depth`` only
            until more than ``min_points`` keypoints (with a map point already or a new
            one) have been counted. A far depth is poor (its error grows with the square
            of the range, 4 cm at 5 m for a Kinect-like sensor), and points made from it
            pull the next poses off where only far points are in view.
        min_points: see ``close_depth``.
    """
    f = kf.frame
    with_depth = np.isfinite(f.depth)
    new = np.flatnonzero((f.map_points < 0) & with_depth)
    if close_depth is not None and len(new):
        order = np.flatnonzero(with_depth)
        order = order[np.argsort(f.depth[order], kind="stable")]
        # counted nearest first; the last one taken is the first past close_depth that
        # brings the count above min_points
        far = np.flatnonzero(f.depth[order] > close_depth)
        stop = far[far >= min_points]
        cut = int(stop[0]) + 1 if len(stop) else len(order)
        keep = np.zeros(len(f.depth), dtype=bool)
        keep[order[:cut]] = True
        new = new[keep[new]]
    if len(new) == 0:
        return np.zeros(0, dtype=np.int64)
    pw = transform(kf.t_wc, f.points_c[new])
    return slam_map.add_points(pw, f.descriptors[new], kf, new)


def cull_recent_points(slam_map: SlamMap, current_kf: int, *, window: int = 3) -> int:
    """Cull points created in the last ``window`` keyframes that are not reliable.

    A point goes when tracking found it in under 25 % of the frames it should have
    been visible in, or when two keyframes after its creation fewer than two
    keyframes observe it. Returns how many were culled.
    """
    n = slam_map.n_points
    if n == 0:
        return 0
    first = slam_map.first_kf[:n]
    recent = np.flatnonzero(
        ~slam_map.bad[:n] & (first >= current_kf - window) & (first < current_kf)
    )
    if len(recent) == 0:
        return 0
    ratio = slam_map.found[recent] / np.maximum(slam_map.visible[recent], 1)
    n_obs = np.fromiter(
        (len(slam_map.observations[p]) for p in recent.tolist()), dtype=np.int64, count=len(recent)
    )
    age = current_kf - first[recent]
    bad = (ratio < 0.25) | ((age >= 2) & (n_obs < 2))
    for p in recent[bad].tolist():
        slam_map.cull_point(p)
    return int(bad.sum())


def fuse_points(
    slam_map: SlamMap,
    cam: CameraIntrinsics,
    kf: Keyframe,
    points: IntArray,
    *,
    radius: float = 3.0,
) -> int:
    """Project ``points`` into ``kf``; merge with the keyframe's points or add observations.

    Of two duplicates the one with more observations survives. Returns the number
    of points merged or newly observed.
    """
    if len(points) == 0:
        return 0
    pts = points[~slam_map.bad[points]]
    seen = np.fromiter(
        (kf.id in slam_map.observations[p] for p in pts.tolist()), dtype=bool, count=len(pts)
    )
    pts = pts[~seen]
    if len(pts) == 0:
        return 0
    mi, ki = search_by_projection(
        kf.frame,
        cam,
        kf.t_cw,
        slam_map.positions[pts],
        slam_map.descriptors[pts],
        radius=radius,
        max_distance=TH_LOW,
        ratio=1.0,
    )
    changed = 0
    for p, kp in zip(pts[mi].tolist(), ki.tolist(), strict=True):
        if slam_map.bad[p] or kf.id in slam_map.observations[p]:
            continue
        existing = int(kf.frame.map_points[kp])
        if existing >= 0 and not slam_map.bad[existing]:
            if existing == p:
                continue
            if len(slam_map.observations[existing]) >= len(slam_map.observations[p]):
                slam_map.replace_point(p, existing)
            else:
                slam_map.replace_point(existing, p)
        else:
            slam_map.add_observation(p, kf, kp)
        changed += 1
    return changed
