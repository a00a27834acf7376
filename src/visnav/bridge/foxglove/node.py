"""The ``foxglove_bridge`` node and ``visnav foxglove``: a Foxglove WebSocket server on the graph.

Parameters are foxglove_bridge's (ROS 2) where it has them, with its defaults except one:
``address`` is ``127.0.0.1`` (foxglove_bridge binds ``0.0.0.0``): every visnav server
(the ROS 1 bridge, the viewer, the graph's Zenoh listener) binds loopback unless asked, so
that starting a run does not open the robot's topics, parameters and publishing to the
whole network. Give ``address:=0.0.0.0`` (``--address 0.0.0.0``) to reach it from another
machine.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from visnav.bridge.foxglove.assets import DEFAULT_ASSET_URI_ALLOWLIST
from visnav.bridge.foxglove.protocol import CAPABILITIES
from visnav.bridge.foxglove.server import FoxgloveOptions, FoxgloveServer
from visnav.graph import Context, Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["DEFAULT_PORT", "FoxgloveBridgeNode", "FoxgloveParams", "run_foxglove"]

DEFAULT_PORT = 8765
"""foxglove_bridge's port (Foxglove and Lichtblick suggest ws://localhost:8765)."""

_log = logging.getLogger("visnav.foxglove")


@dataclass(frozen=True)
class FoxgloveParams:
    """The ``foxglove_bridge`` node's parameters (read once at start)."""

    port: int = param(DEFAULT_PORT, description="TCP port (0: any free port)", range=(0, 65535))
    address: str = param(
        "127.0.0.1", description="address to bind (0.0.0.0: every interface; visnav: loopback)"
    )
    topic_whitelist: tuple[str, ...] = param(
        (".*",), description="regular expressions of topics to advertise"
    )
    service_whitelist: tuple[str, ...] = param(
        (".*",), description="regular expressions of services to advertise"
    )
    param_whitelist: tuple[str, ...] = param(
        (".*",), description="regular expressions of '<node>.<param>' names to serve"
    )
    client_topic_whitelist: tuple[str, ...] = param(
        (".*",), description="regular expressions of topics clients may publish on"
    )
    send_buffer_limit: int = param(
        10_000_000, description="bytes queued per client before messages are dropped"
    )
    capabilities: tuple[str, ...] = param(CAPABILITIES, description="capabilities offered")
    include_hidden: bool = param(False, description="also advertise hidden topics and services")
    min_qos_depth: int = param(1, description="least depth of a subscription", range=(1, 10000))
    max_qos_depth: int = param(25, description="largest depth of a subscription", range=(1, 10000))
    use_compression: bool = param(False, description="offer permessage-deflate")
    service_timeout: float = param(
        5.0, description="timeout of a service call made for a client, s", range=(0.01, 3600.0)
    )
    asset_uri_allowlist: tuple[str, ...] = param(
        DEFAULT_ASSET_URI_ALLOWLIST,
        description="regular expressions of the asset URIs clients may fetch (fetchAsset)",
    )
    packages: tuple[str, ...] = param(
        ("",), description="name=DIR for package:// assets (besides ROS_PACKAGE_PATH)"
    )


def _options(params: FoxgloveParams, name: str) -> FoxgloveOptions:
    return FoxgloveOptions(
        address=params.address,
        port=params.port,
        topic_whitelist=tuple(params.topic_whitelist),
        service_whitelist=tuple(params.service_whitelist),
        param_whitelist=tuple(params.param_whitelist),
        client_topic_whitelist=tuple(params.client_topic_whitelist),
        send_buffer_limit=params.send_buffer_limit,
        capabilities=tuple(params.capabilities),
        include_hidden=params.include_hidden,
        min_qos_depth=params.min_qos_depth,
        max_qos_depth=params.max_qos_depth,
        use_compression=params.use_compression,
        service_timeout_s=params.service_timeout,
        name=name,
        asset_uri_allowlist=tuple(params.asset_uri_allowlist),
        packages=dict(
            item.split("=", 1) for item in params.packages if "=" in item and item.split("=", 1)[1]
        ),
    )


class FoxgloveBridgeNode(Node):
    """The ``foxglove_bridge`` node: serves this graph to Foxglove and Lichtblick (port 8765).

    Parameters: :class:`FoxgloveParams` (``port``, ``address``, ``topic_whitelist``,
    ``send_buffer_limit``, ``capabilities``, ...). See docs/foxglove.md.

    Args:
        name: node name (default ``foxglove_bridge``).
        **node_kwargs: passed to :class:`~visnav.graph.Node`.

    Raises:
        FoxgloveError: a bad parameter, or the port cannot be bound.
    """

    def __init__(self, name: str = "foxglove_bridge", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        params = declare_params(self, FoxgloveParams)
        self.server = FoxgloveServer(self, _options(params, self.get_fully_qualified_name()))
        self.server.start()
        self.get_logger().info(f"Foxglove WebSocket server at {self.server.url}")

    def destroy_node(self) -> None:
        """Stop the server, then destroy the node."""
        server = getattr(self, "server", None)
        if server is not None:
            server.close()
        super().destroy_node()


def run_foxglove(
    ctx: Context,
    options: FoxgloveOptions,
    *,
    use_sim_time: bool | None = None,
    duration_s: float | None = None,
    on_ready: Callable[[FoxgloveServer], None] | None = None,
    stop: threading.Event | None = None,
) -> FoxgloveServer:
    """Serve ``ctx``'s graph until ``stop`` is set, Ctrl-C or ``duration_s``.

    Args:
        ctx: the graph.
        options: what to serve, where.
        use_sim_time: stamp with ``/clock`` time and send it (``time`` capability); None:
            when ``/clock`` has a publisher at start.
        duration_s: stop after this many seconds.
        on_ready: called with the server once its port is bound.
        stop: set it (from another thread) to stop.

    Returns:
        The (closed) server, for its statistics.

    Raises:
        FoxgloveError: bad options, or the port cannot be bound.
    """
    if use_sim_time is None:
        use_sim_time = any(e.kind == "publisher" for e in ctx.graph.endpoints("/clock"))
    node = Node("foxglove_bridge", context=ctx, use_sim_time=use_sim_time)
    server = FoxgloveServer(node, options)
    stop = stop or threading.Event()
    try:
        server.start()
        _log.debug("Foxglove WebSocket server at %s (sim time: %s)", server.url, use_sim_time)
        if on_ready is not None:
            on_ready(server)
        ctx.spin_until(stop.is_set, duration_s)
    finally:
        server.close()
        node.destroy_node()
    return server
