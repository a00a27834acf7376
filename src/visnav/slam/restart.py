"""Tracking loss and restart: follow the depth while lost, hold the restart keyframe.

When the features lose the map (a turn towards a texture that does not repeat
from frame to frame, a wall closer than the depth range), :class:`SlamSystem`
restarts tracking after ``reinit_after_lost`` frames at the pose the odometry
predicts. Two things made that restart cost the car 20 cm:

- Wheel odometry slips in turns on the spot (3 degrees in the 0.2 s of seed 4's
  loss), so the restart pose was off. While lost, :func:`follow_depth` corrects
  the odometry's prediction by point-to-plane ICP of the frame's depth against
  the last keyframe's (:mod:`visnav.slam.dense`, no feature prior): the restart
  pose came within 0.5 degrees.
- The restart keyframe starts a new part of the map that shares almost no points
  with the old one (the features that were lost do not match). In local bundle
  adjustment such a part has nearly free gauge: a handful of links to the old
  map, some of them wrong, moved it by 20 cm in one adjustment. ORB-SLAM3 holds
  the first keyframe of each new map in local bundle adjustment; so does
  :class:`RestartAnchor`, until a keyframe of the new part shares
  ``min_links`` points with the map from before the restart (then it is one map
  again and nothing is held).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from visnav.slam.dense import DenseTracker
from visnav.slam.geometry import inverse, orthonormalize
from visnav.slam.slam_map import Keyframe, SlamMap

__all__ = ["FOLLOW_SIGMA_T", "RestartAnchor", "follow_depth", "predict_from_odometry"]

FloatArray = NDArray[np.float64]

FOLLOW_SIGMA_T = 0.01
"""Standard deviation (m, each axis) of the odometry's camera position over one lost frame.

:func:`follow_depth` holds the predicted camera centre with it and leaves the rotation
to the depth: the wheels slip in heading, hardly in distance, and a depth image seen
mostly far away (one wall, a corridor) cannot tell a small turn from a sideways shift.
"""


def predict_from_odometry(
    odom_pose: FloatArray | None, odom_world: FloatArray | None
) -> FloatArray | None:
    """The predicted ``T_cw`` from the odometry's motion since the last tracked frame.

    Args:
        odom_pose: ``T_odom_camera`` of this frame (None: no odometry).
        odom_world: ``T_odom_world`` at the last tracked frame (``T_odom_camera @ T_cw``).
    """
    if odom_pose is None or odom_world is None:
        return None
    return orthonormalize(inverse(np.asarray(odom_pose, dtype=np.float64)) @ odom_world)


def follow_depth(
    dense: DenseTracker | None,
    slam_map: SlamMap,
    ref_kf: int,
    depth_m: NDArray[np.float32],
    t_cw_pred: FloatArray | None,
    odom_pose: FloatArray | None,
) -> tuple[FloatArray, FloatArray] | None:
    """While lost: the predicted pose corrected by ICP against a keyframe's depth.

    Args:
        dense: the dense tracker (None: ICP is off, nothing to do).
        slam_map: the map.
        ref_kf: the reference keyframe (its depth model is used when kept, else the
            newest keyframe's).
        depth_m: this frame's depth (metres).
        t_cw_pred: the odometry's predicted ``T_cw``.
        odom_pose: ``T_odom_camera`` of this frame.

    Returns:
        ``(T_cw, T_odom_world)``, the corrected pose and the odometry anchor that
        predicts the next frame from it, or None when the ICP refused (too few
        correspondences, or a correction beyond its limits).
    """
    if dense is None or t_cw_pred is None or odom_pose is None or not slam_map.keyframes:
        return None
    ref = ref_kf if dense.has(ref_kf) else slam_map.keyframes[-1].id
    hold_centre = np.diag([1.0 / FOLLOW_SIGMA_T**2] * 3 + [0.0] * 3)  # rotation left free
    res = dense.refine(ref, slam_map.keyframes[ref].t_cw, depth_m, t_cw_pred, hold_centre)
    if not res.ok:
        return None
    return res.t_cw, np.asarray(odom_pose, dtype=np.float64) @ res.t_cw


class RestartAnchor:
    """Keyframes that restarted tracking, held in local bundle adjustment for a while.

    Args:
        min_links: a new keyframe with this many points first seen before the
            (oldest held) restart keyframe joins the parts: nothing is held after it.
    """

    def __init__(self, min_links: int = 50) -> None:
        self.min_links = int(min_links)
        self.held: set[int] = set()

    def hold(self, kf_id: int) -> None:
        """Hold restart keyframe ``kf_id``."""
        self.held.add(int(kf_id))

    def window(self, slam_map: SlamMap, kf: Keyframe, window: list[int]) -> list[int]:
        """The local bundle adjustment window of new keyframe ``kf`` without held ones."""
        if not self.held:
            return window
        first = min(self.held)
        _, pts = slam_map.keyframe_points(kf)
        obs = slam_map.observations
        links = sum(1 for p in pts.tolist() if obs[p] and min(obs[p]) < first)
        if links >= self.min_links:
            self.held.clear()
            return window
        return [k for k in window if k not in self.held]
