"""How ROS 1 nodes of a roslaunch file become visnav nodes.

=============================================  ============================================
roslaunch                                      visnav
=============================================  ============================================
``robot_state_publisher``                      ``robot_state_publisher``: ``robot_description``
                                               and ``tf_prefix`` found as roscpp's
                                               ``searchParam`` finds them (``tf_prefix`` ->
                                               ``frame_prefix``); ``publish_frequency`` (ROS 1's
                                               default 50)
``joint_state_publisher`` (``_gui``)           ``joint_state_publisher`` (``_gui``: headless):
                                               ``rate``, ``source_list``, ``zeros``, ``use_gui``
``tf2_ros`` / ``tf``                           ``static_transform_publisher`` (args -> params;
``static_transform_publisher``                 tf's period is dropped: ``/tf_static`` latches)
``gazebo_ros spawn_model``                     ``spawn_model``: ``-urdf|-sdf``, ``-param P`` or
                                               ``-file F``, ``-model``, ``-x -y -z -R -P -Y``,
                                               ``-robot_namespace``; ``-R -P -J``,
                                               ``-unpause``, ``-b``, ``-wait``,
                                               ``-package_to_model`` noted as ignored;
                                               ``-database``, ``-sdf`` refused
``depthimage_to_laserscan``                    ``depthimage_to_laserscan``: topic ``image`` ->
                                               ``depth``, its sibling ``camera_info`` ->
                                               ``depth_camera_info`` (image_transport's rule);
                                               ``output_frame_id`` -> ``output_frame``
``image_proc``                                 ``image_proc`` (same topics)
``rviz``                                       ``viz`` (the viewer): ``-d CONFIG`` (its fixed
                                               frame is read), ``-f FRAME``; left out with a
                                               note without rerun-sdk
``gazebo_ros/launch/empty_world.launch``       ``sim`` named ``gazebo``: ``world_name`` ->
                                               ``world``; ``/use_sim_time``; the other args
                                               (``paused`` too) noted when not Gazebo's default
=============================================  ============================================

ego-planner's nodes (``ego_planner_node``, ``traj_server``, ``waypoint_generator``) and the
camera drivers (``usb_cam``, ``cv_camera``) are mapped in :mod:`visnav.launch.ros_planner_nodes`;
Gazebo's ``empty_world.launch`` and ``spawn_model`` in :mod:`visnav.launch.ros_gazebo`.

Private parameters (``<param>`` inside ``<node>``, ``~name``) become the node's
parameters; nested names (``a/b``) become ROS 2's ``a.b``. A node with
``respawn="true"`` runs in its own process; the others share one.
"""

from __future__ import annotations

import contextlib
import importlib.util
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from visnav.launch.description import NodeSpec, default_process
from visnav.launch.ros_control_nodes import CONTROLLER_TRANSLATORS
from visnav.launch.ros_gazebo import (
    EMPTY_WORLD_ARGS,
    GAZEBO_TRANSLATORS,
    empty_world_node,
    fold_spawns,
)
from visnav.safe_yaml import YamlError, load_yaml_file
from visnav.tf.static_tf import StaticTransformError, static_transform_params_from_args

__all__ = [
    "EMPTY_WORLD_ARGS",
    "MAPPABLE",
    "NODE_TRANSLATORS",
    "ParamServer",
    "RosNode",
    "empty_world_node",
    "fold_spawns",
    "translate_node",
]

MAPPABLE = (
    "<launch>, <arg>, <group ns if unless>, <remap>, <param> (value/type, textfile, command "
    "running xacro; use_sim_time, robot_description), <rosparam command=load>, <include> of "
    "$(find gazebo_ros)/launch/empty_world.launch, of other roslaunch XML files and of visnav "
    "YAML launch files, and <node> of robot_state_publisher, joint_state_publisher(_gui), "
    "tf2_ros or tf "
    "static_transform_publisher, gazebo_ros spawn_model, depthimage_to_laserscan, image_proc, "
    "rviz (-> the viz node), ego_planner ego_planner_node and traj_server, waypoint_generator "
    "(folded into the planner), usb_cam usb_cam_node, cv_camera cv_camera_node, "
    "controller_manager spawner / controller_manager spawn|load|start (the sim's ros_control "
    "controllers), map_server map_server / map_saver, amcl, move_base (DWAPlannerROS), "
    "gmapping slam_gmapping, explore_lite explore, turtlebot3_teleop turtlebot3_teleop_key, "
    "teleop_twist_keyboard. ROS 2 launch "
    "files (Python or XML) are out of scope: write a visnav "
    "YAML launch file (docs/launch.md)"
)


