"""The observer's bookkeeping, without a graph: contact events, goals, poses, errors.

Plain classes and functions with numbers in and out, so each metric is testable alone;
:mod:`visnav.scenarios.observer` feeds them from topics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ContactEvents",
    "GoalRecord",
    "PoseErrors",
    "path_length",
    "pose_error",
    "yaw_of_matrix",
]

FloatArray = NDArray[np.float64]


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


def yaw_of_matrix(matrix: FloatArray) -> float:
    """Yaw (rad) of a 4x4 (or 3x3) rotation, about z."""
    return math.atan2(float(matrix[1, 0]), float(matrix[0, 0]))


def pose_error(estimate: FloatArray, truth: FloatArray) -> tuple[float, float]:
    """``(position error m, heading error rad)`` of a 4x4 pose against the truth."""
    dist = float(np.linalg.norm(estimate[:3, 3] - truth[:3, 3]))
    heading = math.remainder(yaw_of_matrix(estimate) - yaw_of_matrix(truth), 2 * math.pi)
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
