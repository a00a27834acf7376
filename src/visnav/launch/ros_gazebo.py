"""Gazebo in a roslaunch file: ``empty_world.launch`` and ``spawn_model`` as the ``sim`` node.

=============================================  ============================================
roslaunch                                      visnav
=============================================  ============================================
``gazebo_ros/launch/empty_world.launch``       ``sim`` named ``gazebo``: ``world_name`` ->
                                               ``world``; ``/use_sim_time``; the other args
                                               (``paused`` too) noted when not Gazebo's default
``gazebo_ros spawn_model``                     folded into the ``sim`` node: ``-urdf``,
                                               ``-param P`` or ``-file F``, ``-model``,
                                               ``-x -y -z -Y``, ``-robot_namespace``;
                                               ``-R -P -J``, ``-unpause``, ``-b``, ``-wait``,
                                               ``-package_to_model``, ``-gazebo_namespace``
                                               noted as ignored; ``-database``, ``-stdin``,
                                               ``-sdf``, another ``-reference_frame`` refused
=============================================  ============================================

Gazebo spawns robots into a running world; visnav's simulator composes the MuJoCo model
once, so :func:`fold_spawns` gives the spawned robot to the ``sim`` node. As gazebo_ros's
spawn service does, every ROS 1 ``<plugin>`` of the spawned URDF without a
``<robotNamespace>`` gets the spawner's namespace (``spawn_model``'s ``-robot_namespace``
defaults to its node's namespace, ``/``), so a plugin's default namespace is the spawner's,
not the model's name (a ``gazebo_ros_control`` without ``<robotNamespace>`` serves its
controllers in ``/``).
"""

from __future__ import annotations

import difflib
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from visnav.launch.description import NodeSpec
from visnav.launch.errors import RoslaunchImportError
from visnav.launch.ros_control_nodes import fold_controller_spawners
from visnav.launch.substitutions import VIRTUAL_PACKAGES
from visnav.textfile import TextFileError, read_text

if TYPE_CHECKING:
    from visnav.launch.ros_nodes import ParamServer, RosNode, Translation

__all__ = [
    "EMPTY_WORLD_ARGS",
    "GAZEBO_TRANSLATORS",
    "add_plugin_namespaces",
    "empty_world_node",
    "fold_spawns",
]


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
    "-database",
    "-package_to_model",
    "-b",
    "-wait",
)
# spawn_model options with no effect in visnav: (takes a value, why)
_SPAWN_IGNORED = {
    "-package_to_model": (False, "visnav resolves package:// URIs itself"),
    "-b": (False, "there is no bond: the robot lives as long as the simulation"),
    "-wait": (True, "the world and its models are built together, before the first step"),
}
_SPAWN_REFUSED = {
    "-database": (
        "visnav has no Gazebo model database: give the model as -file MODEL.sdf / -urdf "
        "-param robot_description, or put it in the world file"
    ),
    "-stdin": "the model cannot be read from standard input: give -file FILE or -param NAME",
    "-trimesh": "Gazebo 1's mesh spawning is not supported: give -urdf or -sdf",
    "-gazebo": "Gazebo 1's XML is not supported: give -urdf or -sdf",
}


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
        if flag in _SPAWN_REFUSED:
            issues.append(f"spawn_model {node.fqn}: {flag}: {_SPAWN_REFUSED[flag]}")
            i += 2 if flag == "-database" else 1
            continue
        if flag in _SPAWN_IGNORED:
            takes_value, why = _SPAWN_IGNORED[flag]
            shown = f"{flag} {value}" if takes_value and value is not None else flag
            params.notes.append(f"{node.source}: spawn_model {node.fqn}: {shown} ignored: {why}")
            i += 2 if takes_value else 1
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
    refused = any(f"{flag}:" in t for t in issues for flag in _SPAWN_REFUSED)
    if source is None and not refused and not any("-param" in t or "-file" in t for t in issues):
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


GAZEBO_TRANSLATORS: Mapping[
    tuple[str, str], Callable[[RosNode, ParamServer, Mapping[str, str]], Translation]
] = {("gazebo_ros", "spawn_model"): _spawn_model}
"""The gazebo_ros nodes (spawn_model); :func:`visnav.launch.ros_nodes.translate_node` uses it."""


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
    if _bool(args["paused"]):
        notes.append(
            f"{source}: empty_world paused:=true is ignored: visnav's simulation starts running "
            "(it has no paused start and no /gazebo/unpause_physics service)"
        )
    if world is None:
        return None, issues, notes
    sim_params: dict[str, Any] = {"world": world}
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


