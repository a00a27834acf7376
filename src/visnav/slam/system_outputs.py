"""The output side of :class:`~visnav.slam.SlamSystem`: poses, trajectory and clouds.

Frame poses are stored relative to their reference keyframe (:class:`FrameRecord`), so
loop closures and bundle adjustment move the whole trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from visnav.slam.clouds import voxel_average
from visnav.slam.geometry import inverse
from visnav.slam.loop_closing import LoopCloser
from visnav.slam.optimizer import LoopConstraint
from visnav.slam.slam_map import SlamMap
from visnav.slam.trajectory import Trajectory
from visnav.slam.vocabulary import Vocabulary

__all__ = ["FrameRecord", "SystemOutputs"]

FloatArray = NDArray[np.float64]


@dataclass
class FrameRecord:
    """A tracked frame: its stamp, reference keyframe and pose relative to it."""

    stamp_ns: int
    ref_kf: int
    t_c_ref: FloatArray


class SystemOutputs:
    """Read-only views of a system's map and tracked frames (a base of ``SlamSystem``)."""

    map: SlamMap
    loop_closer: LoopCloser
    _records: list[FrameRecord]

    @property
    def loops(self) -> list[LoopConstraint]:
        """Loop constraints closed so far."""
        return self.loop_closer.loops

    @property
    def vocabulary(self) -> Vocabulary | None:
        """The bag-of-words vocabulary (None until trained)."""
        return self.loop_closer.vocabulary

    @property
    def localized(self) -> bool:
        """Whether any frame has a pose yet (in localisation mode: found in the saved map)."""
        return bool(self._records)

    def trajectory(self) -> Trajectory:
        """Camera poses of all tracked frames in the map frame (loop corrections applied)."""
        if not self._records:
            return Trajectory.empty()
        stamps = np.array([r.stamp_ns for r in self._records], dtype=np.float64) * 1e-9
        mats = np.stack(
            [inverse(r.t_c_ref @ self.map.keyframes[r.ref_kf].t_cw) for r in self._records]
        )
        return Trajectory.from_matrices(stamps, mats)

    def keyframe_trajectory(self) -> Trajectory:
        """Keyframe camera poses in the map frame."""
        kfs = [kf for kf in self.map.keyframes if not kf.bad]
        stamps = np.array([kf.stamp_ns for kf in kfs], dtype=np.float64) * 1e-9
        if not kfs:
            return Trajectory.empty()
        return Trajectory.from_matrices(stamps, np.stack([kf.t_wc for kf in kfs]))

    def map_cloud(self, *, min_observations: int = 2) -> NDArray[np.float32]:
        """Sparse map: (N, 3) float32 positions of points seen by enough keyframes."""
        return self.map.point_cloud(min_observations=min_observations).astype(np.float32)

    def dense_cloud(
        self, voxel_size: float = 0.05
    ) -> tuple[NDArray[np.float32], NDArray[np.uint8]]:
        """Dense coloured cloud from the keyframes' depth, voxel-averaged.

        Args:
            voxel_size: voxel side in metres (one averaged point per occupied voxel).

        Returns:
            ``(points (N, 3) float32, rgb (N, 3) uint8)`` in the map frame.
        """
        return voxel_average(self.map.keyframes, voxel_size)
