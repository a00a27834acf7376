"""Planner / navigation input checks: inputs published, sensor reach vs horizon, coverage ahead.

The planner is described by ``--expect`` (``planner``: horizon, inputs, sensors,
base_frame) or recognised in the live graph by node name (:data:`KNOWN_PLANNERS`; the
horizon then is that planner's default parameter, and its inputs its subscriptions of
sensor, odometry and map types).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.doctor.context import CheckContext
from visnav.doctor.findings import Finding, Severity
from visnav.msgs.errors import MessageError
from visnav.msgs.pointcloud import cloud_to_xyz
from visnav.tf.errors import TransformException

__all__ = ["KNOWN_PLANNERS", "PlannerSetup", "check_planner", "planner_setup"]

CLOUD = "sensor_msgs/msg/PointCloud2"
SCAN = "sensor_msgs/msg/LaserScan"
IMAGE = "sensor_msgs/msg/Image"
INPUT_TYPES = frozenset(
    {
        CLOUD,
        SCAN,
        IMAGE,
        "sensor_msgs/msg/CameraInfo",
        "nav_msgs/msg/Odometry",
        "nav_msgs/msg/OccupancyGrid",
        "geometry_msgs/msg/PoseStamped",
    }
)
SENSOR_INPUTS = frozenset({CLOUD, SCAN})

KNOWN_PLANNERS: dict[str, float | None] = {
    "ego_planner": 7.5,  # fsm.planning_horizon default of ego_planner_node
    "planner": None,
    "move_base": None,
    "controller_server": None,
    "navigator": None,
    "grid_map": None,
    "costmap": None,
}
"""Node name fragments of planners and their default horizon in metres (None: unknown)."""

_AHEAD_DEG = 15.0


@dataclass(frozen=True)
class PlannerSetup:
    """The planner doctor checks against.

    Attributes:
        horizon: metres, or None.
        horizon_source: where the horizon comes from.
        inputs: input topics (must be published).
        sensors: cloud / scan topics that must see ahead.
        nodes: planner nodes found in the graph.
    """

    horizon: float | None
    horizon_source: str
    inputs: tuple[str, ...]
    sensors: tuple[str, ...]
    nodes: tuple[str, ...]


def _is_goal(topic: str) -> bool:
    return "goal" in topic.rsplit("/", 1)[-1]


def planner_setup(ctx: CheckContext) -> PlannerSetup | None:
    """The planner from ``--expect`` or the graph, or None when there is none."""
    exp = ctx.expect.planner if ctx.expect is not None else None
    nodes: dict[str, float | None] = {}
    for node in ctx.obs.graph.nodes if ctx.obs.graph is not None else ():
        for frag, horizon in KNOWN_PLANNERS.items():
            if frag in node.name:
                nodes[node.fully_qualified_name] = horizon
                break
    if exp is None and not nodes:
        return None
    horizon, source = None, ""
    if exp is not None and exp.horizon is not None:
        horizon, source = exp.horizon, "--expect planner.horizon"
    else:
        for fqn, h in sorted(nodes.items()):
            if h is not None:
                horizon, source = h, f"default planning horizon of {fqn}"
                break
    if exp is not None and exp.inputs:
        inputs = exp.inputs
    else:
        subs = [
            e
            for e in ctx.endpoints(kind="subscription")
            if e.node_fqn in nodes and e.type_name in INPUT_TYPES and not _is_goal(e.topic)
        ]
        inputs = tuple(sorted({e.topic for e in subs}))
    if exp is not None and exp.sensors:
        sensors = exp.sensors
    else:
        types = {name: _topic_type(ctx, name) for name in inputs}
        sensors = tuple(t for t in inputs if types[t] in SENSOR_INPUTS)
    return PlannerSetup(horizon, source, tuple(inputs), tuple(sensors), tuple(sorted(nodes)))


def _topic_type(ctx: CheckContext, topic: str) -> str:
    data = ctx.obs.topics.get(topic)
    if data is not None:
        return data.type_name
    types = {e.type_name for e in ctx.endpoints(topic)}
    return next(iter(types)) if len(types) == 1 else ""


def planner_input_topics(ctx: CheckContext) -> frozenset[str]:
    """Inputs of the planner (other checks leave their missing publishers to this one)."""
    setup = planner_setup(ctx)
    return frozenset(setup.inputs) if setup is not None else frozenset()


def check_planner(ctx: CheckContext) -> Iterator[Finding]:
    """``planner.inputs_missing``, ``planner.range_short``, ``planner.fov_ahead``."""
    setup = planner_setup(ctx)
    if setup is None:
        return
    for topic in setup.inputs:
        data = ctx.obs.topics.get(topic)
        pubs = ctx.endpoints(topic, "publisher")
        if data is not None and data.count > 0:
            continue
        subs = sorted({e.node_fqn for e in ctx.endpoints(topic, "subscription")})
        yield Finding(
            Severity.ERROR,
            "planner.inputs_missing",
            f"planner input {topic} is not published"
            if not pubs
            else f"planner input {topic} has a publisher but delivered no message",
            {
                "topic": topic,
                "planner_nodes": list(setup.nodes) or subs,
                "publishers": sorted({e.node_fqn for e in pubs}),
                "messages": 0,
            },
            f"start the node that publishes {topic} (sensor driver, depth_image_proc, "
            "odometry) or remap the planner's input to the topic that carries it",
            topic,
        )
    for topic in setup.sensors:
        data = ctx.obs.topics.get(topic)
        if data is None or not data.samples:
            continue
        points = _points(data.type_name, [s.msg for s in data.samples[-3:]])
        yield from _range(ctx, setup, topic, data.type_name, points, data.samples[-1].msg)
        yield from _ahead(ctx, topic, data.frame_id.lstrip("/"), points)


def _points(type_name: str, msgs: list[Any]) -> NDArray[np.float64]:
    chunks = []
    for m in msgs:
        try:
            if type_name == CLOUD:
                pts = np.asarray(cloud_to_xyz(m), dtype=np.float64)
            else:
                r = np.asarray(m.ranges, dtype=np.float64)
                a = float(m.angle_min) + float(m.angle_increment) * np.arange(r.size)
                ok = np.isfinite(r) & (r >= float(m.range_min)) & (r <= float(m.range_max))
                pts = np.stack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)], axis=1)[ok]
        except (MessageError, ValueError, TypeError):
            continue
        pts = pts[np.isfinite(pts).all(axis=1)]
        if pts.shape[0] > 20000:
            pts = pts[:: pts.shape[0] // 20000 + 1]
        chunks.append(pts)
    return np.concatenate(chunks) if chunks else np.empty((0, 3))


def _range(
    ctx: CheckContext,
    setup: PlannerSetup,
    topic: str,
    type_name: str,
    points: NDArray[np.float64],
    last: Any,
) -> Iterator[Finding]:
    h = setup.horizon
    if h is None:
        return
    decl = ctx.declared.get(topic)
    reach, source = None, ""
    if decl is not None and decl.clip_far is not None and math.isfinite(decl.clip_far):
        reach, source = decl.clip_far, decl.source
    elif type_name == SCAN:
        reach, source = float(last.range_max), "LaserScan.range_max"
    measured = None
    if points.size:
        ahead = _in_base(ctx, str(getattr(last.header, "frame_id", "")).lstrip("/"), points)
        dist = ahead[:, 0] if ahead is not None else np.linalg.norm(points, axis=1)
        measured = float(np.percentile(dist, 99))
    ev: dict[str, Any] = {
        "topic": topic,
        "planner_horizon_m": h,
        "horizon_from": setup.horizon_source,
    }
    if measured is not None:
        ev["measured_p99_reach_m"] = round(measured, 3)
    if reach is not None:
        ev["sensor_range_m"] = reach
        ev["range_from"] = source
        if reach < h:
            yield Finding(
                Severity.ERROR,
                "planner.range_short",
                f"{topic} reaches {reach:.3g} m but the planner plans {h:.3g} m ahead",
                ev,
                f"obstacles between {reach:.3g} and {h:.3g} m are never seen: shorten the "
                "planner horizon or raise the sensor's clip far / max range",
                topic,
            )
    elif measured is not None and measured < 0.8 * h:
        yield Finding(
            Severity.WARNING,
            "planner.range_short",
            f"{topic} points reach {measured:.3g} m ahead (99th percentile), the planner plans "
            f"{h:.3g} m ahead",
            ev,
            "if the scene is not simply small, raise the sensor's range or shorten the horizon; "
            "declare the sensor range (clip_far) in --expect to make this check exact",
            topic,
        )


def _in_base(
    ctx: CheckContext, frame: str, points: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """``points`` in the vehicle frame, or None when the frame or the transform is unknown."""
    base = ctx.base_frame()
    if base is None or not frame:
        return None
    try:
        m = ctx.buffer.lookup_transform_matrix(base, frame, 0)
    except TransformException:
        return None
    out: NDArray[np.float64] = points @ m[:3, :3].T + m[:3, 3]
    return out


def _ahead(
    ctx: CheckContext, topic: str, frame: str, points: NDArray[np.float64]
) -> Iterator[Finding]:
    base = ctx.base_frame()
    if points.shape[0] < 50:
        return
    pts = _in_base(ctx, frame, points)
    if pts is None:
        return
    horiz = np.hypot(pts[:, 0], pts[:, 1])
    pts = pts[horiz > 0.3]
    if pts.shape[0] < 50:
        return
    bearing = np.degrees(np.arctan2(pts[:, 1], pts[:, 0]))
    ahead = float((np.abs(bearing) <= _AHEAD_DEG).mean())
    if ahead > 0.005:
        return
    yield Finding(
        Severity.ERROR,
        "planner.fov_ahead",
        f"{topic} never covers the region ahead of '{base}' (no point within "
        f"+-{_AHEAD_DEG:.0f} deg of +x)",
        {
            "topic": topic,
            "frame_id": frame,
            "base_frame": base,
            "bearing_min_deg": round(float(bearing.min()), 1),
            "bearing_max_deg": round(float(bearing.max()), 1),
            "fraction_ahead": round(ahead, 4),
        },
        "point the sensor forward (check the mount transform base -> sensor: yaw, and optical "
        "vs body frame) so that its field of view contains the direction of travel",
        topic,
    )
