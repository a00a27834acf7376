"""Which world to draw: from the simulator node's parameters (live) or a run's files (bag).

The viewer draws the world the simulator built (RViz shows no world; Gazebo's window does).
Live, :func:`world_from_graph` asks the ``sim`` node for its ``world``, ``world_params``,
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

from visnav.description.world import load_world
from visnav.description.worldmodel import WorldDescription
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
    "tb3-nav": "turtlebot3_world",
    "tb3-slam": "turtlebot3_world",
}
"""The world of each built-in scenario (what its launch file gives the ``sim`` node)."""


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


def find_sim_node(node: Node, *, name: str = "sim") -> str | None:
    """The fully qualified name of the graph's node called ``name`` (any namespace)."""
    for node_name, namespace in sorted(node.get_node_names_and_namespaces()):
        if node_name == name:
            return f"{namespace.rstrip('/')}/{node_name}"
    return None


def world_from_graph(
    node: Node, *, sim_node: str | None = None, timeout_s: float = 5.0, wait_s: float = 5.0
) -> WorldDescription | None:
    """The world of the graph's simulator node, None when there is no such node.

    Blocks for up to ``wait_s`` (for the node to appear) plus ``timeout_s`` per call:
    call it off the thread that spins the simulator node (the
    :class:`~visnav.viz.display_sink.DisplaySink` worker does).

    Args:
        node: the node that asks.
        sim_node: the simulator node's full name (default: the node named ``sim``).
        timeout_s: each parameter call's timeout.
        wait_s: how long to wait for a ``sim`` node to appear in the graph.
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
        world, world_params, seed, packages = client.get_parameters(
            ["world", "world_params", "seed", "packages"]
        )
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
        return load_sim_world(name, seed=int(seed) if isinstance(seed, int) else -1)
    return None
