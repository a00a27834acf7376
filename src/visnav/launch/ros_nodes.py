"""How ROS 1 nodes of a roslaunch file become visnav nodes.

=============================================  ============================================
roslaunch                                      visnav
=============================================  ============================================
``robot_state_publisher``                      ``robot_state_publisher``: ``robot_description``
                                               found as roscpp's ``searchParam`` finds it;
                                               ``tf_prefix`` -> ``frame_prefix``
``tf2_ros`` / ``tf``                           ``static_transform_publisher`` (args -> params;
``static_transform_publisher``                 tf's period is dropped: ``/tf_static`` latches)
``gazebo_ros spawn_model``                     ``spawn_model``: ``-urdf|-sdf``, ``-param P`` or
                                               ``-file F``, ``-model``, ``-x -y -z -R -P -Y``,
                                               ``-robot_namespace``, ``-reference_frame``,
                                               ``-unpause``, ``-J joint value``
``depthimage_to_laserscan``                    ``depthimage_to_laserscan``: topic ``image`` ->
                                               ``depth``, its sibling ``camera_info`` ->
                                               ``depth_camera_info`` (image_transport's rule);
                                               ``output_frame_id`` -> ``output_frame``
``image_proc``                                 ``image_proc`` (same topics)
``rviz``                                       ``viz`` (the viewer): ``-d CONFIG`` (its fixed
                                               frame is read), ``-f FRAME``
``gazebo_ros/launch/empty_world.launch``       ``sim`` named ``gazebo``: ``world_name`` ->
                                               ``world``, ``paused``; ``/use_sim_time``
=============================================  ============================================

ego-planner's nodes (``ego_planner_node``, ``traj_server``, ``waypoint_generator``) and the
camera drivers (``usb_cam``, ``cv_camera``) are mapped in :mod:`visnav.launch.ros_planner_nodes`.

Private parameters (``<param>`` inside ``<node>``, ``~name``) become the node's
parameters; nested names (``a/b``) become ROS 2's ``a.b``. A node with
``respawn="true"`` runs in its own process; the others share one.
"""

from __future__ import annotations

import contextlib
import difflib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from visnav.launch.description import NodeSpec
from visnav.launch.errors import RoslaunchImportError
from visnav.launch.substitutions import VIRTUAL_PACKAGES
from visnav.safe_yaml import YamlError, load_yaml_file
from visnav.textfile import TextFileError, read_text
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
    "YAML launch files, and <node> of robot_state_publisher, tf2_ros or tf "
    "static_transform_publisher, gazebo_ros spawn_model, depthimage_to_laserscan, image_proc, "
    "rviz (-> the viz node), ego_planner ego_planner_node and traj_server, waypoint_generator "
    "(folded into the planner), usb_cam usb_cam_node, cv_camera cv_camera_node. ROS 2 launch "
    "files (Python or XML) are out of scope: write a visnav "
    "YAML launch file (docs/launch.md)"
)

# gazebo_ros empty_world.launch (Noetic) and its defaults.
EMPTY_WORLD_ARGS: Mapping[str, str] = {
    "paused": "false",
    "use_sim_time": "true",
    "extra_gazebo_args": "",
    "gui": "true",
    "recording": "false",
    "headless": "false",
    "debug": "false",
    "physics": "ode",
    "verbose": "false",
    "output": "screen",
    "world_name": "worlds/empty.world",
    "respawn_gazebo": "false",
    "use_clock_frequency": "false",
    "pub_clock_frequency": "100",
    "enable_ros_network": "true",
    "server_required": "false",
    "gui_required": "false",
}
_EMPTY_WORLDS = ("worlds/empty.world", "worlds/empty_sky.world", "")
_WORLD_SUFFIXES = (".world", ".sdf", ".yaml", ".yml")


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
            "process": "own" if self.respawn else "shared",
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