def _bool(text: str) -> bool:
    return str(text).strip().lower() in ("true", "1", "yes", "on")


class ParamServer:
    """roslaunch's parameter server: absolute names -> values, read after loading."""

    def __init__(self) -> None:
        self._values: dict[str, Any] = {}
        self._sources: dict[str, str] = {}
        self._read: set[str] = set()
        self.notes: list[str] = []
        """What translators left out or folded (shown when the launch starts)."""
        self.folded: dict[str, Any] = {}
        """Values a folded node hands to another (waypoint_generator's goal topic)."""

    def set(self, name: str, value: Any, source: str) -> None:
        """Set ``name`` (absolute); a mapping sets its leaves under ``name``."""
        if isinstance(value, dict):
            self.load(name, value, source)
            return
        self._values[name] = value
        self._sources[name] = source

    def load(self, namespace: str, data: Mapping[str, Any], source: str) -> None:
        """Set every leaf of ``data`` under ``namespace`` (``<rosparam command=load>``)."""
        for key, value in data.items():
            self.set(f"{namespace.rstrip('/')}/{key}", value, source)

    def get(self, name: str) -> Any:
        """The value of ``name`` (None if unset); marks it read."""
        if name in self._values:
            self._read.add(name)
        return self._values.get(name)

    def source(self, name: str) -> str:
        """Where ``name`` was set."""
        return self._sources.get(name, "?")

    def search(self, namespace: str, key: str) -> str | None:
        """roscpp's ``searchParam``: ``key`` in ``namespace`` or its closest ancestor."""
        parts = [p for p in namespace.split("/") if p]
        for depth in range(len(parts), -1, -1):
            name = "/" + "/".join([*parts[:depth], key])
            if name in self._values:
                return name
        return None

    def private(self, fqn: str) -> dict[str, Any]:
        """The private parameters of node ``fqn`` (``a/b`` -> ``a.b``); marks them read."""
        prefix = fqn.rstrip("/") + "/"
        out: dict[str, Any] = {}
        for name, value in self._values.items():
            if name.startswith(prefix):
                out[name[len(prefix) :].replace("/", ".")] = value
                self._read.add(name)
        return out

    def unread(self) -> list[str]:
        """Names no mapped node read."""
        return [n for n in self._values if n not in self._read]


@dataclass(frozen=True)
class RosNode:
    """A ``<node>`` element as roslaunch resolved it."""

    pkg: str
    type: str
    name: str
    namespace: str
    args: Sequence[str]
    remaps: tuple[tuple[str, str], ...]
    respawn: bool
    respawn_delay: float
    required: bool
    source: str

    @property
    def fqn(self) -> str:
        """``/ns/name``."""
        return f"{self.namespace.rstrip('/')}/{self.name}"

    def spec(self, executable: str, params: Mapping[str, Any], **changes: Any) -> NodeSpec:
        """A :class:`NodeSpec` with this node's name, namespace, remaps and process options."""
        fields: dict[str, Any] = {
            "executable": executable,
            "name": self.name,
            "namespace": self.namespace,
            "params": dict(params),
            "remaps": self.remaps,
            "process": "own" if self.respawn else default_process(executable),
            "respawn": self.respawn,
            "respawn_delay": self.respawn_delay,
            "required": self.required,
            "source": self.source,
        }
        fields.update(changes)
        return NodeSpec(**fields)


Translation = tuple[NodeSpec | None, list[str]]


