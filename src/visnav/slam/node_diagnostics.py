"""The SLAM node's ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header

if TYPE_CHECKING:
    from visnav.slam.node import SlamNode
    from visnav.slam.worker import SlamStats

__all__ = ["LOCALIZE_FRAMES", "SlamDiagnostics"]

LOCALIZE_FRAMES = 40
"""Localisation mode: frames without a fix before the node says it cannot localise."""


class SlamDiagnostics:
    """``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``, as diagnostic_updater).

    One status named after the node, every ``diagnostic_period`` s and when tracking is
    lost or regained: level OK while tracking, WARN while lost (message says so; in
    localisation mode before the first fix WARN, ERROR after ``LOCALIZE_FRAMES``), and the
    counters ``frames``, ``tracking_lost``, ``relocalized``, ``reinitialized``,
    ``keyframes``, ``loop_closures``, ``skipped``, ``dropped``, ``ba_runs``,
    ``ba_failures``, ``cpu_s`` and ``cpu_s.<stage>``, and ``last_frame_stamp_ns``: the
    stamp of the last frame they include (-1: none; frames still in the worker are not
    counted yet), so a reader can tell the frames after it. rtabmap reports these on its own
    ``rtabmap/info`` message type; a standard type lets any ROS tool read them.
    """

    def __init__(self, node: SlamNode) -> None:
        self._node = node
        self._status = get_message_class("diagnostic_msgs/msg/DiagnosticStatus")
        self._kv = get_message_class("diagnostic_msgs/msg/KeyValue")
        array = get_message_class("diagnostic_msgs/msg/DiagnosticArray")
        self._pub = node.create_publisher(array, "/diagnostics", 100)

    def publish(self, s: SlamStats, *, tracking: bool, started: bool) -> None:
        """Publish one status with the counters ``s`` and the node's state."""
        node = self._node
        values = {
            "frames": s.frames,
            "tracking_lost": s.lost,
            "relocalized": s.relocalized,
            "reinitialized": s.reinitialized,
            "keyframes": s.keyframes,
            "loop_closures": s.loops,
            "skipped": node.skipped,
            "dropped": node.dropped,
            "odometry_fallbacks": node.odometry_fallbacks,
            "ba_runs": s.ba_runs,
            "ba_failures": s.ba_failures,
            "cpu_s": round(s.cpu_s, 4),
            **{f"cpu_s.{k}": round(v, 4) for k, v in sorted(s.stage_cpu_s.items())},
            "last_frame_stamp_ns": node.stats_stamp_ns,
        }
        if not started:
            level, text = 0, "waiting for the first frame"
        elif node.localization and node.t_map_odom is None:
            n = node.unlocalized_frames
            level = 2 if n >= LOCALIZE_FRAMES else 1
            text = f"not localised in the saved map ({n} frames): map -> odom not published"
        elif tracking:
            level, text = 0, "tracking"
        else:
            level, text = 1, "tracking lost: relocalising (map -> odom not refreshed)"
        status = self._status(
            level=level,
            name=node.get_fully_qualified_name(),
            message=text,
            hardware_id="",
            values=[self._kv(key=k, value=str(v)) for k, v in values.items()],
        )
        header = Header(stamp=ns_to_time(node.get_clock().now_ns()), frame_id="")
        self._pub.publish(self._pub.msg_type(header=header, status=[status]))
