"""When tracking makes a new keyframe (ORB-SLAM2's RGB-D rule, with visnav's motion rule)."""

from __future__ import annotations

import numpy as np

from visnav.slam.config import SlamConfig
from visnav.slam.features import Frame
from visnav.slam.geometry import rotation_angle
from visnav.slam.slam_map import SlamMap

__all__ = ["need_keyframe"]


def need_keyframe(
    config: SlamConfig, slam_map: SlamMap, frame: Frame, inliers: int, ref_kf: int, since: int
) -> bool:
    """Whether the tracked ``frame`` becomes a keyframe.

    Yes when ``kf_max_frames`` frames passed, when the camera moved ``kf_translation`` m or
    turned ``kf_rotation_deg`` since the newest keyframe, when close tracked points run low
    while close untracked ones abound (ORB-SLAM2's RGB-D rule), or when the inliers fall
    below ``kf_ratio`` of the points the reference keyframe sees from enough views; never
    before ``kf_min_frames`` frames.

    Args:
        config: the SLAM parameters.
        slam_map: the map.
        frame: the tracked frame (its ``t_cw`` set).
        inliers: its inlier matches.
        ref_kf: the reference keyframe's id.
        since: frames since the newest keyframe.
    """
    if since < config.kf_min_frames:
        return False
    if frame.t_cw is None:
        return False
    last_kf = slam_map.keyframes[-1]
    rel = frame.t_cw @ last_kf.t_wc
    moved = (
        float(np.linalg.norm(rel[:3, 3])) > config.kf_translation
        or np.degrees(rotation_angle(rel)) > config.kf_rotation_deg
    )
    _, ref_pts = slam_map.keyframe_points(slam_map.keyframes[ref_kf])
    min_obs = 2 if len(slam_map.keyframes) <= 2 else 3
    n_ref = sum(1 for p in ref_pts.tolist() if len(slam_map.observations[p]) >= min_obs)
    close = np.isfinite(frame.depth) & (frame.depth < config.close_depth)
    tracked_close = int((close & (frame.map_points >= 0)).sum())
    untracked_close = int((close & (frame.map_points < 0)).sum())
    need_close = tracked_close < 100 and untracked_close > 70
    weak = inliers < config.kf_ratio * n_ref
    return since >= config.kf_max_frames or moved or need_close or weak