def add_plugin_namespaces(urdf: str, namespace: str) -> str:
    """``urdf`` with ``<robotNamespace>namespace</robotNamespace>`` in each ROS 1 plugin lacking it.

    gazebo_ros_api_plugin's ``walkChildAddRobotNamespace``, which the spawn service applies to
    the spawned model: ROS 2 plugins (with a ``<ros>`` block) and visnav's own plugins keep
    their XML. Text that does not parse is returned as it is (the simulator then reports it).
    """
    try:
        root = ET.fromstring(urdf)  # noqa: S314 - the launch file's robot description
    except ET.ParseError:
        return urdf
    changed = False
    for plugin in root.iter("plugin"):
        filename = plugin.get("filename") or ""
        if filename.startswith("libvisnav_") or plugin.find("ros") is not None:
            continue
        if plugin.find("robotNamespace") is None:
            ET.SubElement(plugin, "robotNamespace").text = namespace
            changed = True
    return ET.tostring(root, encoding="unicode") if changed else urdf


def fold_spawns(nodes: list[NodeSpec], notes: list[str]) -> list[NodeSpec]:
    """Give spawn_model's robot to the sim node (visnav builds the world and robot together).

    Gazebo spawns robots into a running world; visnav's simulator composes the MuJoCo
    model once, so a launch file's ``spawn_model`` becomes the ``sim`` node's ``robot``
    (URDF text), ``spawn``, ``robot_namespace`` and ``packages``. The simulator publishes
    the robot's state itself, so an imported ``robot_state_publisher`` and
    ``joint_state_publisher`` are then left out (each with a note).

    Raises:
        RoslaunchImportError: spawn_model nodes that cannot be folded (not exactly one
            simulator and one spawned URDF): visnav has no spawn_model node.
    """
    nodes = fold_controller_spawners(nodes, notes)  # ros_control: spawned controllers
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
    name = f"{spawn.namespace.rstrip('/')}/{spawn.name}"
    if p.get("format") == "sdf":
        msg = (
            f"spawn_model {name} ({spawn.source}): -sdf: visnav spawns URDF robots only. Fix: "
            "spawn the robot with -urdf, and put SDF models into the world file "
            "(<include><uri>model://NAME</uri></include>)"
        )
        raise RoslaunchImportError(msg)
    reference = str(p.get("reference_frame", "") or "")
    if reference not in ("", "world", "map"):
        msg = (
            f"spawn_model {name} ({spawn.source}): -reference_frame {reference}: visnav places "
            "a spawned robot in the world frame only. Fix: give -x -y -z -Y in world coordinates"
        )
        raise RoslaunchImportError(msg)
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
    else:
        params["robot"] = add_plugin_namespaces(params["robot"], spawn.namespace)
    if p.get("packages") and "packages" not in params:
        params["packages"] = list(p["packages"])
    ignored = [f"-{axis} {p[axis]}" for axis in ("R", "P") if float(p.get(axis, 0.0)) != 0.0]
    if ignored:
        ignored[-1] += " (visnav spawns a robot upright: roll and pitch are dropped)"
    if p.get("initial_joint_names"):
        joints = ", ".join(
            f"{j}={q}"
            for j, q in zip(p["initial_joint_names"], p["initial_joint_positions"], strict=True)
        )
        ignored.append(f"-J {joints} (joints start at 0)")
    if str(p.get("gazebo_namespace", "/gazebo") or "/gazebo") != "/gazebo":
        ignored.append(f"-gazebo_namespace {p['gazebo_namespace']}")
    folded = replace(sim, params=params)
    notes.append(
        f"spawn_model {name} ({spawn.source}) is folded into the sim node "
        f"{sim.namespace.rstrip('/')}/{sim.name}: visnav builds world and robot together"
        + (f"; ignored: {', '.join(ignored)}" if ignored else "")
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
        if n.executable in ("joint_state_publisher", "joint_state_publisher_gui"):
            notes.append(
                f"{n.executable} {n.namespace.rstrip('/')}/{n.name} ({n.source}) is left out: "
                "the sim moves the spawned robot's joints and publishes their /tf itself "
                "(zeros on joint_states would contradict its joint state plugins)"
            )
            continue
        out.append(folded if n is sim else n)
    return out
