"""Place recognition: loop candidates from bag-of-words, geometric verification.

:func:`localize_in_map` finds the pose of a frame in the map around some
keyframes (used by loop verification and relocalisation): brute-force descriptor
matches against the keyframes' map points, PnP + RANSAC (OpenCV, seeded through
``cv2.setRNGSeed`` by the caller), a robust pose refinement using depth, then a
projection search for more matches and a final refinement.

:class:`LoopDetector` proposes loop candidates for a new keyframe as ORB-SLAM
does: keyframes not connected to it in the covisibility graph and not among the
most recent ones, whose bag-of-words similarity is at least the lowest similarity
between the keyframe and its covisible neighbours; optionally a candidate region
must be detected for ``consistency`` consecutive keyframes.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.features import Frame
from visnav.slam.geometry import PoseObservations, optimize_pose, pose_covariance
from visnav.slam.matching import match_descriptors, search_by_projection
from visnav.slam.slam_map import Keyframe, SlamMap
from visnav.slam.vocabulary import BowDatabase, Vocabulary

__all__ = ["Localization", "LoopDetector", "localize_in_map"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class Localization:
    """A frame's pose found in the map.

    Attributes:
        t_cw: world -> camera pose.
        keypoints: matched keypoint indices of the frame (inliers).
        points: the map point ids they match.
        covariance: 6x6 covariance of the pose (twist order rho, phi; 1 px at level 0).
    """

    t_cw: FloatArray
    keypoints: IntArray
    points: IntArray
    covariance: FloatArray

    def sigmas(self) -> tuple[float, float]:
        """Largest translation (m) and rotation (rad) standard deviation."""
        c = self.covariance
        st = float(np.sqrt(max(np.linalg.eigvalsh(c[:3, :3]).max(), 0.0)))
        sr = float(np.sqrt(max(np.linalg.eigvalsh(c[3:, 3:]).max(), 0.0)))
        return st, sr

    @property
    def inliers(self) -> int:
        """Number of inlier matches."""
        return len(self.keypoints)


def _observations(frame: Frame, slam_map: SlamMap, kp: IntArray, pts: IntArray) -> PoseObservations:
    return PoseObservations(
        slam_map.positions[pts], frame.uv[kp], frame.u_right[kp], frame.inv_sigma2[kp]
    )


def localize_in_map(
    frame: Frame,
    cam: CameraIntrinsics,
    slam_map: SlamMap,
    keyframe_ids: list[int],
    *,
    min_inliers: int = 30,
    ratio: float = 0.8,
    ransac_iterations: int = 300,
    reprojection_error: float = 4.0,
) -> Localization | None:
    """Find ``frame``'s pose from the map points of some keyframes, or None.

    Args:
        frame: keypoints (with depth where available).
        cam: intrinsics.
        slam_map: the map.
        keyframe_ids: keyframes whose map points to match against.
        min_inliers: inliers required after the final refinement.
        ratio: ratio test of the brute-force matching.
        ransac_iterations: PnP RANSAC iterations.
        reprojection_error: RANSAC inlier threshold (px).
    """
    points = slam_map.local_points(keyframe_ids)
    if len(points) < 10 or len(frame) < 10:
        return None
    q, t = match_descriptors(frame.descriptors, slam_map.descriptors[points], ratio=ratio)
    if len(q) < 12:
        return None
    pts = points[t]
    ok, rvec, tvec, inl = cv2.solvePnPRansac(
        slam_map.positions[pts].astype(np.float64),
        frame.uv[q].astype(np.float64),
        cam.matrix(),
        None,
        iterationsCount=int(ransac_iterations),
        reprojectionError=float(reprojection_error),
        confidence=0.999,
        flags=cv2.SOLVEPNP_AP3P,
    )
    if not ok or inl is None or len(inl) < 10:
        return None
    inl = inl.reshape(-1)
    t_cw = np.eye(4)
    t_cw[:3, :3] = cv2.Rodrigues(rvec)[0]
    t_cw[:3, 3] = tvec.reshape(3)
    kp, pts = q[inl], pts[inl]
    t_cw, mask = optimize_pose(cam, t_cw, _observations(frame, slam_map, kp, pts))
    if int(mask.sum()) < 10:
        return None
    # more matches by projection around the found pose
    available = np.ones(len(frame), dtype=bool)
    available[kp[mask]] = False
    taken = np.isin(points, pts[mask])
    rest = points[~taken]
    mi, ki = search_by_projection(
        frame,
        cam,
        t_cw,
        slam_map.positions[rest],
        slam_map.descriptors[rest],
        radius=8.0,
        available=available,
    )
    kp_all = np.concatenate([kp[mask], ki])
    pts_all = np.concatenate([pts[mask], rest[mi]])
    obs = _observations(frame, slam_map, kp_all, pts_all)
    t_cw, mask = optimize_pose(cam, t_cw, obs)
    if int(mask.sum()) < min_inliers:
        return None
    cov = pose_covariance(cam, t_cw, obs, mask)
    return Localization(t_cw, kp_all[mask], pts_all[mask], cov)


@dataclass
class _Group:
    members: set[int]
    count: int


class LoopDetector:
    """Loop candidates for new keyframes (bag-of-words + covisibility rules).

    Args:
        exclude_recent: keyframes this close in index to the query are never candidates.
        max_candidates: at most this many candidates per query, best score first.
        consistency: a candidate region must be detected this many consecutive
            times before it is returned (1: at once).
        min_score: absolute lower bound on the similarity.
    """

    def __init__(
        self,
        *,
        exclude_recent: int = 20,
        max_candidates: int = 3,
        consistency: int = 1,
        min_score: float = 0.01,
    ) -> None:
        self.exclude_recent = int(exclude_recent)
        self.max_candidates = int(max_candidates)
        self.consistency = max(int(consistency), 1)
        self.min_score = float(min_score)
        self._groups: list[_Group] = []

    def reset(self) -> None:
        """Forget consistency history (after a loop was closed)."""
        self._groups = []

    def candidates(
        self, kf: Keyframe, slam_map: SlamMap, db: BowDatabase, vocabulary: Vocabulary
    ) -> list[int]:
        """Return candidate keyframe ids for ``kf`` (not yet geometrically verified)."""
        if kf.bow is None or len(db) == 0:
            return []
        neighbours = kf.best_covisibles(30, min_weight=1)
        scores_nb = [
            vocabulary.score(kf.bow, slam_map.keyframes[n].bow)  # type: ignore[arg-type]
            for n in neighbours
            if slam_map.keyframes[n].bow is not None
        ]
        floor = max(min(scores_nb) if scores_nb else 0.0, self.min_score)
        excluded = set(neighbours) | {kf.id}
        ids, scores = db.query(kf.bow)
        order = np.lexsort((ids, -scores))
        chosen: list[int] = []
        for i in order.tolist():
            k = int(ids[i])
            if k in excluded or k > kf.id - self.exclude_recent or slam_map.keyframes[k].bad:
                continue
            if float(scores[i]) < floor:
                break
            chosen.append(k)
            if len(chosen) >= self.max_candidates:
                break
        if self.consistency <= 1:
            return chosen
        groups: list[_Group] = []
        ready: list[int] = []
        for k in chosen:
            members = {k, *slam_map.keyframes[k].best_covisibles(10)}
            count = 1 + max((g.count for g in self._groups if g.members & members), default=0)
            groups.append(_Group(members, count))
            if count >= self.consistency:
                ready.append(k)
        self._groups = groups
        return ready
