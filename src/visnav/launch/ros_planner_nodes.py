"""roslaunch nodes of ego-planner and of the camera drivers, mapped onto visnav's built-ins.

==========================================  =================================================
roslaunch                                   visnav
==========================================  =================================================
``ego_planner ego_planner_node``            ``ego_planner_node``: parameters ``fsm/``,
                                            ``grid_map/``, ``manager/``, ``optimization/`` by
                                            name (``a/b`` -> ``a.b``); ``fsm/waypoint_num`` +
                                            ``fsm/waypointN_x|y|z`` -> ``fsm.waypoints``;
                                            ``fsm/emergency_time_`` -> ``fsm.emergency_time``;
                                            remaps of ``/odom_world``, ``/grid_map/odom``,
                                            ``/grid_map/cloud``, ``/grid_map/pose``,
                                            ``/grid_map/depth``, ``/planning/bspline`` (also
                                            written ``~name`` or ``name``) -> the topic
                                            parameters; upstream's topics when not remapped
``ego_planner traj_server``                 ``traj_server``: ``traj_server/time_forward``;
                                            remaps of ``/position_cmd``, ``planning/bspline``,
                                            ``/odom_world``
``waypoint_generator waypoint_generator``   folded into the planner: with
                                            ``waypoint_type`` ``manual-lonely-waypoint`` its
                                            ``~goal`` becomes the planner's ``goal_topic``
``usb_cam usb_cam_node``                    ``usb_cam`` (same parameters)
``cv_camera cv_camera_node``                ``cv_camera`` (same parameters)
==========================================  =================================================

Upstream names that ego-planner itself never reads (``bspline/limit_*``, a leftover of
Fast-Planner), those it reads but never uses (``fsm/planning_horizen_time``,
``manager/max_jerk``, ``grid_map/depth_filter_tolerance``) and ``fsm/waypointN_*`` beyond
``fsm/waypoint_num`` are named in the import's notes; every other parameter goes to the
node, which reports one it does not declare with the closest name it has
(:mod:`visnav.launch.param_check`). Messages differ from upstream's: the planner sends its
trajectory as ``trajectory_msgs/MultiDOFJointTrajectory`` (not ``ego_planner/Bspline``) and
traj_server its command as a one-point ``MultiDOFJointTrajectory`` (not
``quadrotor_msgs/PositionCommand``), which is what visnav's simulated quadrotor follows on
``<robot_namespace>/command/trajectory``.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from visnav.launch.description import NodeSpec
    from visnav.launch.ros_nodes import ParamServer, RosNode

__all__ = ["PLANNER_TRANSLATORS"]

Translation = tuple["NodeSpec | None", list[str]]

# upstream topic (as ego-planner's code names it) -> visnav parameter, per node
_PLANNER_TOPICS: Mapping[str, tuple[str, str]] = {
    "odom_world": ("odometry_topic", "/odom_world"),
    "grid_map/odom": ("grid_map.odom_topic", "/grid_map/odom"),
    "grid_map/cloud": ("grid_map.cloud_topic", "/grid_map/cloud"),
    "grid_map/pose": ("grid_map.pose_topic", "/grid_map/pose"),
    "grid_map/depth": ("grid_map.depth_topic", "/grid_map/depth"),
    "planning/bspline": ("trajectory_topic", "/planning/bspline"),
}
_SERVER_TOPICS: Mapping[str, tuple[str, str]] = {
    "position_cmd": ("command_topic", "/position_cmd"),
    "planning/bspline": ("trajectory_topic", "planning/bspline"),
    "odom_world": ("odometry_topic", "/odom_world"),
}
_NOT_READ = ("bspline.",)
# read by ego-planner but never used there, so not parameters of visnav's planner
_READ_UNUSED = ("fsm.planning_horizen_time", "manager.max_jerk", "grid_map.depth_filter_tolerance")
_WAYPOINT = re.compile(r"^fsm\.waypoint(\d+)_([xyz])$")
_GOAL_PARAM = "_folded_goal_topic"


def _topic_key(name: str, fqn: str) -> str:
    """A remap's ``from`` as ego-planner's code names it (``/x``, ``~/x``, ``x`` -> ``x``)."""
    if name.startswith("~/"):
        return name[2:]
    prefix = fqn.rstrip("/") + "/"
    if name.startswith(prefix):
        return name[len(prefix) :]
    return name.lstrip("/")


def _topics(
    node: RosNode, table: Mapping[str, tuple[str, str]]
) -> tuple[dict[str, Any], tuple[tuple[str, str], ...]]:
    """Topic parameters from the node's remaps; the remaps left for the node itself."""
    params: dict[str, Any] = dict(table.values())
    rest: list[tuple[str, str]] = []
    seen: set[str] = set()
    for src, dst in node.remaps:
        key = _topic_key(src, node.fqn)
        if key in table:
            if key not in seen:  # first rule wins, as in rcl
                params[table[key][0]] = dst
                seen.add(key)
            continue
        rest.append((src, dst))
    return params, tuple(rest)


