"""Sensor observations for the obstacle layer (costmap_2d's ``Observation(Buffer)``).

An :class:`Observation` is a point cloud in the costmap's global frame plus the
sensor origin it was seen from. An :class:`ObservationBuffer` keeps the
observations of one source:

* points outside ``[min_obstacle_height, max_obstacle_height]`` (z in the global
  frame) are dropped when buffered;
* ``observation_persistence`` 0 keeps only the newest observation, otherwise those
  no older than that many seconds before the newest buffering time;
* ``expected_update_rate`` (seconds between messages; 0 = no check): the buffer is
  not current when nothing arrived for longer, and the reason says so.

LaserScan messages are projected as laser_geometry's ``projectLaser``: a beam
becomes a point when ``range_min <= r < range_max``; with ``inf_is_valid`` a +inf
reading becomes ``range_max - 1e-4`` first (so it clears but, with
``obstacle_range < range_max``, does not mark).

visnav additions: an empty message (a scan without ranges, a cloud of width x height
0) makes the buffer not current with the reason until a non-empty one arrives,
unless ``empty_is_error`` is false; a scan whose beams are all NaN or out of range is
not empty (a depth camera facing a wall closer than ``range_min`` sends exactly that)
and simply marks and clears nothing. The beam directions of a scan are computed once
per (angle_min, increment, count).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.errors import ObservationError
from visnav.msgs.pointcloud import cloud_to_xyz
from visnav.msgs.types import LaserScan, PointCloud2

__all__ = [
    "Observation",
    "ObservationBuffer",
    "ObservationSource",
    "ScanCache",
    "cloud_points",
    "scan_points",
]

_NS = 1_000_000_000


@dataclass(frozen=True)
class ObservationSource:
    """The parameters of one observation source (costmap_2d's per-source parameters).

    Defaults are costmap_2d's: ``marking`` true, ``clearing`` false.
    """

    name: str
    topic: str = ""
    data_type: str = "LaserScan"
    sensor_frame: str = ""
    observation_persistence: float = 0.0
    expected_update_rate: float = 0.0
    min_obstacle_height: float = 0.0
    max_obstacle_height: float = 2.0
    obstacle_range: float = 2.5
    raytrace_range: float = 3.0
    inf_is_valid: bool = False
    clearing: bool = False
    marking: bool = True
    empty_is_error: bool = True

    def __post_init__(self) -> None:
        if self.data_type not in ("LaserScan", "PointCloud2"):
            msg = (
                f"observation source {self.name!r}: data_type is {self.data_type!r}; expected "
                "'LaserScan' or 'PointCloud2'"
            )
            raise ObservationError(msg)
        for what in ("obstacle_range", "raytrace_range", "observation_persistence"):
            value = getattr(self, what)
            if not (math.isfinite(value) and value >= 0):
                msg = f"observation source {self.name!r}: {what} is {value}; expected >= 0"
                raise ObservationError(msg)
        if self.min_obstacle_height > self.max_obstacle_height:
            msg = (
                f"observation source {self.name!r}: min_obstacle_height "
                f"{self.min_obstacle_height} > max_obstacle_height {self.max_obstacle_height}"
            )
            raise ObservationError(msg)

    @property
    def resolved_topic(self) -> str:
        """``topic``, or the source name when empty (costmap_2d's default)."""
        return self.topic or self.name


@dataclass
class Observation:
    """Points (N, 3) seen from ``origin`` (3,), both in the costmap's global frame."""

    origin: NDArray[np.float64]
    points: NDArray[np.float64]
    obstacle_range: float
    raytrace_range: float
    stamp_ns: int = 0


@dataclass
class ScanCache:
    """Beam directions of the last scan geometry (one per source)."""

    key: tuple[float, float, int] = (0.0, 0.0, -1)
    cos: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    sin: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))


