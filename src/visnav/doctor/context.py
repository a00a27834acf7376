"""What every check gets: the observation plus derived facts (TF buffer, clock, declarations).

:class:`CheckContext` computes derived data once and lazily: the TF buffer filled with
every valid transform received, the clock model, the declarations of ``--expect`` and
``robot_description``, the frame conventions (optical or body) and the graph queries
the checks share.
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from visnav.doctor.declared import Declared, declared_from
from visnav.doctor.expect import Expectations, TopicExpectation
from visnav.doctor.observation import ClockModel, Observation, TopicData
from visnav.graph.graph_cache import EndpointInfo
from visnav.msgs.types import Header, Quaternion, Time, Transform, TransformStamped, Vector3
from visnav.tf.buffer import Buffer
from visnav.tf.errors import TransformException

__all__ = ["SENSOR_TYPES", "CheckContext", "FrameKind"]

FrameKind = Literal["optical", "body"]

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
CLOUD = "sensor_msgs/msg/PointCloud2"
SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
SENSOR_TYPES = (IMAGE, CAMERA_INFO, CLOUD, SCAN, "sensor_msgs/msg/CompressedImage")
"""Types whose frame_id names a sensor frame that consumers look up in TF."""

_QUAT_TOL = 0.01  # tf2 refuses |q|^2 - 1 >= this
_CACHE_S = 1.0e6  # keep every transform of the observation


def _valid_quaternion(q: tuple[float, float, float, float]) -> bool:
    n2 = sum(v * v for v in q)
    return math.isfinite(n2) and abs(n2 - 1.0) < _QUAT_TOL


def _time(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class CheckContext:
    """The observation and everything derived from it.

    Args:
        observation: what was observed.
        expect: ``--expect`` declarations.
        fixed_frame: the frame consumers transform data into (``--fixed-frame``; default
            the expect file's ``fixed_frame``).
    """

    def __init__(
        self,
        observation: Observation,
        *,
        expect: Expectations | None = None,
        fixed_frame: str | None = None,
    ) -> None:
        self.obs = observation
        self.expect = expect
        self.fixed_frame = fixed_frame or (expect.fixed_frame if expect else None)
        self.clock: ClockModel = observation.clock_model()

    # ------------------------------------------------------------------ declarations
    @cached_property
    def declared(self) -> Declared:
        """``--expect`` merged with ``robot_description``."""
        return declared_from(
            self.obs.robot_description, self.obs.robot_description_topic, self.expect
        )

    def expected(self, topic: str) -> TopicExpectation | None:
        """The ``--expect`` entry of ``topic``."""
        return self.expect.topics.get(topic) if self.expect else None

    # ------------------------------------------------------------------ graph
    @property
    def has_graph(self) -> bool:
        """True for a live observation (endpoints known)."""
        return self.obs.graph is not None

    def endpoints(self, topic: str | None = None, kind: str | None = None) -> list[EndpointInfo]:
        """Endpoints of the graph (none for a bag)."""
        graph = self.obs.graph
        if graph is None:
            return []
        return [
            e
            for e in graph.endpoints
            if (topic is None or e.topic == topic) and (kind is None or e.kind == kind)
        ]

    def all_topic_names(self) -> set[str]:
        """Topics with messages, declared in a bag, or with an endpoint in the graph."""
        names = set(self.obs.topics)
        if self.obs.graph is not None:
            names |= self.obs.graph.topics()
        return names

    def topics_of_type(self, *type_names: str) -> list[TopicData]:
        """Topics (with at least one message) of the given types, sorted by name."""
        return [t for t in self.obs.topics.values() if t.type_name in type_names and t.count > 0]

    # ------------------------------------------------------------------ time
    def reference_ns(self, topic: TopicData) -> NDArray[np.int64]:
        """ROS time (``/clock`` when published) at each message's arrival."""
        return self.clock.at(topic.receive_ns)

    @property
    def end_clock_ns(self) -> int:
        """ROS time at the end of the observation."""
        return int(self.clock.at(self.obs.end_ns)[0])

    @property
    def uses_sim_clock(self) -> bool:
        """True when ``/clock`` was published."""
        return self.clock.has_clock

    # ------------------------------------------------------------------ TF
    @cached_property
    def buffer(self) -> Buffer:
        """A TF buffer holding every valid transform received (static and dynamic)."""
        buf = Buffer(cache_time=_CACHE_S)
        for r in self.obs.tf:
            if not _valid_quaternion(r.rotation) or r.stamp_ns < 0 or not r.parent or not r.child:
                continue
            if r.parent.lstrip("/") == r.child.lstrip("/"):
                continue
            msg = TransformStamped(
                Header(_time(r.stamp_ns), r.parent),
                r.child,
                Transform(Vector3(*r.translation), Quaternion(*r.rotation)),
            )
            try:
                if r.is_static:
                    buf.set_transform_static(msg, r.authority or "unknown", strict=True)
                else:
                    buf.set_transform(msg, r.authority or "unknown", strict=True)
            except TransformException:
                continue
        return buf

    @cached_property
    def tf_frames(self) -> set[str]:
        """Every frame seen in TF, as child or parent."""
        frames: set[str] = set()
        for r in self.obs.tf:
            frames.add(r.parent.lstrip("/"))
            frames.add(r.child.lstrip("/"))
        frames.discard("")
        return frames

    def tf_root(self, frame: str) -> str:
        """The root of ``frame``'s tree (following the newest parents; stops on a cycle)."""
        infos = self.buffer.frame_infos()
        seen = {frame}
        while frame in infos:
            frame = infos[frame].parent
            if frame in seen:
                break
            seen.add(frame)
        return frame

    def rotation_to_root(self, frame: str) -> NDArray[np.float64] | None:
        """``R_root_frame`` (3x3) at the newest common time, or None if unknown."""
        if frame not in self.tf_frames:
            return None
        root = self.tf_root(frame)
        if root == frame:
            return np.eye(3)
        try:
            m = self.buffer.lookup_transform_matrix(root, frame, 0)
        except TransformException:
            return None
        return np.asarray(m[:3, :3], dtype=np.float64)

    def frame_kind(self, frame: str) -> tuple[FrameKind | None, str]:
        """Whether ``frame`` follows the optical (z forward, y down) or body (z up) convention.

        From TF when the frame is known: the root of its tree is taken as z up (REP 103),
        a frame whose y axis points down is optical and one whose z axis points up is a
        body frame. Otherwise from the name (``optical`` in it). Returns the kind and how
        it was decided.
        """
        rot = self.rotation_to_root(frame)
        if rot is not None:
            up_y, up_z = float(rot[2, 1]), float(rot[2, 2])
            if up_y < -0.6:
                return "optical", f"TF: its y axis points down in '{self.tf_root(frame)}'"
            if up_z > 0.6:
                return "body", f"TF: its z axis points up in '{self.tf_root(frame)}'"
        if "optical" in frame:
            return "optical", "its name contains 'optical'"
        return None, "unknown"

    # ------------------------------------------------------------------ odometry
    def odometry(self) -> list[tuple[str, str, str]]:
        """``(topic, frame_id, child_frame_id)`` of every odometry topic (newest sample)."""
        out = []
        for t in self.topics_of_type(ODOMETRY):
            if t.samples:
                msg = t.samples[-1].msg
                out.append((t.name, str(msg.header.frame_id), str(msg.child_frame_id)))
        return out

    def base_frame(self) -> str | None:
        """The vehicle frame whose +x is "ahead".

        ``planner.base_frame``, else an odometry child frame on TF, else ``base_link`` or
        ``base_footprint`` when on TF.
        """
        if self.expect and self.expect.planner and self.expect.planner.base_frame:
            return self.expect.planner.base_frame
        for _, _, child in self.odometry():
            if child in self.tf_frames:
                return child
        for name in ("base_link", "base_footprint"):
            if name in self.tf_frames:
                return name
        return None
