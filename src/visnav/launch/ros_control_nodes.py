"""roslaunch's ``controller_manager`` nodes: spawned ros_control controllers go to the sim.

gazebo_ros_control runs the controller manager inside Gazebo; a launch file loads the
controllers' configuration with ``<rosparam command="load">`` and starts them with

* ``<node pkg="controller_manager" type="spawner" args="[--stopped] [--namespace NS]
  [--timeout T] [--no-timeout] [--shutdown-timeout T] [--wait-for TOPIC] NAME ...">``, or
* ``<node pkg="controller_manager" type="controller_manager" args="spawn|load|start NAME ...">``.

visnav's simulator builds the robot's controller manager when the simulation is built, so
these nodes are folded into the ``sim`` node (as ``spawn_model`` is): its parameter
``controllers`` lists the started controllers and ``stopped_controllers`` the loaded ones
(``--stopped``, ``load``), each as its name relative to the root (``NAME`` for a spawner in
``/``, ``ns/NAME`` in ``/ns``), and every parameter under ``<ns>/<NAME>`` of the launch's
parameter server becomes the sim node's parameter ``<ns>.<NAME>.<a>.<b>`` (see
:mod:`visnav.sim.ros_control`). ``unspawner`` and ``--shutdown-timeout`` only act at
shutdown: they are notes. Anything else is an import problem naming it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from visnav.graph.parameters import ParameterType
from visnav.launch.description import NodeSpec
from visnav.launch.errors import RoslaunchImportError

if TYPE_CHECKING:
    from visnav.launch.ros_nodes import ParamServer, RosNode, Translation

__all__ = ["CONTROLLER_TRANSLATORS", "fold_controller_spawners"]

_EXECUTABLE = "controller_manager/spawner"  # never started: folded into the sim node
_FLAGS_WITH_VALUE = ("--namespace", "--timeout", "--shutdown-timeout", "--wait-for")
_FLAGS = ("--stopped", "--no-timeout", "-h", "--help", *_FLAGS_WITH_VALUE)


def _join(*parts: str) -> str:
    pieces = [p.strip("/") for p in parts if p.strip("/")]
    return "/" + "/".join(pieces)


def _split_flag(arg: str) -> tuple[str, str | None]:
    flag, sep, value = arg.partition("=")
    return flag, (value if sep else None)


def _controller_params(
    node: RosNode, params: ParamServer, entry: str, notes: list[str]
) -> dict[str, Any]:
    out: dict[str, Any] = {}
    prefix = entry.replace("/", ".")
    for key, value in params.private("/" + entry).items():
        try:
            ParameterType.from_value(value)
        except Exception:  # noqa: BLE001 (a list of mappings, ...: not a parameter value)
            notes.append(
                f"{node.source}: controller {entry}: parameter /{entry}/{key.replace('.', '/')} "
                f"({type(value).__name__}) is not passed to the simulator"
            )
            continue
        out[f"{prefix}.{key}"] = value
    return out


def _spawner(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    """``controller_manager spawner``: started (or ``--stopped``) controllers."""
    del packages
    issues: list[str] = []
    notes: list[str] = []
    names: list[str] = []
    stopped = False
    namespace = node.namespace
    args = list(node.args)
    i = 0
    while i < len(args):
        flag, value = _split_flag(args[i])
        if not flag.startswith("-"):
            names.append(args[i])
            i += 1
            continue
        if flag not in _FLAGS:
            issues.append(
                f"spawner {node.fqn}: option {flag!r} is not mapped (it takes "
                f"{', '.join(_FLAGS)} and controller names)"
            )
            i += 1
            continue
        if flag in _FLAGS_WITH_VALUE and value is None:
            value = args[i + 1] if i + 1 < len(args) else None
            i += 1
            if value is None:
                issues.append(f"spawner {node.fqn}: {flag} needs a value")
                break
        i += 1
        if flag == "--stopped":
            stopped = True
        elif flag == "--namespace" and value is not None:
            namespace = value if value.startswith("/") else _join(node.namespace, value)
        elif flag in ("--shutdown-timeout", "--wait-for"):
            notes.append(
                f"{node.source}: spawner {node.fqn}: {flag} {value} ignored (the controllers "
                "start with the simulation and stop with it)"
            )
    return _spawned(node, params, names, namespace, stopped=stopped, issues=issues, notes=notes)


def _controller_manager(
    node: RosNode, params: ParamServer, packages: Mapping[str, str]
) -> Translation:
    """``controller_manager controller_manager spawn|load|start NAME ...``."""
    del packages
    args = list(node.args)
    command = args[0] if args else ""
    if command not in ("spawn", "load", "start"):
        params.private(node.fqn)
        return None, [
            f"controller_manager {node.fqn}: command {command or '(none)'!r} is not mapped "
            "(spawn, load and start are: the controllers start with the simulation)"
        ]
    return _spawned(
        node, params, args[1:], node.namespace, stopped=command == "load", issues=[], notes=[]
    )


def _unspawner(node: RosNode, params: ParamServer, packages: Mapping[str, str]) -> Translation:
    """``controller_manager unspawner``: acts at shutdown only, a note."""
    del packages
    params.private(node.fqn)
    params.notes.append(
        f"{node.source}: unspawner {node.fqn} is left out: visnav's controllers stop with the "
        "simulation"
    )
    return None, []


def _spawned(
    node: RosNode,
    params: ParamServer,
    names: list[str],
    namespace: str,
    *,
    stopped: bool,
    issues: list[str],
    notes: list[str],
) -> Translation:
    params.private(node.fqn)
    if not names:
        issues.append(f"{node.type} {node.fqn}: no controller names in args {list(node.args)}")
    entries = [_join(namespace, n).lstrip("/") for n in names]
    out: dict[str, Any] = {"stopped_controllers" if stopped else "controllers": entries}
    for entry in entries:
        if params.get(f"/{entry}/type") is None:
            issues.append(
                f"{node.type} {node.fqn}: controller {entry!r} has no /{entry}/type parameter: "
                'load its configuration (<rosparam command="load" file="...yaml"/>) in this '
                "launch file"
            )
        out.update(_controller_params(node, params, entry, notes))
    params.notes.extend(notes)
    return node.spec(_EXECUTABLE, out), issues


CONTROLLER_TRANSLATORS: Mapping[
    tuple[str, str], Callable[[RosNode, ParamServer, Mapping[str, str]], Translation]
] = {
    ("controller_manager", "spawner"): _spawner,
    ("controller_manager", "controller_manager"): _controller_manager,
    ("controller_manager", "unspawner"): _unspawner,
}
"""roslaunch ``(pkg, type)`` -> translator, merged into the roslaunch import's table."""


