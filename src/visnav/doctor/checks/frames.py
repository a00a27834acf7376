"""Frame checks: optical vs body conventions (the rotated cloud), odometry vs TF, frame ids.

Conventions (REP 103/105): body frames have x forward, y left, z up; optical frames
z forward, x right, y down. A frame's convention is read from TF (the tree's root is
z up; see :meth:`~visnav.doctor.context.CheckContext.frame_kind`), a cloud's from its
points: optical data have nearly every point at +z (in front of the camera) while x
takes both signs; body data have nearly every point at +x while z takes both signs.
"""

from __future__ import annotations

import difflib
import math
from collections import defaultdict
from collections.abc import Iterator
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from visnav.doctor.context import CheckContext
from visnav.doctor.findings import Finding, Severity
from visnav.errors import VisnavError
from visnav.msgs.errors import MessageError
from visnav.msgs.pointcloud import cloud_to_xyz
from visnav.msgs.time import time_to_ns
from visnav.tf.errors import TransformException
from visnav.tf.transforms import pose_to_matrix

__all__ = ["check_frame_ids", "check_frame_conventions", "check_odometry", "cloud_convention"]

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
CLOUD = "sensor_msgs/msg/PointCloud2"
SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
FRAME_TYPES = frozenset(
    {
        IMAGE,
        CAMERA_INFO,
        CLOUD,
        SCAN,
        ODOMETRY,
        "sensor_msgs/msg/CompressedImage",
        "sensor_msgs/msg/Imu",
        "nav_msgs/msg/OccupancyGrid",
        "nav_msgs/msg/Path",
        "geometry_msgs/msg/PoseStamped",
        "geometry_msgs/msg/PoseWithCovarianceStamped",
    }
)
"""Types whose header.frame_id must name a frame."""

_MAX_POINTS = 20000