def _robot_state_publisher(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    del packages
    issues = _no_args(node)
    private = params.private(node.fqn)
    prefix = private.pop("tf_prefix", None)
    if prefix:
        private["frame_prefix"] = str(prefix).strip("/") + "/"
    if "robot_description" not in private:
        found = params.search(node.namespace, "robot_description")
        if found is None:
            issues.append(
                f"robot_state_publisher {node.fqn} needs a robot_description parameter: set "
                '<param name="robot_description" command="$(find xacro)/xacro FILE"/>'
            )
        else:
            private["robot_description"] = params.get(found)
    return node.spec("robot_state_publisher", private), issues


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


_SPAWN_FLOATS = {"-x": "x", "-y": "y", "-z": "z", "-R": "R", "-P": "P", "-Y": "Y"}
_SPAWN_STRINGS = {
    "-model": "model",
    "-robot_namespace": "robot_namespace",
    "-reference_frame": "reference_frame",
    "-gazebo_namespace": "gazebo_namespace",
}

_SPAWN_OPTIONS = (
    *_SPAWN_FLOATS,
    *_SPAWN_STRINGS,
    "-param",
    "-file",
    "-J",
    "-urdf",
    "-sdf",
    "-unpause",
)


def _spawn_model(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    issues: list[str] = []
    out: dict[str, Any] = {"format": "urdf"}
    joint_names: list[str] = []
    joint_positions: list[float] = []
    source: str | None = None
    args = list(node.args)
    i = 0
    while i < len(args):
        flag = args[i]
        value = args[i + 1] if i + 1 < len(args) else None
        if flag in ("-urdf", "-sdf"):
            out["format"] = flag[1:]
            i += 1
            continue
        if flag == "-unpause":
            out["unpause"] = True
            i += 1
            continue
        if flag not in (*_SPAWN_FLOATS, *_SPAWN_STRINGS, "-param", "-file", "-J"):
            close = difflib.get_close_matches(flag, _SPAWN_OPTIONS, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            issues.append(f"spawn_model {node.fqn}: option {flag!r} is not mapped{hint}")
            # skip the unknown option's value too, if it has one
            i += 2 if value is not None and not value.startswith("-") else 1
            continue
        if value is None:
            issues.append(f"spawn_model {node.fqn}: {flag} needs a value")
            break
        if flag in _SPAWN_FLOATS:
            try:
                out[_SPAWN_FLOATS[flag]] = float(value)
            except ValueError:
                issues.append(f"spawn_model {node.fqn}: {flag} {value!r} is not a number")
        elif flag in _SPAWN_STRINGS:
            out[_SPAWN_STRINGS[flag]] = value
        elif flag == "-param":
            name = value if value.startswith("/") else f"{node.namespace.rstrip('/')}/{value}"
            text = params.get(name)
            if text is None:
                issues.append(
                    f"spawn_model {node.fqn}: -param {value}: parameter {name} is not set in "
                    "this launch file"
                )
            source = None if text is None else str(text)
        elif flag == "-file":
            try:
                source = read_text(value, what="the model file")
            except TextFileError as exc:
                issues.append(f"spawn_model {node.fqn}: -file: {exc}")
        elif flag == "-J":
            if i + 2 >= len(args):
                issues.append(f"spawn_model {node.fqn}: -J needs a joint name and a position")
                break
            try:
                joint_positions.append(float(args[i + 2]))
                joint_names.append(value)
            except ValueError:
                issues.append(f"spawn_model {node.fqn}: -J {value} {args[i + 2]!r} is not a number")
            i += 3
            continue
        i += 2
    if "model" not in out:
        issues.append(f"spawn_model {node.fqn}: -model NAME is required")
    if source is None and not any("-param" in t or "-file" in t for t in issues):
        issues.append(f"spawn_model {node.fqn}: give the robot with -param NAME or -file FILE")
    if source is not None:
        out["robot_description"] = source
    if joint_names:
        out["initial_joint_names"] = joint_names
        out["initial_joint_positions"] = joint_positions
    if packages:
        out["packages"] = [f"{k}={v}" for k, v in sorted(packages.items())]
    out.update(params.private(node.fqn))
    return node.spec("spawn_model", out), issues


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
    del packages
    issues: list[str] = []
    out: dict[str, Any] = params.private(node.fqn)
    args = list(node.args)
    i = 0
    while i < len(args):
        flag = args[i]
        value = args[i + 1] if i + 1 < len(args) else None
        if flag in ("-d", "--display-config") and value is not None:
            out["config"] = value
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
    return node.spec("viz", out), issues


NODE_TRANSLATORS: Mapping[
    tuple[str, str], Callable[[RosNode, ParamServer, Mapping[str, str]], Translation]
] = {
    ("robot_state_publisher", "robot_state_publisher"): _robot_state_publisher,
    ("robot_state_publisher", "state_publisher"): _robot_state_publisher,
    ("tf2_ros", "static_transform_publisher"): _static_transform_publisher,
    ("tf", "static_transform_publisher"): _static_transform_publisher,
    ("gazebo_ros", "spawn_model"): _spawn_model,
    ("depthimage_to_laserscan", "depthimage_to_laserscan"): _depthimage_to_laserscan,
    ("image_proc", "image_proc"): _image_proc,
    ("rviz", "rviz"): _rviz,
}


def translate_node(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    """Map one roslaunch node; return the visnav node (None if impossible) and the problems.

    Args:
        node: the node as roslaunch resolved it.
        params: the parameter server after the whole file was loaded.
        packages: package directories known to the import (for the simulator's meshes).
    """
    from visnav.launch.ros_planner_nodes import PLANNER_TRANSLATORS  # noqa: PLC0415 (cycle)

    key = (node.pkg, node.type)
    translate = NODE_TRANSLATORS.get(key) or PLANNER_TRANSLATORS.get(key)
    if translate is None:
        return None, [
            f"<node pkg={node.pkg!r} type={node.type!r}> ({node.fqn}) has no visnav counterpart"
        ]
    return translate(node, params, packages)


def _world(name: str) -> tuple[str | None, str | None]:
    """Map empty_world's ``world_name`` to the sim's ``world`` (value, or an issue)."""
    gazebo = VIRTUAL_PACKAGES["gazebo_ros"]
    if name in _EMPTY_WORLDS or name in (f"{gazebo}/{w}" for w in _EMPTY_WORLDS[:2]):
        return "empty", None
    if name.startswith(gazebo) or (name.startswith("worlds/") and not Path(name).is_file()):
        shown = name.replace(gazebo, "$(find gazebo_ros)")
        return None, (
            f"world_name {shown!r}: Gazebo's bundled worlds are not available in visnav (only "
            "worlds/empty.world); give an SDF .world file or a visnav world name (office, forest)"
        )
    if name.endswith(_WORLD_SUFFIXES) or "/" in name:
        path = Path(name)
        if not path.is_file():
            return None, f"world_name {name!r}: no such world file"
        return str(path.resolve()), None
    return name, None


def empty_world_node(
    args: Mapping[str, str], namespace: str, source: str, params: ParamServer
) -> tuple[NodeSpec | None, list[str], list[str]]:
    """The sim node that replaces gazebo_ros ``empty_world.launch``; sets ``/use_sim_time``.

    Returns:
        The node (None if the world cannot be mapped), problems, notes on what was ignored.
    """
    params.set("/use_sim_time", _bool(args["use_sim_time"]), source)
    world, issue = _world(args["world_name"])
    issues = [issue] if issue else []
    notes: list[str] = []
    if _bool(args["gui"]) and not _bool(args["headless"]):
        notes.append(
            f"{source}: empty_world gui:=true: Gazebo's client has no launch counterpart; watch "
            "with `visnav view` (an rviz node maps to the viz node)"
        )
    ignored = [
        f"{k}:={args[k]}"
        for k in ("debug", "verbose", "recording", "gui_required")
        if _bool(args[k])
    ]
    if args["extra_gazebo_args"].strip():
        ignored.append(f"extra_gazebo_args:={args['extra_gazebo_args']!r}")
    if args["physics"] != "ode":
        ignored.append(f"physics:={args['physics']} (visnav simulates with MuJoCo)")
    if not _bool(args["enable_ros_network"]):
        ignored.append("enable_ros_network:=false")
    if ignored:
        notes.append(f"{source}: empty_world args ignored: {', '.join(ignored)}")
    if world is None:
        return None, issues, notes
    sim_params: dict[str, Any] = {"world": world, "paused": _bool(args["paused"])}
    if _bool(args["use_clock_frequency"]):
        try:
            sim_params["pub_clock_frequency"] = float(args["pub_clock_frequency"])
        except ValueError:
            issues.append(f"pub_clock_frequency {args['pub_clock_frequency']!r} is not a number")
    respawn = _bool(args["respawn_gazebo"])
    spec = NodeSpec(
        executable="sim",
        name="gazebo",
        namespace=namespace,
        params=sim_params,
        process="own" if respawn else "shared",
        respawn=respawn,
        required=_bool(args["server_required"]),
        source=source,
    )
    return spec, issues, notes


def fold_spawns(nodes: list[NodeSpec], notes: list[str]) -> list[NodeSpec]:
    """Give spawn_model's robot to the sim node (visnav builds the world and robot together).

    Gazebo spawns robots into a running world; visnav's simulator composes the MuJoCo
    model once, so a launch file's ``spawn_model`` becomes the ``sim`` node's ``robot``
    (URDF text), ``spawn`` and ``robot_namespace``. The simulator publishes the robot's
    state itself, so an imported ``robot_state_publisher`` is then left out.

    Raises:
        RoslaunchImportError: spawn_model nodes that cannot be folded (not exactly one
            simulator and one spawned URDF): visnav has no spawn_model node.
    """
    sims = [n for n in nodes if n.executable == "sim"]
    spawns = [n for n in nodes if n.executable == "spawn_model"]
    if not spawns:
        return nodes
    if len(sims) != 1 or len(spawns) != 1 or "robot_description" not in spawns[0].params:
        where = ", ".join(f"{n.source}: {n.namespace.rstrip('/')}/{n.name}" for n in spawns)
        msg = (
            f"spawn_model ({where}): visnav builds the world and its robots together, so a "
            f"spawn_model needs exactly one simulator and one spawned URDF (found {len(sims)} "
            f"gazebo / sim node(s) and {len(spawns)} spawn_model node(s)). Fix: import a file "
            "with one gazebo_ros empty_world.launch and one spawn_model -urdf -param, or write "
            "a visnav launch file whose sim node lists the robots (params robot / robots)"
        )
        raise RoslaunchImportError(msg)
    sim, spawn = sims[0], spawns[0]
    p = spawn.params
    params = dict(sim.params)
    params["robot"] = str(p["robot_description"])
    params["spawn"] = [
        float(p.get("x", 0.0)),
        float(p.get("y", 0.0)),
        float(p.get("z", 0.0)),
        float(p.get("Y", 0.0)),
    ]
    if p.get("robot_namespace"):
        params["robot_namespace"] = str(p["robot_namespace"])
    folded = replace(sim, params=params)
    notes.append(
        f"spawn_model {spawn.namespace.rstrip('/')}/{spawn.name} ({spawn.source}) is folded into "
        f"the sim node {sim.namespace.rstrip('/')}/{sim.name}: visnav builds world and robot "
        "together"
    )
    out: list[NodeSpec] = []
    for n in nodes:
        if n is spawn:
            continue
        if n.executable == "robot_state_publisher":
            notes.append(
                f"robot_state_publisher {n.namespace.rstrip('/')}/{n.name} ({n.source}) is left "
                "out: the sim publishes the spawned robot's /tf and /tf_static"
            )
            continue
        out.append(folded if n is sim else n)
    return out
