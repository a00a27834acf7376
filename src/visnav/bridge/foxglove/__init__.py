"""A Foxglove WebSocket server for the visnav graph (foxglove_bridge without ROS 2).

Foxglove and Lichtblick connect to ``ws://127.0.0.1:8765`` (see docs/foxglove.md). The
pieces: :mod:`~visnav.bridge.foxglove.protocol` (the wire format, no I/O),
:mod:`~visnav.bridge.foxglove.websocket` (connections, send buffers),
:mod:`~visnav.bridge.foxglove.server` (the graph side), :mod:`~visnav.bridge.foxglove.params`
(parameters), :mod:`~visnav.bridge.foxglove.node` (the ``foxglove_bridge`` node and CLI).
"""

from __future__ import annotations

from visnav.bridge.foxglove.errors import FoxgloveError, FoxgloveProtocolError
from visnav.bridge.foxglove.node import (
    DEFAULT_PORT,
    FoxgloveBridgeNode,
    FoxgloveParams,
    run_foxglove,
)
from visnav.bridge.foxglove.protocol import CAPABILITIES, SUBPROTOCOLS, parse_client_message
from visnav.bridge.foxglove.server import FoxgloveOptions, FoxgloveServer

__all__ = [
    "CAPABILITIES",
    "DEFAULT_PORT",
    "SUBPROTOCOLS",
    "FoxgloveBridgeNode",
    "FoxgloveError",
    "FoxgloveOptions",
    "FoxgloveParams",
    "FoxgloveProtocolError",
    "FoxgloveServer",
    "parse_client_message",
    "run_foxglove",
]