def cloud_convention(
    points: NDArray[np.float32],
) -> tuple[Literal["optical", "body"] | None, dict[str, float]]:
    """Which convention a cloud's points follow (None: undecided), with the statistics."""
    pts = np.asarray(points, dtype=np.float64)
    pts = pts[np.isfinite(pts).all(axis=1)]
    pts = pts[np.linalg.norm(pts, axis=1) > 0.05]
    if pts.shape[0] > _MAX_POINTS:
        pts = pts[:: pts.shape[0] // _MAX_POINTS + 1]
    if pts.shape[0] < 50:
        return None, {"points": float(pts.shape[0])}
    fx = float((pts[:, 0] > 0).mean())
    fz = float((pts[:, 2] > 0).mean())
    stats = {
        "points": float(pts.shape[0]),
        "fraction_x_positive": round(fx, 3),
        "fraction_z_positive": round(fz, 3),
        "median_abs_xyz": np.round(np.median(np.abs(pts), axis=0), 3).tolist(),
    }
    if fz >= 0.95 and fx < 0.9:
        return "optical", stats
    if fx >= 0.95 and fz < 0.9:
        return "body", stats
    return None, stats


def _optical_sibling(ctx: CheckContext, frame: str) -> str | None:
    """An optical frame attached to ``frame`` (its child or sibling), if TF has one."""
    infos = ctx.buffer.frame_infos()
    children = [f for f, i in infos.items() if i.parent == frame and "optical" in f]
    if children:
        return sorted(children)[0]
    parent = infos[frame].parent if frame in infos else None
    siblings = [f for f, i in infos.items() if parent and i.parent == parent and "optical" in f]
    return sorted(siblings)[0] if siblings else None


_WORLD_FRAMES = frozenset({"map", "odom", "world", "earth"})
"""REP 105's world-fixed frames (and Gazebo's ``world``)."""


def _is_world_frame(ctx: CheckContext, frame: str) -> bool:
    """A world-fixed frame (its points surround the origin: no "in front" to judge).

    An accumulated map's points lie on every side of its origin, so the share of points
    in front of a sensor says nothing about their convention.
    """
    if frame in _WORLD_FRAMES or frame in {f.lstrip("/") for _, f, _ in ctx.odometry()}:
        return True
    return frame in ctx.tf_frames and ctx.tf_root(frame) == frame


def check_frame_conventions(ctx: CheckContext) -> Iterator[Finding]:
    """``frames.rotated_cloud``, ``frames.image_in_body_frame``, ``frames.scan_in_...``."""
    for topic in ctx.topics_of_type(CLOUD):
        frame = topic.frame_id.lstrip("/")
        if not frame or not topic.samples or _is_world_frame(ctx, frame):
            continue
        kind, how = ctx.frame_kind(frame)
        votes: list[str] = []
        stats: dict[str, Any] = {}
        for s in topic.samples[-3:]:
            try:
                data_kind, st = cloud_convention(cloud_to_xyz(s.msg))
            except MessageError:
                continue
            if data_kind is not None:
                votes.append(data_kind)
                stats = st
        if kind is None or not votes:
            continue
        data = max(set(votes), key=votes.count)
        if data == kind:
            continue
        if kind == "body":
            optical = _optical_sibling(ctx, frame)
            title = (
                f"{topic.name}: cloud in body frame '{frame}' but its points are optical "
                "(z forward): the cloud appears rotated"
            )
            fix = (
                "set header.frame_id to the camera's optical frame"
                + (f" '{optical}'" if optical else " (z forward, x right, y down)")
                + ", or rotate the points into the body convention (x = z, y = -x, z = -y)"
            )
        else:
            title = (
                f"{topic.name}: cloud in optical frame '{frame}' but its points are body "
                "(x forward, z up): the cloud appears rotated"
            )
            fix = (
                "set header.frame_id to the body frame the points are in (e.g. the camera "
                "link), or rotate them into the optical convention (x = -y, y = -z, z = x)"
            )
        yield Finding(
            Severity.ERROR,
            "frames.rotated_cloud",
            title,
            {
                "topic": topic.name,
                "frame_id": frame,
                "frame_is": kind,
                "decided_by": how,
                "data_look": data,
                **stats,
            },
            fix,
            topic.name,
        )
    yield from _image_frames(ctx)
    for topic in ctx.topics_of_type(SCAN):
        frame = topic.frame_id.lstrip("/")
        kind, how = ctx.frame_kind(frame) if frame else (None, "")
        if kind == "optical":
            yield Finding(
                Severity.ERROR,
                "frames.scan_in_optical_frame",
                f"{topic.name}: LaserScan in optical frame '{frame}': its scan plane is vertical",
                {"topic": topic.name, "frame_id": frame, "frame_is": kind, "decided_by": how},
                "a LaserScan lies in the x-y plane of its frame: use a body frame (z up), e.g. "
                "the camera link, for a scan made from depth (depthimage_to_laserscan "
                "output_frame_id)",
                topic.name,
            )


def _image_frames(ctx: CheckContext) -> Iterator[Finding]:
    for topic in ctx.topics_of_type(IMAGE, CAMERA_INFO):
        frame = topic.frame_id.lstrip("/")
        if not frame or frame not in ctx.tf_frames:
            continue
        kind, how = ctx.frame_kind(frame)
        if kind != "body" or not how.startswith("TF"):
            continue
        optical = _optical_sibling(ctx, frame)
        yield Finding(
            Severity.ERROR,
            "frames.image_in_body_frame",
            f"{topic.name} is in body frame '{frame}' (z up), but image data are optical",
            {
                "topic": topic.name,
                "frame_id": frame,
                "frame_is": kind,
                "decided_by": how,
                **({"optical_frame_on_tf": optical} if optical else {}),
            },
            "set the camera's frame_id to its optical frame"
            + (f" '{optical}'" if optical else "")
            + " (rotation rpy = (-pi/2, 0, -pi/2) from the camera link): projected points "
            "and clouds otherwise come out rotated",
            topic.name,
        )


# ---------------------------------------------------------------------- odometry


def _angle(r: NDArray[np.float64]) -> float:
    return math.acos(max(-1.0, min(1.0, (float(np.trace(r)) - 1.0) / 2.0)))


def check_odometry(ctx: CheckContext) -> Iterator[Finding]:
    """``frames.odom_tf_mismatch``."""
    known = ctx.tf_frames
    infos = ctx.buffer.frame_infos()
    for topic in ctx.topics_of_type(ODOMETRY):
        if not topic.samples:
            continue
        msg = topic.samples[-1].msg
        frame, child = str(msg.header.frame_id).lstrip("/"), str(msg.child_frame_id).lstrip("/")
        base = {"topic": topic.name, "frame_id": frame, "child_frame_id": child}
        if frame and frame == child:
            yield Finding(
                Severity.ERROR,
                "frames.odom_tf_mismatch",
                f"{topic.name}: frame_id and child_frame_id are both '{frame}'",
                base,
                "frame_id is the fixed frame (odom), child_frame_id the vehicle (base_link)",
                topic.name,
            )
            continue
        if not known or not child:
            continue
        if child not in known:
            close = difflib.get_close_matches(child, sorted(known), n=3, cutoff=0.5)
            tf_children = sorted(f for f, i in infos.items() if i.parent == frame)
            if frame in known or close:
                yield Finding(
                    Severity.ERROR,
                    "frames.odom_tf_mismatch",
                    f"{topic.name}: child_frame_id '{child}' is not on TF"
                    + (f"; TF places {', '.join(tf_children)} in '{frame}'" if tf_children else ""),
                    {
                        **base,
                        "tf_children_of_frame_id": tf_children,
                        **({"similar_frames": close} if close else {}),
                    },
                    "set child_frame_id to the vehicle frame TF uses"
                    + (f" ('{(tf_children or close)[0]}')" if tf_children or close else ""),
                    topic.name,
                )
            continue
        if frame not in known:
            close = difflib.get_close_matches(frame, sorted(known), n=3, cutoff=0.6)
            parent = infos[child].parent if child in infos else ""
            yield Finding(
                Severity.ERROR if close else Severity.INFO,
                "frames.odom_tf_mismatch",
                f"{topic.name}: frame_id '{frame}' is not on TF (TF places '{child}' in "
                f"'{parent}')",
                {
                    **base,
                    "tf_parent_of_child": parent,
                    **({"similar_frames": close} if close else {}),
                },
                f"set frame_id to '{close[0]}'"
                if close
                else "fine for ground truth in a world frame; otherwise publish the "
                f"transform {frame} -> {parent} or use the TF frame in frame_id",
                topic.name,
            )
            continue
        yield from _odometry_pose(ctx, topic.name, frame, child, [s.msg for s in topic.samples])


def _odometry_pose(
    ctx: CheckContext, name: str, frame: str, child: str, msgs: list[Any]
) -> Iterator[Finding]:
    base = {"topic": name, "frame_id": frame, "child_frame_id": child}
    compared = 0
    bad: list[tuple[float, float]] = []
    for m in msgs:
        try:
            stamp = time_to_ns(m.header.stamp)
            if stamp <= 0:  # 0 would mean "latest" to TF
                continue
            tf = ctx.buffer.lookup_transform_matrix(frame, child, stamp)
        except (TransformException, MessageError):
            continue
        try:
            odo = pose_to_matrix(m.pose.pose)
        except (VisnavError, ValueError):
            continue
        compared += 1
        dpos = float(np.linalg.norm(tf[:3, 3] - odo[:3, 3]))
        dang = math.degrees(_angle(tf[:3, :3].T @ odo[:3, :3]))
        if dpos > 0.05 or dang > 3.0:
            bad.append((dpos, dang))
    if compared >= 3 and len(bad) >= 0.2 * compared:
        worst = max(bad)
        yield Finding(
            Severity.ERROR,
            "frames.odom_tf_mismatch",
            f"{name}: odometry pose and TF {frame} -> {child} disagree (up to {worst[0]:.3g} m, "
            f"{worst[1]:.3g} deg)",
            {
                **base,
                "compared": compared,
                "disagreeing": len(bad),
                "max_position_error_m": round(worst[0], 4),
                "max_angle_error_deg": round(worst[1], 3),
            },
            "two sources estimate the same transform (e.g. diff drive odom TF and an EKF): "
            "let one publish the TF, or publish the other under its own frames",
            name,
        )


# ---------------------------------------------------------------------- frame ids


def check_frame_ids(ctx: CheckContext) -> Iterator[Finding]:
    """``frames.empty_frame_id`` and ``frames.leading_slash``."""
    slashed: dict[str, set[str]] = defaultdict(set)
    for topic in ctx.obs.topics.values():
        if topic.type_name not in FRAME_TYPES or not topic.count:
            continue
        empty = sum(1 for f in topic.frame_ids if not f)
        if empty:
            yield Finding(
                Severity.ERROR,
                "frames.empty_frame_id",
                f"{topic.name}: header.frame_id is empty in {empty} of {topic.count} messages",
                {"topic": topic.name, "empty": empty, "messages": topic.count},
                "set header.frame_id to the sensor's frame (for a camera, its optical frame)",
                topic.name,
            )
        for f in set(topic.frame_ids):
            if f.startswith("/"):
                slashed[f].add(topic.name)
    for r in ctx.obs.tf:
        for f in (r.parent, r.child):
            if f.startswith("/"):
                slashed[f].add("/tf_static" if r.is_static else "/tf")
    for frame, topics in sorted(slashed.items()):
        yield Finding(
            Severity.WARNING,
            "frames.leading_slash",
            f"frame id '{frame}' starts with '/'",
            {"frame_id": frame, "topics": sorted(topics)},
            f"use '{frame.lstrip('/')}': tf2 strips the slash on insertion but refuses it in "
            "lookups (ROS 1 tf_prefix habit)",
            frame,
        )