def _waypoints(node: RosNode, private: dict[str, Any], notes: list[str]) -> list[str]:
    issues: list[str] = []
    count = private.pop("fsm.waypoint_num", None)
    coords: dict[tuple[int, str], Any] = {}
    for name, match in [(n, _WAYPOINT.match(n)) for n in list(private)]:
        if match is not None:
            coords[(int(match.group(1)), match.group(2))] = private.pop(name)
    if count is None:
        if coords:
            issues.append(
                f"ego_planner_node {node.fqn}: fsm/waypointN_* are given without "
                "fsm/waypoint_num; set fsm/waypoint_num to how many to fly"
            )
        return issues
    try:
        n = int(count)
    except (TypeError, ValueError):
        return [f"ego_planner_node {node.fqn}: fsm/waypoint_num {count!r} is not an integer"]
    flat: list[float] = []
    missing: list[str] = []
    for i in range(max(n, 0)):
        for axis in "xyz":
            value = coords.pop((i, axis), None)
            if value is None:
                missing.append(f"fsm/waypoint{i}_{axis}")
                continue
            try:
                flat.append(float(value))
            except (TypeError, ValueError):
                issues.append(
                    f"ego_planner_node {node.fqn}: fsm/waypoint{i}_{axis} {value!r} is not a number"
                )
    if missing:
        issues.append(
            f"ego_planner_node {node.fqn}: fsm/waypoint_num is {n} but {', '.join(missing)} "
            "are not set"
        )
    if coords:
        unread = ", ".join(f"fsm/waypoint{i}_{a}" for i, a in sorted(coords))
        notes.append(
            f"{node.source}: ego_planner_node {node.fqn}: {unread} lie beyond "
            f"fsm/waypoint_num={n}; ego-planner does not read them either"
        )
    if flat and not issues:
        private["fsm.waypoints"] = flat
    return issues


def _ego_planner_node(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    del packages
    issues = [f"ego_planner_node {node.fqn}: arguments {list(node.args)} are not mapped"] * bool(
        node.args
    )
    private = params.private(node.fqn)
    if "fsm.emergency_time_" in private:  # upstream's name, trailing underscore included
        private["fsm.emergency_time"] = private.pop("fsm.emergency_time_")
    issues += _waypoints(node, private, params.notes)
    not_read = sorted(k for k in private if k.startswith(_NOT_READ))
    for key in not_read:
        del private[key]
    if not_read:
        shown = ", ".join(k.replace(".", "/") for k in not_read)
        params.notes.append(
            f"{node.source}: ego_planner_node {node.fqn}: {shown} are not read by ego-planner "
            "(Fast-Planner's names); its limits are manager/max_vel and manager/max_acc"
        )
    unused = [k for k in _READ_UNUSED if k in private]
    for key in unused:
        del private[key]
    if unused:
        shown = ", ".join(k.replace(".", "/") for k in unused)
        params.notes.append(
            f"{node.source}: ego_planner_node {node.fqn}: {shown} are read by ego-planner but "
            "never used there, so visnav's planner has no such parameters (dropped)"
        )
    order = private.pop("optimization.order", 3)
    if order != 3:
        issues.append(
            f"ego_planner_node {node.fqn}: optimization/order {order!r}: visnav's ego-planner "
            "optimises cubic B-splines only (order 3, as upstream's default)"
        )
    topics, remaps = _topics(node, _PLANNER_TOPICS)
    goal = params.folded.get(_GOAL_PARAM)
    if goal is not None:
        topics["goal_topic"] = goal
    return node.spec("ego_planner_node", {**topics, **private}, remaps=remaps), issues


def _traj_server(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    del packages
    issues = [f"traj_server {node.fqn}: arguments {list(node.args)} are not mapped"] * bool(
        node.args
    )
    topics, remaps = _topics(node, _SERVER_TOPICS)
    return node.spec("traj_server", {**topics, **params.private(node.fqn)}, remaps=remaps), issues


def _waypoint_generator(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    del packages
    private = params.private(node.fqn)
    kind = str(private.pop("waypoint_type", "manual"))
    if kind not in ("manual", "manual-lonely-waypoint"):
        return None, [
            f"waypoint_generator {node.fqn}: waypoint_type {kind!r} is not mapped (only "
            "manual-lonely-waypoint: the planner takes goals itself)"
        ]
    goal = next(
        (dst for src, dst in node.remaps if _topic_key(src, node.fqn) == "goal"),
        f"{node.fqn}/goal",
    )
    params.folded[_GOAL_PARAM] = goal
    params.notes.append(
        f"{node.source}: waypoint_generator {node.fqn} is folded into ego_planner_node: the "
        f"planner takes its goals (geometry_msgs/PoseStamped) on {goal} itself"
        + (f"; ignored: {', '.join(sorted(private))}" if private else "")
    )
    return None, []


def _driver(executable: str) -> Callable[[RosNode, ParamServer, Mapping[str, str]], Translation]:
    def translate(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
        del packages
        issues = [f"{executable} {node.fqn}: arguments {list(node.args)} are not mapped"] * bool(
            node.args
        )
        return node.spec(executable, params.private(node.fqn)), issues

    return translate


PLANNER_TRANSLATORS: Mapping[
    tuple[str, str], Callable[[RosNode, ParamServer, Mapping[str, str]], Translation]
] = {
    ("ego_planner", "ego_planner_node"): _ego_planner_node,
    ("ego_planner", "traj_server"): _traj_server,
    ("waypoint_generator", "waypoint_generator"): _waypoint_generator,
    ("usb_cam", "usb_cam_node"): _driver("usb_cam"),
    ("cv_camera", "cv_camera_node"): _driver("cv_camera"),
}
"""Translators of this module by ``(pkg, type)``: ``waypoint_generator`` must be
translated before ``ego_planner_node`` (see :func:`translation_order`)."""


def translation_order(pkg_type: tuple[str, str]) -> int:
    """Sort key: nodes that fold into others first (waypoint_generator before the planner)."""
    return 0 if pkg_type == ("waypoint_generator", "waypoint_generator") else 1