def _no_args(node: RosNode) -> list[str]:
    if node.args:
        return [
            f"node {node.fqn} ({node.pkg}/{node.type}): arguments {list(node.args)} are not mapped"
        ]
    return []


def _description_param(node: RosNode, params: ParamServer, private: dict[str, Any]) -> str | None:
    """Put ``robot_description`` into ``private`` as roscpp's ``searchParam`` finds it."""
    if "robot_description" in private:
        return None
    found = params.search(node.namespace, "robot_description")
    if found is None:
        return (
            f"{node.type} {node.fqn} needs a robot_description parameter: set "
            '<param name="robot_description" command="$(find xacro)/xacro FILE"/>'
        )
    private["robot_description"] = params.get(found)
    return None


def _robot_state_publisher(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    del packages
    issues = _no_args(node)
    private = params.private(node.fqn)
    # ROS 1 robot_state_publisher finds tf_prefix with searchParam (private first)
    if "tf_prefix" not in private:
        found = params.search(node.namespace, "tf_prefix")
        if found is not None:
            private["tf_prefix"] = params.get(found)
    prefix = private.pop("tf_prefix", None)
    if prefix:
        private["frame_prefix"] = str(prefix).strip("/") + "/"
    private.setdefault("publish_frequency", 50.0)  # ROS 1's default (ROS 2's is 20)
    dropped = []
    if not _bool(str(private.pop("use_tf_static", True))):
        dropped.append("use_tf_static:=false (fixed joints always go to /tf_static)")
    if "ignore_timestamp" in private:
        dropped.append(f"ignore_timestamp:={private.pop('ignore_timestamp')}")
    if dropped:
        params.notes.append(
            f"{node.source}: robot_state_publisher {node.fqn}: ignored " + ", ".join(dropped)
        )
    issue = _description_param(node, params, private)
    if issue:
        issues.append(issue)
    return node.spec("robot_state_publisher", private), issues


def _joint_state_publisher(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    del packages
    issues = _no_args(node)
    private = params.private(node.fqn)
    issue = _description_param(node, params, private)
    if issue:
        issues.append(issue)
    if "rate" in private:
        with contextlib.suppress(TypeError, ValueError):
            private["rate"] = float(private["rate"])
    if isinstance(private.get("source_list"), str):
        private["source_list"] = [private["source_list"]]
    for key in [k for k in private if k.startswith("dependent_joints.")]:
        params.notes.append(
            f"{node.source}: joint_state_publisher {node.fqn}: {key} is not supported (use "
            "<mimic> in the URDF)"
        )
        private.pop(key)
    executable = (
        "joint_state_publisher_gui" if node.pkg.endswith("_gui") else "joint_state_publisher"
    )
    return node.spec(executable, private), issues


def _static_transform_publisher(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    del packages
    params.private(node.fqn)  # tf's publisher reads none; mark them seen
    try:
        values = static_transform_params_from_args(node.args)
    except StaticTransformError as exc:
        return None, [f"node {node.fqn}: {exc}"]
    return node.spec("static_transform_publisher", values), []


def _parent(topic: str) -> str:
    head, sep, _ = topic.rpartition("/")
    if not sep:
        return ""
    return head or "/"


def _sibling(topic: str, name: str) -> str:
    parent = _parent(topic)
    if not parent:
        return name
    return f"{parent.rstrip('/')}/{name}"


def _depthimage_to_laserscan(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    del packages
    issues = _no_args(node)
    private = params.private(node.fqn)
    if "output_frame_id" in private:
        private["output_frame"] = private.pop("output_frame_id")
    ns = node.namespace.rstrip("/")

    def names(short: str) -> tuple[str, ...]:
        return (short, f"{ns}/{short}")

    image_target = next((b for a, b in node.remaps if a in names("image")), None)
    info_target = next((b for a, b in node.remaps if a in names("camera_info")), None)
    remaps: list[tuple[str, str]] = []
    for a, b in node.remaps:
        if a in names("image") or a in names("camera_info"):
            continue
        remaps.append((a, b))
    image = image_target or "image"
    info = info_target or _sibling(image, "camera_info")
    remaps = [("depth", image), ("depth_camera_info", info), *remaps]
    return node.spec("depthimage_to_laserscan", private, remaps=tuple(remaps)), issues


def _image_proc(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    del packages
    return node.spec("image_proc", params.private(node.fqn)), _no_args(node)


def _rviz_fixed_frame(config: str) -> str | None:
    try:
        data = load_yaml_file(config, what="the RViz config")
    except YamlError:
        return None
    with contextlib.suppress(KeyError, TypeError):
        frame = data["Visualization Manager"]["Global Options"]["Fixed Frame"]
        return str(frame) if frame else None
    return None


def _rviz(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    if importlib.util.find_spec("rerun") is None:
        params.private(node.fqn)
        params.notes.append(
            f"{node.source}: rviz {node.fqn} is skipped: visnav's viewer needs rerun-sdk "
            "(pip install 'visnav[viz]'); `visnav view` shows a recorded bag the same way"
        )
        return None, []
    issues: list[str] = []
    out: dict[str, Any] = params.private(node.fqn)
    args = list(node.args)
    i = 0
    while i < len(args):
        flag = args[i]
        value = args[i + 1] if i + 1 < len(args) else None
        if flag in ("-d", "--display-config") and value is not None:
            out["config"] = value
            if not Path(value).is_file():
                params.notes.append(
                    f"{node.source}: rviz {node.fqn}: config {value} does not exist; the viewer "
                    "draws in the TF root frame"
                )
            frame = _rviz_fixed_frame(value)
            if frame is not None:
                out.setdefault("fixed_frame", frame)
        elif flag in ("-f", "--fixed-frame") and value is not None:
            out["fixed_frame"] = value
        else:
            issues.append(
                f"rviz {node.fqn}: arguments {args[i:]} are not mapped (only -d CONFIG, -f FRAME)"
            )
            break
        i += 2
    known = [f"{k}={v}" for k, v in sorted(packages.items()) if "://" not in str(v)]
    if known:  # the robot model's package:// meshes
        out.setdefault("packages", known)
    return node.spec("viz", out), issues


NODE_TRANSLATORS: Mapping[
    tuple[str, str], Callable[[RosNode, ParamServer, Mapping[str, str]], Translation]
] = {
    ("robot_state_publisher", "robot_state_publisher"): _robot_state_publisher,
    ("robot_state_publisher", "state_publisher"): _robot_state_publisher,
    ("joint_state_publisher", "joint_state_publisher"): _joint_state_publisher,
    ("joint_state_publisher_gui", "joint_state_publisher_gui"): _joint_state_publisher,
    ("tf2_ros", "static_transform_publisher"): _static_transform_publisher,
    ("tf", "static_transform_publisher"): _static_transform_publisher,
    ("depthimage_to_laserscan", "depthimage_to_laserscan"): _depthimage_to_laserscan,
    ("image_proc", "image_proc"): _image_proc,
    ("rviz", "rviz"): _rviz,
    **GAZEBO_TRANSLATORS,  # gazebo_ros spawn_model (visnav.launch.ros_gazebo)
    **CONTROLLER_TRANSLATORS,  # controller_manager spawner / controller_manager / unspawner
}


def translate_node(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    """Map one roslaunch node; return the visnav node (None if impossible) and the problems.

    Args:
        node: the node as roslaunch resolved it.
        params: the parameter server after the whole file was loaded.
        packages: package directories known to the import (for the simulator's meshes).
    """
    from visnav.launch.ros_nav_nodes import NAV_TRANSLATORS  # noqa: PLC0415 (cycle)
    from visnav.launch.ros_planner_nodes import PLANNER_TRANSLATORS  # noqa: PLC0415 (cycle)

    key = (node.pkg, node.type)
    translate = (
        NODE_TRANSLATORS.get(key) or PLANNER_TRANSLATORS.get(key) or NAV_TRANSLATORS.get(key)
    )
    if translate is None:
        return None, [
            f"<node pkg={node.pkg!r} type={node.type!r}> ({node.fqn}) has no visnav counterpart"
        ]
    return translate(node, params, packages)
