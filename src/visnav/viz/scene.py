"""Which world to draw: from the simulator node's parameters (live) or a run's files (bag).

The viewer draws the world the simulator built (RViz shows no world; Gazebo's window does).
Live, :func:`world_from_graph` asks the simulator node (``sim``, or ``gazebo`` in the
TurtleBot3 scenarios: the ``/clock`` publisher) for its ``world``, ``world_params``,
``seed`` and ``packages`` parameters (the parameter services, as ``visnav param get``)
and loads the same world from its description (no MuJoCo). For a bag of ``visnav run``,
:func:`world_for_bag` reads the run's ``summary.json`` beside the bag (its ``scenario``
and ``seed``) and the scenario's world.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from visnav.description.urdf_model import find_package
from visnav.description.world import load_world
from visnav.description.worldmodel import WorldDescription
from visnav.graph.errors import ServiceError
from visnav.graph.node import Node
from visnav.graph.param_client import ParameterClient
from visnav.safe_yaml import load_yaml
from visnav.viz.errors import VizError

__all__ = [
    "SCENARIO_WORLDS",
    "find_sim_node",
    "load_sim_world",
    "world_for_bag",
    "world_from_graph",
]

_LOG = logging.getLogger("visnav.viz")

SCENARIO_WORLDS: dict[str, str] = {
    "car": "office",
    "car-slam": "office",
    "drone": "forest",
    "tb3-nav": "package://turtlebot3_gazebo/worlds/turtlebot3_world.world",
    "tb3-slam": "package://turtlebot3_gazebo/worlds/turtlebot3_world.world",
}
"""The world of each built-in scenario (what its launch file gives the ``sim`` node): a
built-in world or ``package://PKG/PATH``, found on ``ROS_PACKAGE_PATH``."""

_SIM_NODE_NAMES = ("sim", "gazebo")
_PARAM_ATTEMPTS = 3


def load_sim_world(
    world: str,
    *,
    world_params: Sequence[str] = (),
    seed: int = -1,
    packages: Sequence[str] = (),
) -> WorldDescription:
    """Load a world as the ``sim`` node does from its parameters.

    Args:
        world: built-in world name or world file.
        world_params: ``name:=value`` items (YAML values).
        seed: the world seed (-1: the world's own).
        packages: ``name=DIR`` package directories.

    Raises:
        WorldError: the world does not load.
        VizError: a malformed ``world_params`` item.
    """
    params: dict[str, Any] = {}
    for item in world_params:
        if not str(item):
            continue
        name, sep, text = str(item).partition(":=")
        if not sep:
            text_ = f"world_params item {item!r} is not name:=value"
            raise VizError(text_)
        params[name.strip()] = load_yaml(text, source=f"world_params {name}", what="the value")
    dirs: dict[str, str] = {}
    for item in packages:
        name, sep, folder = str(item).partition("=")
        if sep and name and folder:
            dirs[name] = folder
    return load_world(
        world,
        params=params or None,
        seed=None if seed < 0 else seed,
        packages=dirs or None,
        skip_missing_models=True,
    )


def find_sim_node(node: Node, *, name: str | None = None) -> str | None:
    """The fully qualified name of the graph's simulator node, None if there is none.

    The simulator is the node that publishes ``/clock`` and serves parameters (the
    built-in scenarios name it ``sim``, the TurtleBot3 ones ``gazebo``, as
    ``turtlebot3_world.launch`` does); failing that, a node called ``sim`` or ``gazebo``.

    Args:
        node: the node that asks.
        name: only a node of this name (any namespace).
    """
    names = sorted(node.get_node_names_and_namespaces())
    if name is not None:
        wanted: tuple[str, ...] = (name,)
    else:
        for endpoint in node.get_publishers_info_by_topic("/clock"):
            if not endpoint.node_name.startswith("_"):  # hidden nodes (bridges, tools)
                return f"{endpoint.node_namespace.rstrip('/')}/{endpoint.node_name}"
        wanted = _SIM_NODE_NAMES
    for wanted_name in wanted:
        for node_name, namespace in names:
            if node_name == wanted_name:
                return f"{namespace.rstrip('/')}/{node_name}"
    return None


def world_from_graph(
    node: Node, *, sim_node: str | None = None, timeout_s: float = 5.0, wait_s: float = 5.0
) -> WorldDescription | None:
    """The world of the graph's simulator node, None when there is no such node.

    The simulator node is found by :func:`find_sim_node`. Blocks for up to ``wait_s``
    (for the node to appear) plus ``timeout_s`` per call (the parameters are asked for
    up to three times): call it off the thread that spins the simulator node (the
    :class:`~visnav.viz.display_sink.DisplaySink` worker does).

    Args:
        node: the node that asks.
        sim_node: the simulator node's full name (default: :func:`find_sim_node`).
        timeout_s: each parameter call's timeout.
        wait_s: how long to wait for a simulator node to appear in the graph.
    """
    deadline = time.monotonic() + wait_s
    target = sim_node
    while target is None:
        target = find_sim_node(node)
        if target is None:
            if time.monotonic() >= deadline:
                _LOG.debug("viewer: no sim node in the graph: no world geometry")
                return None
            time.sleep(0.2)
    client = ParameterClient(node, target, timeout_sec=timeout_s)
    try:
        if not client.wait_for_services(timeout_s):
            _LOG.debug("viewer: %s serves no parameters: no world geometry", target)
            return None
        for attempt in range(1, _PARAM_ATTEMPTS + 1):  # a loaded machine answers late
            try:
                world, world_params, seed, packages = client.get_parameters(
                    ["world", "world_params", "seed", "packages"]
                )
                break
            except ServiceError:
                if attempt == _PARAM_ATTEMPTS:
                    raise
                _LOG.debug("viewer: %s's parameters: no answer yet, asking again", target)
    finally:
        client.close()
    if not world:
        return None
    return load_sim_world(
        str(world),
        world_params=list(world_params or ()),
        seed=int(seed) if seed is not None else -1,
        packages=list(packages or ()),
    )


def world_for_bag(
    bag: str | Path, *, worlds: Mapping[str, str] | None = None
) -> WorldDescription | None:
    """The world of a ``visnav run`` bag (its ``summary.json``), None if not known."""
    path = Path(bag)
    for folder in (path.parent, path.parent.parent) if path.is_file() else (path.parent, path):
        summary = folder / "summary.json"
        if not summary.is_file():
            continue
        try:
            data = json.loads(summary.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            return None
        name = (worlds or SCENARIO_WORLDS).get(str(data.get("scenario", "")))
        if name is None:
            return None
        seed = data.get("seed")
        packages: list[str] = []
        if name.startswith("package://"):
            package, _, rest = name[len("package://") :].partition("/")
            share = find_package(package, base_dir=None)
            if share is None:
                _LOG.warning(
                    "viewer: %s's world %s: package %s is not on ROS_PACKAGE_PATH: no world "
                    "geometry (or give --world FILE)",
                    path,
                    name,
                    package,
                )
                return None
            name = str(share / rest)
            packages.append(f"{package}={share}")
        return load_sim_world(
            name, seed=int(seed) if isinstance(seed, int) else -1, packages=packages
        )
    return None
