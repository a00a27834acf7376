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
    "UnknownNodeError",
    "check_node_name",
    "resolve_node_class",
]

BUILTIN_NODES: Mapping[str, str] = {
    "image_proc": "visnav.perception.nodes:ImageProcNode",
    "usb_cam": "visnav.perception.camera_driver_node:UsbCamNode",
    "cv_camera": "visnav.perception.camera_driver_node:CvCameraNode",
    "point_cloud_xyz": "visnav.perception.nodes:PointCloudXyzNode",
    "point_cloud_xyzrgb": "visnav.perception.nodes:PointCloudXyzrgbNode",
    "convert_metric": "visnav.perception.nodes:ConvertMetricNode",
    "depthimage_to_laserscan": "visnav.perception.nodes:DepthImageToLaserScanNode",
    "slam": "visnav.slam.node:SlamNode",
    "static_transform_publisher": "visnav.tf.static_tf:StaticTransformPublisherNode",
    "sim": "visnav.sim.sim_node:SimulatorNode",
    "robot_state_publisher": "visnav.tf.robot_state_node:RobotStatePublisherNode",
    "joint_state_publisher": "visnav.tf.joint_state_publisher:JointStatePublisherNode",
    "joint_state_publisher_gui": "visnav.tf.joint_state_publisher:JointStatePublisherGuiNode",
    "ego_planner_node": "visnav.planning.ego_planner.nodes:EgoPlannerNode",
    "traj_server": "visnav.planning.ego_planner.nodes:TrajServerNode",
    "grid_map": "visnav.mapping.grid_map_node:GridMapNode",
    "move_base": "visnav.planning.nodes:NavigatorNode",
    "explore_lite": "visnav.planning.explore.node:ExploreNode",
    "costmap_2d": "visnav.mapping.nodes:CostmapNode",
    "mapper": "visnav.mapping.nodes:MapperNode",
    "map_server": "visnav.mapping.map_server_node:MapServerNode",
    "map_saver": "visnav.mapping.map_saver_node:MapSaverNode",
    "teleop_twist_keyboard": "visnav.teleop.nodes:TeleopTwistKeyboardNode",
    "turtlebot3_teleop_key": "visnav.teleop.nodes:Turtlebot3TeleopKeyNode",
    "amcl": "visnav.mapping.amcl_node:AmclNode",
    "slam_gmapping": "visnav.mapping.gmapping.node:SlamGmappingNode",
    "viz": "visnav.viz.node:ViewerNode",
    "ros1_bridge": "visnav.bridge.runner:Ros1BridgeNode",
    "foxglove_bridge": "visnav.bridge.foxglove.node:FoxgloveBridgeNode",
    "scenario_observer": "visnav.scenarios.observer:ObserverNode",
    "car_goals": "visnav.scenarios.missions:CarGoalSender",
    "tb3_goals": "visnav.scenarios.tb3_mission:Tb3Goals",
    "drone_mission": "visnav.scenarios.missions:DroneMission",
}


class UnknownNodeError(VisnavError, LookupError):
    """A node name is neither built in nor a ``module:Class`` path that imports."""


def check_node_name(name: str) -> str:
    """Check a node name without importing anything; return its kind.

    Returns:
        ``"builtin"`` or ``"path"`` (a ``module:Class`` path, not imported here).

    Raises:
        UnknownNodeError: neither a known name nor a ``module:Class`` path (the closest
            names are suggested).
    """
    if name in BUILTIN_NODES:
        return "builtin"
    module_name, sep, cls_name = name.partition(":")
    if sep and module_name and cls_name:
        return "path"
    known = list(BUILTIN_NODES)
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
        UnknownNodeError: unknown name (closest built-in names suggested) or a path that
            does not import.
    """
    check_node_name(name)
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
