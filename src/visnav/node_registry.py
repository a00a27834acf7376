"""visnav's built-in nodes by name, for launch files and ``visnav run``.

Names follow the ROS executables users know (``image_proc``, ``point_cloud_xyz``,
``depthimage_to_laserscan``, ...). Values are ``module:Class`` paths imported only
when a node is started, so reading the registry imports nothing heavy.
"""

from __future__ import annotations

import difflib
import importlib
from collections.abc import Mapping
from typing import Any

from visnav.errors import VisnavError

__all__ = [
    "BUILTIN_NODES",
    "PENDING_NODES",
    "NodeNotBuiltError",
    "UnknownNodeError",
    "check_node_name",
    "resolve_node_class",
]

BUILTIN_NODES: Mapping[str, str] = {
    "image_proc": "visnav.perception.nodes:ImageProcNode",
    "point_cloud_xyz": "visnav.perception.nodes:PointCloudXyzNode",
    "point_cloud_xyzrgb": "visnav.perception.nodes:PointCloudXyzrgbNode",
    "convert_metric": "visnav.perception.nodes:ConvertMetricNode",
    "depthimage_to_laserscan": "visnav.perception.nodes:DepthImageToLaserScanNode",
    "slam": "visnav.slam.node:SlamNode",
    "static_transform_publisher": "visnav.launch.static_tf:StaticTransformPublisherNode",
    "sim": "visnav.sim.sim_node:SimulatorNode",
    "robot_state_publisher": "visnav.sim.robot_state_node:RobotStatePublisherNode",
    "ego_planner_node": "visnav.planning.ego_planner.nodes:EgoPlannerNode",
    "traj_server": "visnav.planning.ego_planner.nodes:TrajServerNode",
    "grid_map": "visnav.mapping.grid_map_node:GridMapNode",
    "move_base": "visnav.planning.nodes:NavigatorNode",
    "costmap_2d": "visnav.mapping.nodes:CostmapNode",
    "mapper": "visnav.mapping.nodes:MapperNode",
    "map_server": "visnav.mapping.map_server_node:MapServerNode",
    "viz": "visnav.viz.node:ViewerNode",
    "ros1_bridge": "visnav.bridge.runner:Ros1BridgeNode",
}

# Node names launch files (and the roslaunch import) may use whose class another issue
# is still building: name -> who builds it. Move a name to BUILTIN_NODES once it exists.
PENDING_NODES: Mapping[str, str] = {
    "spawn_model": (
        "issue 3 (spawning into a running simulator: give the robot to the `sim` node's "
        "robots instead)"
    ),
}


class UnknownNodeError(VisnavError, LookupError):
    """A node name is neither built in nor a ``module:Class`` path that imports."""


class NodeNotBuiltError(UnknownNodeError):
    """A built-in node name whose class is not written yet (see :data:`PENDING_NODES`)."""


def check_node_name(name: str) -> str:
    """Check a node name without importing anything; return its kind.

    Returns:
        ``"builtin"``, ``"pending"`` (named in :data:`PENDING_NODES`) or ``"path"``
        (a ``module:Class`` path, not imported here).

    Raises:
        UnknownNodeError: neither a known name nor a ``module:Class`` path (the closest
            names are suggested).
    """
    if name in BUILTIN_NODES:
        return "builtin"
    if name in PENDING_NODES:
        return "pending"
    module_name, sep, cls_name = name.partition(":")
    if sep and module_name and cls_name:
        return "path"
    known = [*BUILTIN_NODES, *PENDING_NODES]
    close = difflib.get_close_matches(name, known, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    msg = (
        f"unknown node {name!r}: expected a built-in node ({', '.join(sorted(known))}) "
        f"or 'module:Class' for your own{hint}"
    )
    raise UnknownNodeError(msg)


def resolve_node_class(name: str) -> type[Any]:
    """Return the node class for a built-in name or a ``module:Class`` path.

    Raises:
        NodeNotBuiltError: a built-in name whose class another issue is still building.
        UnknownNodeError: unknown name (closest built-in names suggested) or a path that
            does not import.
    """
    if check_node_name(name) == "pending":
        msg = (
            f"node {name!r} is not built yet: {PENDING_NODES[name]} provides it; leave it out "
            "of the launch file until then"
        )
        raise NodeNotBuiltError(msg)
    path = BUILTIN_NODES.get(name, name)
    module_name, _, cls_name = path.partition(":")
    try:
        module = importlib.import_module(module_name)
        cls = getattr(module, cls_name)
    except (ImportError, AttributeError) as exc:
        msg = f"node {name!r}: cannot import {path!r} ({exc}); check the module and class names"
        raise UnknownNodeError(msg) from exc
    if not isinstance(cls, type):
        msg = f"node {name!r}: {path!r} is not a class"
        raise UnknownNodeError(msg)
    return cls
