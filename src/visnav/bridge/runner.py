"""Start the bridge: find (or serve) the master, open the ROS 1 node, keep the graphs in step.

:class:`Ros1BridgeNode` is the ``ros1_bridge`` built-in node of launch files; :func:`run_bridge`
is what ``visnav bridge ros1`` calls.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from visnav.bridge.bridge import BridgeOptions, Ros1Bridge
from visnav.bridge.master import Ros1Master
from visnav.bridge.master_api import master_uri_from_env, node_addresses
from visnav.bridge.ros1_node import Ros1Node
from visnav.graph import Context, Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["DEFAULT_NODE_NAME", "BridgeParams", "Ros1BridgeNode", "open_ros1_node", "run_bridge"]

DEFAULT_NODE_NAME = "visnav_bridge"
_log = logging.getLogger("visnav.bridge")


def open_ros1_node(
    name: str = DEFAULT_NODE_NAME,
    *,
    master_uri: str | None = None,
    env: Mapping[str, str] | None = None,
    on_shutdown: Any = None,
    on_demand: Any = None,
) -> Ros1Node:
    """Open a ROS 1 node on the master of ``ROS_MASTER_URI`` (or ``master_uri``) and start it.

    Raises:
        MasterUnreachableError: no master answers (the message says how to start one).
        BridgeError: ``ROS_MASTER_URI`` is malformed, or ``ROS_IP`` / ``ROS_HOSTNAME`` is
            not an address of this machine.
    """
    env = os.environ if env is None else env
    uri = master_uri or master_uri_from_env(env)
    host, bind = node_addresses(uri, env)
    node = Ros1Node(
        name,
        master_uri=uri,
        host=host,
        bind=bind,
        on_shutdown=on_shutdown,
        on_demand=on_demand,
    )
    try:
        node.master.ping()
    except Exception:
        node.close()
        raise
    node.start()
    return node


@dataclass(frozen=True)
class BridgeParams:
    """The ``ros1_bridge`` node's parameters (read once at start).

    ``topics``, ``exclude``, ``services`` and ``actions`` default to ``[""]``, a typed
    placeholder for "none given".
    """

    topics: tuple[str, ...] = param(("",), description="shell-style topic patterns to bridge")
    exclude: tuple[str, ...] = param(
        ("",), description="shell-style patterns of topics, services and actions to leave out"
    )
    services: tuple[str, ...] = param(("",), description="shell-style service patterns to bridge")
    actions: tuple[str, ...] = param(
        ("",), description="shell-style patterns of actions offered as actionlib servers"
    )
    ros1_node_name: str = param(DEFAULT_NODE_NAME, description="the bridge's ROS 1 node name")
    master_uri: str = param("", description="ROS 1 master ('': ROS_MASTER_URI)")
    serve_master_port: int = param(
        0, description="0: use a running master; a port: serve one on 127.0.0.1", range=(0, 65535)
    )


class Ros1BridgeNode(Node):
    """The ``ros1_bridge`` node: bridges this visnav graph with the ROS 1 graph.

    Parameters (ROS 1 names where ros1_bridge has them): ``topics``, ``services``, ``actions``
    and ``exclude`` (lists of shell-style patterns), ``ros1_node_name`` (default
    ``visnav_bridge``), ``master_uri`` (default ``ROS_MASTER_URI``), ``serve_master_port``
    (0: use an existing master; a port: serve a master on 127.0.0.1 there).

    Args:
        name: visnav node name (default ``ros1_bridge``).
        **node_kwargs: passed to :class:`~visnav.graph.Node`.

    Raises:
        MasterUnreachableError: no master answers.
    """

    def __init__(self, name: str = "ros1_bridge", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        params = declare_params(self, BridgeParams)
        topics, exclude = params.topics, params.exclude
        ros1_name, master_uri = params.ros1_node_name, params.master_uri
        port = params.serve_master_port
        self.master: Ros1Master | None = None
        if port:
            self.master = Ros1Master(port)
            self.master.start()
            master_uri = self.master.uri
        try:
            self.ros1 = open_ros1_node(
                ros1_name, master_uri=master_uri or None, on_shutdown=self._on_kill
            )
        except Exception:
            if self.master is not None:
                self.master.close()
            raise
        options = BridgeOptions(
            topics=tuple(str(t) for t in topics if t),
            exclude=tuple(str(t) for t in exclude if t),
            services=tuple(str(t) for t in params.services if t),
            actions=tuple(str(t) for t in params.actions if t),
        )
        self.bridge = Ros1Bridge(self, self.ros1, options)

    def _on_kill(self, why: str) -> None:
        """``rosnode kill``: leave the ROS 1 graph (the visnav node stays, as its launch says)."""
        self.get_logger().warning(f"left the ROS 1 graph: shutdown requested by {why}")
        self.ros1.close()

    def destroy_node(self) -> None:
        """Unregister from ROS 1, stop the served master, then destroy the visnav node."""
        if hasattr(self, "bridge"):
            self.ros1.close()
        master = getattr(self, "master", None)
        if master is not None:
            master.close()
        super().destroy_node()


def _stop(stop: threading.Event, ctx: Context) -> None:
    stop.set()
    ctx.wake()


def run_bridge(
    ctx: Context,
    *,
    topics: Sequence[str] = (),
    exclude: Sequence[str] = (),
    services: Sequence[str] = (),
    actions: Sequence[str] = (),
    serve_master_port: int | None = None,
    node_name: str = DEFAULT_NODE_NAME,
    duration_s: float | None = None,
    ready: threading.Event | None = None,
) -> None:
    """Run the bridge until ``rosnode kill``, Ctrl-C or ``duration_s``.

    Args:
        ctx: the visnav graph.
        topics: patterns of topics to bridge (empty: all).
        exclude: patterns of topics, services and actions not to bridge.
        services: patterns of services to bridge (empty: all whose types cross).
        actions: patterns of visnav actions to offer as actionlib servers (empty: all).
        serve_master_port: serve a ROS 1 master on 127.0.0.1 at this port first.
        node_name: the ROS 1 node name.
        duration_s: stop after this many seconds.
        ready: set once the bridge is registered.

    Raises:
        MasterUnreachableError: no master (and none served).
    """
    master: Ros1Master | None = None
    stop = threading.Event()
    if serve_master_port is not None:
        master = Ros1Master(serve_master_port)
        master.start()
        _log.info("serving a ROS 1 master at %s", master.uri)
    try:
        ros1 = open_ros1_node(
            node_name,
            master_uri=master.uri if master else None,
            on_shutdown=lambda _why: _stop(stop, ctx),
        )
        node = Node("ros1_bridge", context=ctx)
        options = BridgeOptions(
            topics=tuple(topics),
            exclude=tuple(exclude),
            services=tuple(services),
            actions=tuple(actions),
        )
        bridge = Ros1Bridge(node, ros1, options)
        _log.info("bridging ROS 1 master %s as %s (%s)", ros1.master.uri, ros1.name, ros1.uri)
        if ready is not None:
            ready.set()
        try:
            ctx.spin_until(stop.is_set, duration_s)
        finally:
            bridge.close()
            ros1.close()
    finally:
        if master is not None:
            master.close()
