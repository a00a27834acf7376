"""The observer's bookkeeping, without a graph: contact events, goals, poses, errors.

Plain classes and functions with numbers in and out, so each metric is testable alone;
:mod:`visnav.scenarios.observer` feeds them from topics. The SLAM scores
(:func:`slam_metrics`) pair the estimate with the ground truth interpolated at its stamps
(:func:`interpolate_poses`): linear position, slerp rotation, so ``ground_truth.tum`` has
the SLAM stamps and ``visnav eval ate -a slam_trajectory.tum ground_truth.tum``
reproduces ``ate_rmse_m`` (``evo_ape -a``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from visnav.tf.transforms import yaw_from_matrix

if TYPE_CHECKING:
    from visnav.slam.trajectory import Trajectory

__all__ = [
    "ENDED_STATUSES",
    "SUCCEEDED_STATUS",
    "ContactEvents",
    "GoalRecord",
    "PoseErrors",
    "interpolate_poses",
    "path_length",
    "pose_error",
    "slam_metrics",
]

FloatArray = NDArray[np.float64]

ENDED_STATUSES = frozenset({2, 3, 4, 5})
"""``actionlib_msgs/GoalStatus`` codes of a goal that ended: PREEMPTED, SUCCEEDED, ABORTED,
REJECTED (the end states move_base publishes; actionlib's RECALLED and LOST never occur)."""
SUCCEEDED_STATUS = 3
"""``actionlib_msgs/GoalStatus.SUCCEEDED``."""


class ContactEvents:
    """Counts contact events from contact samples taken at a fixed rate.

    A new event starts when the robot touches something after a sample without contact
    and more than ``gap_s`` after the last touching sample; a run of touching samples is
    one event.

    Args:
        gap_s: contacts closer together than this are one event.
    """

    def __init__(self, gap_s: float = 0.0) -> None:
        self._gap_s = gap_s
        self._touching = False
        self._last_touch = -math.inf
        self.events = 0

    def sample(self, now_s: float, *, touching: bool) -> None:
        """Take the sample of sim time ``now_s``."""
        if touching and not self._touching and now_s - self._last_touch > self._gap_s:
            self.events += 1
        if touching:
            self._last_touch = now_s
        self._touching = touching


@dataclass
class GoalRecord:
    """One goal sent to the robot and how it ended.

    Attributes:
        x: goal x (m).
        y: goal y (m).
        start_index: index of the first ground-truth sample of the drive to it.
        ended: whether the navigator reported an end.
        succeeded: the navigator reported SUCCEEDED.
        duration_s: accepted -> ended, from the status stamps.
        travelled_m: ground-truth path length of the drive.
        shortest_m: shortest collision-free path from the drive's start (NaN: none).
        reached: succeeded and within the tolerance of the goal at the end.
    """

    x: float
    y: float
    start_index: int
    ended: bool = False
    succeeded: bool = False
    duration_s: float = 0.0
    travelled_m: float = 0.0
    shortest_m: float = math.nan
    reached: bool = False


def path_length(points: FloatArray) -> float:
    """Length of a polyline of ``(N, D)`` points (0 with fewer than two)."""
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def pose_error(estimate: FloatArray, truth: FloatArray) -> tuple[float, float]:
    """``(position error m, heading error rad)`` of a 4x4 pose against the truth."""
    dist = float(np.linalg.norm(estimate[:3, 3] - truth[:3, 3]))
    heading = math.remainder(yaw_from_matrix(estimate) - yaw_from_matrix(truth), 2 * math.pi)
    return dist, heading


class PoseErrors:
    """Position and heading errors of an estimate sampled against ground truth."""

    def __init__(self) -> None:
        self.position: list[float] = []
        self.heading: list[float] = []

    def add(self, estimate: FloatArray, truth: FloatArray) -> None:
        """Add one sample (4x4 poses in the same frame)."""
        dist, heading = pose_error(estimate, truth)
        self.position.append(dist)
        self.heading.append(heading)

    def summary(self, source: str) -> dict[str, Any]:
        """``{source, samples, rmse_m, max_m, heading_rmse_deg}`` (None without samples)."""
        if not self.position:
            return {
                "source": source,
                "samples": 0,
                "rmse_m": None,
                "max_m": None,
                "heading_rmse_deg": None,
            }
        pos = np.asarray(self.position)
        head = np.asarray(self.heading)
        return {
            "source": source,
            "samples": len(pos),
            "rmse_m": round(float(np.sqrt(np.mean(pos**2))), 4),
            "max_m": round(float(pos.max()), 4),
            "heading_rmse_deg": round(math.degrees(float(np.sqrt(np.mean(head**2)))), 3),
        }


def interpolate_poses(
    stamps_ns: NDArray[np.int64], matrices: FloatArray, at_ns: NDArray[np.int64]
) -> tuple[NDArray[np.int64], FloatArray]:
    """Poses at ``at_ns`` by linear / slerp interpolation of stamped poses.

    Args:
        stamps_ns: (N,) increasing stamps of the known poses.
        matrices: (N, 4, 4) poses.
        at_ns: (M,) stamps wanted.

    Returns:
        ``(indices, poses)``: the indices into ``at_ns`` inside the known span and their
        (K, 4, 4) interpolated poses.
    """
    from scipy.spatial.transform import Rotation, Slerp  # noqa: PLC0415 - heavy, at the end

    at = np.asarray(at_ns, dtype=np.int64)
    known = np.asarray(stamps_ns, dtype=np.int64)
    if len(known) < 2:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 4, 4))
    inside = np.flatnonzero((at >= known[0]) & (at <= known[-1]))
    if len(inside) == 0:
        return inside.astype(np.int64), np.zeros((0, 4, 4))
    t = (at[inside] - known[0]).astype(np.float64) * 1e-9
    tk = (known - known[0]).astype(np.float64) * 1e-9
    mats = np.asarray(matrices, dtype=np.float64)
    out = np.tile(np.eye(4), (len(inside), 1, 1))
    out[:, :3, :3] = Slerp(tk, Rotation.from_matrix(mats[:, :3, :3]))(t).as_matrix()
    for axis in range(3):
        out[:, axis, 3] = np.interp(t, tk, mats[:, axis, 3])
    return inside.astype(np.int64), out