def scan_points(
    msg: LaserScan, *, inf_is_valid: bool = False, cache: ScanCache | None = None
) -> tuple[NDArray[np.float64], int]:
    """Project a scan into its own frame: ``(points (N, 3), number of beams)``.

    Args:
        msg: the scan.
        inf_is_valid: turn +inf readings into ``range_max - 1e-4`` first.
        cache: beam direction cache (one per source).
    """
    ranges = np.asarray(msg.ranges, dtype=np.float64)
    n = ranges.size
    c = cache if cache is not None else ScanCache()
    key = (float(msg.angle_min), float(msg.angle_increment), n)
    if c.key != key:
        angles = key[0] + np.arange(n) * key[1]
        c.key, c.cos, c.sin = key, np.cos(angles), np.sin(angles)
    if inf_is_valid:
        ranges = np.where(np.isposinf(ranges), float(msg.range_max) - 1e-4, ranges)
    with np.errstate(invalid="ignore"):
        valid = (ranges >= float(msg.range_min)) & (ranges < float(msg.range_max))
    r = ranges[valid]
    pts = np.zeros((r.size, 3))
    pts[:, 0] = r * c.cos[valid]
    pts[:, 1] = r * c.sin[valid]
    return pts, n


def cloud_points(msg: PointCloud2) -> NDArray[np.float64]:
    """The finite points of a cloud in its own frame, float64 (N, 3)."""
    return cloud_to_xyz(msg, skip_nans=True).astype(np.float64)


class ObservationBuffer:
    """The buffered observations of one source.

    Args:
        source: the source parameters.
    """

    def __init__(self, source: ObservationSource) -> None:
        self.source = source
        self.observations: list[Observation] = []
        self.last_updated_ns: int | None = None
        self.last_empty_text = ""
        self.scan_cache = ScanCache()
        self.received = 0

    def buffer_points(
        self,
        points_sensor: NDArray[np.float64],
        T_global_sensor: NDArray[np.float64],  # noqa: N803
        *,
        stamp_ns: int,
        now_ns: int,
        T_global_origin: NDArray[np.float64] | None = None,  # noqa: N803
        empty_text: str = "",
    ) -> None:
        """Add one message's points.

        Args:
            points_sensor: (N, 3) points in the message's frame.
            T_global_sensor: 4x4 transform from that frame into the global frame.
            stamp_ns: the message stamp.
            now_ns: the time of buffering (for persistence and the update rate check).
            T_global_origin: transform of ``sensor_frame`` when set (the ray origin);
                default: the message frame's origin.
            empty_text: non-empty when the message was empty (why).
        """
        src = self.source
        self.received += 1
        origin_tf = T_global_sensor if T_global_origin is None else T_global_origin
        pts = points_sensor @ T_global_sensor[:3, :3].T + T_global_sensor[:3, 3]
        keep = (pts[:, 2] <= src.max_obstacle_height) & (pts[:, 2] >= src.min_obstacle_height)
        obs = Observation(
            origin=origin_tf[:3, 3].copy(),
            points=pts[keep],
            obstacle_range=src.obstacle_range,
            raytrace_range=src.raytrace_range,
            stamp_ns=stamp_ns,
        )
        self.observations.insert(0, obs)
        self.last_updated_ns = now_ns
        self.last_empty_text = empty_text if src.empty_is_error else ""
        self.purge_stale()

    def purge_stale(self) -> None:
        """Drop observations older than the persistence window (keep only the newest at 0)."""
        if not self.observations:
            return
        keep_ns = round(self.source.observation_persistence * _NS)
        if keep_ns == 0:
            del self.observations[1:]
            return
        assert self.last_updated_ns is not None
        limit = self.last_updated_ns - keep_ns
        self.observations = [o for o in self.observations if o.stamp_ns >= limit]

    def get_observations(self) -> list[Observation]:
        """The kept observations, newest first."""
        self.purge_stale()
        return list(self.observations)

    def is_current(self, now_ns: int) -> tuple[bool, str]:
        """``(current, reason)``: stale when the expected update period passed, or empty."""
        src = self.source
        topic = src.resolved_topic
        if self.last_empty_text:
            return False, f"last message on '{topic}' was empty: {self.last_empty_text}"
        if src.expected_update_rate == 0:
            return True, ""
        if self.last_updated_ns is None:
            return False, (
                f"no message on '{topic}' yet (source {src.name!r} expects one every "
                f"{src.expected_update_rate:.2f} s)"
            )
        age = (now_ns - self.last_updated_ns) / _NS
        if age > src.expected_update_rate:
            return False, (
                f"the {src.name!r} observation buffer ('{topic}') has not been updated for "
                f"{age:.2f} s, and it should be updated every {src.expected_update_rate:.2f} s"
            )
        return True, ""

    def reset_last_updated(self, now_ns: int) -> None:
        """Treat the buffer as fresh from ``now_ns`` (after a reset)."""
        self.last_updated_ns = now_ns

    def clear(self) -> None:
        """Drop all observations."""
        self.observations.clear()
