"""Localisation in a saved SLAM map (rtabmap's localization mode, ORB-SLAM's "only tracking").

:class:`SavedMapAnchor` holds what :class:`~visnav.slam.system.SlamSystem` needs to track
in a map written by an earlier run (:func:`~visnav.slam.map_file.load_slam_map`):

* the saved keyframes are held: bundle adjustment never moves them (a new keyframe's
  window leaves them out, and :func:`~visnav.slam.optimizer.bundle_adjustment` holds
  every keyframe outside the window that observes a point in it), and loop closing is
  off, so the saved map's frame stays the frame the run is localised in;
* :meth:`SavedMapAnchor.nearby` gives the saved keyframes near a pose, which join the
  local map each frame, so tracking snaps back to the saved points whenever they are in
  view (after a stretch the saved map does not cover, or a relocalisation);
* the saved keyframes' odometry poses are dropped: they belong to the earlier run's
  odometry, and an odometry factor between one of them and a new keyframe would tie two
  unrelated odometry frames together.

Where visnav differs: ORB-SLAM's localization mode inserts no keyframe (outside the map
it tracks on visual-odometry points of the last frame only) and rtabmap's adds none to
its memory. visnav inserts keyframes as in mapping, but only they move in bundle
adjustment: where the saved map has no points (the car's route differs from the mapping
run's by a metre here and there), the new keyframes carry the tracking as mapping does,
and they are dropped with the run (nothing is written back to the saved map).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.errors import SlamInputError
from visnav.slam.map_file import SavedSlamMap
from visnav.slam.slam_map import SlamMap

__all__ = ["NEARBY_KEYFRAMES", "NEARBY_RADIUS_M", "SavedMapAnchor", "check_map_camera"]

FloatArray = NDArray[np.float64]

NEARBY_RADIUS_M = 4.0
"""Saved keyframes farther than this from the camera never join its local map."""
NEARBY_KEYFRAMES = 6
"""At most this many saved keyframes join the local map each frame."""
_NEARBY_MAX_ANGLE_DEG = 60.0
"""...and only those looking within this angle of the camera's direction."""


def check_map_camera(saved: CameraIntrinsics, live: CameraIntrinsics, path: str) -> None:
    """Refuse a saved map built with another camera (its points project elsewhere).

    Raises:
        SlamInputError: the intrinsics or image size differ by more than 0.1 %.
    """
    pairs = {
        "fx": (saved.fx, live.fx),
        "fy": (saved.fy, live.fy),
        "cx": (saved.cx, live.cx),
        "cy": (saved.cy, live.cy),
        "width": (saved.width, live.width),
        "height": (saved.height, live.height),
    }
    for name, (a, b) in pairs.items():
        if not math.isclose(float(a), float(b), rel_tol=1e-3, abs_tol=1e-6):
            text = (
                f"{path}: the saved SLAM map's camera has {name}={a:g}, this camera_info "
                f"{name}={b:g}; localise with the camera (and resolution) the map was built "
                "with, or map again"
            )
            raise SlamInputError(text)


class SavedMapAnchor:
    """The saved part of a map being localised in.

    Args:
        saved: the loaded map (its keyframes become ids ``0 .. n_saved - 1``).
    """

    def __init__(self, saved: SavedSlamMap) -> None:
        self.map: SlamMap = saved.map
        self.n_saved = len(saved.map.keyframes)
        for kf in self.map.keyframes:
            kf.odom_pose = None  # the earlier run's odometry frame
        good = [kf for kf in self.map.keyframes if not kf.bad]
        self._ids = np.array([kf.id for kf in good], dtype=np.int64)
        poses = [kf.t_wc for kf in good]
        self._centres = np.array([p[:3, 3] for p in poses]).reshape(-1, 3)
        self._axes = np.array([p[:3, 2] for p in poses]).reshape(-1, 3)

    def new_only(self, kf_ids: list[int]) -> list[int]:
        """``kf_ids`` without the saved keyframes."""
        return [k for k in kf_ids if k >= self.n_saved]

    def nearby(self, t_wc: FloatArray, count: int = NEARBY_KEYFRAMES) -> list[int]:
        """The saved keyframes nearest the camera pose ``t_wc`` that look its way.

        Within :data:`NEARBY_RADIUS_M` and :data:`_NEARBY_MAX_ANGLE_DEG` of its optical
        axis, nearest first (ties by id, so the choice is deterministic).
        """
        if not len(self._ids):
            return []
        d = np.linalg.norm(self._centres - t_wc[:3, 3], axis=1)
        cos = self._axes @ t_wc[:3, 2]
        ok = (d <= NEARBY_RADIUS_M) & (cos >= math.cos(math.radians(_NEARBY_MAX_ANGLE_DEG)))
        idx = np.flatnonzero(ok)
        order = idx[np.lexsort((self._ids[idx], d[idx]))][:count]
        return [int(k) for k in self._ids[order]]