def slam_metrics(estimate: Trajectory, reference: Trajectory) -> dict[str, float | None]:
    """ATE (aligned and not) and RPE (consecutive poses) of paired trajectories.

    Args:
        estimate: SLAM poses.
        reference: ground truth with the same stamps.

    Returns:
        ``ate_rmse_m`` (Umeyama SE(3)-aligned, ``evo_ape -a``), ``ate_unaligned_rmse_m``,
        ``rpe_trans_rmse_m``, ``rpe_rot_rmse_deg`` (None when there are too few poses).
    """
    from visnav.slam.errors import SlamError  # noqa: PLC0415 - heavy, at the end
    from visnav.slam.evaluation import ate, rpe  # noqa: PLC0415

    out: dict[str, float | None] = dict.fromkeys(
        ("ate_rmse_m", "ate_unaligned_rmse_m", "rpe_trans_rmse_m", "rpe_rot_rmse_deg")
    )
    if len(estimate) < 3 or len(reference) < 3:
        return out
    try:
        out["ate_rmse_m"] = round(ate(estimate, reference, align=True).rmse, 5)
    except SlamError:  # degenerate (the car did not move): aligned ATE is undefined
        out["ate_rmse_m"] = None
    out["ate_unaligned_rmse_m"] = round(ate(estimate, reference).rmse, 5)
    out["rpe_trans_rmse_m"] = round(rpe(estimate, reference).rmse, 5)
    out["rpe_rot_rmse_deg"] = round(rpe(estimate, reference, pose_relation="angle_deg").rmse, 4)
    return out