def fold_controller_spawners(nodes: list[NodeSpec], notes: list[str]) -> list[NodeSpec]:
    """Give the spawned controllers (and their parameters) to the one sim node.

    Raises:
        RoslaunchImportError: spawners without exactly one simulator node, or one
            controller spawned twice.
    """
    spawners = [n for n in nodes if n.executable == _EXECUTABLE]
    if not spawners:
        return nodes
    where = ", ".join(f"{n.source}: {n.namespace.rstrip('/')}/{n.name}" for n in spawners)
    sims = [n for n in nodes if n.executable == "sim"]
    if len(sims) != 1:
        msg = (
            f"controller_manager spawner ({where}): the controllers run in the simulator's "
            f"controller manager (gazebo_ros_control), so a spawner needs exactly one simulator "
            f"in the launch (found {len(sims)} gazebo / sim nodes). Fix: include "
            "$(find gazebo_ros)/launch/empty_world.launch and spawn the robot with spawn_model"
        )
        raise RoslaunchImportError(msg)
    sim = sims[0]
    params = dict(sim.params)
    seen: dict[str, str] = {}
    for spawner in spawners:
        for key, value in spawner.params.items():
            if key in ("controllers", "stopped_controllers"):
                for entry in value:
                    if entry in seen:
                        msg = (
                            f"controller {entry!r} is spawned twice ({seen[entry]} and "
                            f"{spawner.source}): ros_control refuses to load a second "
                            "controller of the same name. Fix: spawn it once"
                        )
                        raise RoslaunchImportError(msg)
                    seen[entry] = spawner.source
                params[key] = [*params.get(key, []), *value]
            else:
                params[key] = value
    notes.append(
        f"controller_manager spawner ({where}) is folded into the sim node "
        f"{sim.namespace.rstrip('/')}/{sim.name}: its controllers "
        f"({', '.join(seen)}) start with the simulation"
    )
    folded = replace(sim, params=params)
    out: list[NodeSpec] = []
    for n in nodes:
        if n.executable == _EXECUTABLE:
            continue
        out.append(folded if n is sim else n)
    return out
