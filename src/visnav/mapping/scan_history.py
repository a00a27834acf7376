"""The scans a mapper integrated, kept so the grid can be rebuilt on corrected poses.

A SLAM system corrects its past poses after a loop closure; a grid that integrated each
scan at the pose of its moment keeps the old errors (a wall seen before and after a
loop appears twice). RTAB-Map therefore assembles its grid from the scans attached to
its graph's nodes at their optimised poses. :class:`ScanHistory` is that store for a
scan mapper: each kept scan with its sensor pose in the odometry frame (continuous, never
corrected) and in the base frame. :meth:`ScanHistory.poses_from_path`
re-derives every kept scan's map pose from the SLAM trajectory (a ``nav_msgs/Path`` of
the base frame in the map):

* a scan whose stamp is in the path gets ``path(t) @ T_base_sensor``, levelled to the
  plane (x, y, yaw: the grid is 2D, SLAM's z / tilt errors stay out as they stay out
  of ``map -> odom`` with ``force_3dof``);
* another scan (tracking lost, or newer than the path) gets the correction
  ``T_map_odom`` of the nearest kept scan that is in the path, applied to its own
  odometry pose.

Scans are kept as gmapping processes them: one whenever the sensor moved
``linear_update`` metres or turned ``angular_update`` radians since the last kept scan, or
``temporal_update`` seconds passed (0 and 0: every scan). Without the time rule a robot
standing still integrates one scan, and a log-odds cell needs several misses to be free.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.errors import MappingError
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import LaserScan, Path
from visnav.tf.transforms import yaw_from_matrix

__all__ = ["PathProbe", "ScanHistory", "pose_displacement"]

FloatArray = NDArray[np.float64]


def pose_displacement(a: FloatArray, b: FloatArray, reach: float) -> FloatArray:
    """How far, in the plane, a point ``reach`` m ahead of each pose moves from ``a`` to ``b``.

    Args:
        a: ``(N, 4, 4)`` poses.
        b: ``(N, 4, 4)`` poses.
        reach: the range at which the heading difference is counted (m).

    Returns:
        ``(N,)`` x-y translation difference plus ``reach`` times the yaw difference.
    """
    dxy = np.linalg.norm(a[:, :2, 3] - b[:, :2, 3], axis=1)
    yaw_a = np.arctan2(a[:, 1, 0], a[:, 0, 0])
    yaw_b = np.arctan2(b[:, 1, 0], b[:, 0, 0])
    dyaw = np.abs(np.remainder(yaw_a - yaw_b + np.pi, 2 * np.pi) - np.pi)
    return np.asarray(dxy + reach * dyaw, dtype=np.float64)


def _path_matrices(path: Path) -> tuple[NDArray[np.int64], FloatArray]:
    """Stamps (ns) and levelled 4x4 poses of a ``nav_msgs/Path``."""
    n = len(path.poses)
    stamps = np.empty(n, np.int64)
    poses = np.tile(np.eye(4), (n, 1, 1))
    for i, ps in enumerate(path.poses):
        stamps[i] = time_to_ns(ps.header.stamp)
        p, q = ps.pose.position, ps.pose.orientation
        yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
        c, s = math.cos(yaw), math.sin(yaw)
        poses[i, :2, :2] = [[c, -s], [s, c]]
        poses[i, 0, 3], poses[i, 1, 3] = p.x, p.y
    return stamps, poses


_PROBES = 32  # poses of a path compared to tell an appended path from a corrected one


@dataclass(frozen=True)
class PathProbe:
    """A few poses of a path (index, stamp, x, y, z, qz, qw), to see whether its past changed.

    A SLAM node republishes its whole trajectory every second; between loop closures only
    new poses are appended. Comparing :data:`_PROBES` evenly spaced poses of the earlier
    path with the same indices of the new one tells the two cases apart without decoding
    thousands of poses per second.
    """

    rows: tuple[tuple[int, int, float, float, float, float, float], ...] = ()

    @staticmethod
    def of(path: Path) -> PathProbe:
        """The probe of ``path``."""
        n = len(path.poses)
        step = max(1, n // _PROBES)
        rows = []
        for i in range(0, n, step):
            ps = path.poses[i]
            p, q = ps.pose.position, ps.pose.orientation
            rows.append((i, time_to_ns(ps.header.stamp), p.x, p.y, p.z, q.z, q.w))
        return PathProbe(tuple(rows))

    def same_past(self, path: Path) -> bool:
        """Whether ``path`` holds the probed poses unchanged (it only grew)."""
        if not self.rows or len(path.poses) < self.rows[-1][0] + 1:
            return False
        for i, stamp, x, y, z, qz, qw in self.rows:
            ps = path.poses[i]
            p, q = ps.pose.position, ps.pose.orientation
            if (time_to_ns(ps.header.stamp), p.x, p.y, p.z, q.z, q.w) != (stamp, x, y, z, qz, qw):
                return False
        return True


@dataclass
class ScanHistory:
    """Kept scans and their sensor poses in the odometry and base frames.

    Args:
        linear_update: keep a scan after this much sensor travel (m; 0: not by travel).
        angular_update: ... or this much sensor rotation (rad; 0: not by rotation); both
            0: every scan.
        keep: store the scans (else only the last pose, for :meth:`wants`).
        temporal_update: ... or when this many seconds passed since the last kept scan
            (gmapping's ``temporalUpdate``; <= 0: not by time).
    """

    linear_update: float = 0.0
    angular_update: float = 0.0
    keep: bool = True
    temporal_update: float = 0.0
    scans: list[LaserScan] = field(default_factory=list)
    stamps: list[int] = field(default_factory=list)
    t_odom_sensor: list[FloatArray] = field(default_factory=list)
    t_base_sensor: list[FloatArray] = field(default_factory=list)
    last: FloatArray | None = None
    last_ns: int = 0

    def __len__(self) -> int:
        return len(self.scans)

    def wants(self, t_odom_sensor: FloatArray, stamp_ns: int = 0) -> bool:
        """Whether a scan at this odometry-frame sensor pose (and stamp) is to be kept."""
        last = self.last
        if last is None or (self.linear_update <= 0 and self.angular_update <= 0):
            return True
        if self.temporal_update > 0 and stamp_ns - self.last_ns >= self.temporal_update * 1e9:
            return True
        moved = float(np.linalg.norm(t_odom_sensor[:2, 3] - last[:2, 3]))
        rel = last[:3, :3].T @ t_odom_sensor[:3, :3]
        turned = abs(yaw_from_matrix(rel))
        return (0 < self.linear_update <= moved) or (0 < self.angular_update <= turned)

    def add(
        self,
        scan: LaserScan,
        t_odom_sensor: FloatArray,
        t_base_sensor: FloatArray | None,
    ) -> None:
        """Keep ``scan`` (or only its pose, for :meth:`wants`, without ``keep``).

        Raises:
            MappingError: ``keep`` without the scan's base-frame pose.
        """
        self.last = np.array(t_odom_sensor, dtype=np.float64)
        self.last_ns = time_to_ns(scan.header.stamp)
        if not self.keep:
            return
        if t_base_sensor is None:
            msg = "scan history: a kept scan needs its pose in the base frame"
            raise MappingError(msg)
        self.scans.append(scan)
        self.stamps.append(self.last_ns)
        self.t_odom_sensor.append(np.array(t_odom_sensor, dtype=np.float64))
        self.t_base_sensor.append(np.array(t_base_sensor, dtype=np.float64))

    def poses_from_path(self, path: Path) -> FloatArray | None:
        """Every kept scan's map pose from the SLAM trajectory ``path`` (module docstring).

        Returns:
            ``(N, 4, 4)`` poses, or None when no kept scan's stamp is in the path.
        """
        if not self.scans or not path.poses:
            return None
        p_stamps, p_poses = _path_matrices(path)
        order = np.argsort(p_stamps, kind="stable")
        p_stamps, p_poses = p_stamps[order], p_poses[order]
        stamps = np.asarray(self.stamps, np.int64)
        idx = np.clip(np.searchsorted(p_stamps, stamps), 0, len(p_stamps) - 1)
        found = p_stamps[idx] == stamps
        if not found.any():
            return None
        odom = np.stack(self.t_odom_sensor)
        base = np.stack(self.t_base_sensor)
        out = np.empty_like(odom)
        anchors = np.flatnonzero(found)
        out[anchors] = p_poses[idx[anchors]] @ base[anchors]
        missing = np.flatnonzero(~found)
        if len(missing):
            a_stamps = stamps[anchors]
            k = np.clip(np.searchsorted(a_stamps, stamps[missing]), 1, len(anchors) - 1)
            if len(anchors) == 1:
                k = np.zeros_like(k)
            else:
                earlier = np.abs(stamps[missing] - a_stamps[k - 1]) <= np.abs(
                    a_stamps[k] - stamps[missing]
                )
                k = np.where(earlier, k - 1, k)
            j = anchors[k]
            correction = out[j] @ np.linalg.inv(odom[j])
            out[missing] = correction @ odom[missing]
        return out
