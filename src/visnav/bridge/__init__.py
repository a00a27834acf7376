"""Bridges to other graphs: ROS 1 (master XML-RPC + TCPROS), no rospy needed.

See docs/ros1.md. The pieces: :mod:`~visnav.bridge.typemap` (types and byte conversion),
:mod:`~visnav.bridge.tcpros` (wire format), :mod:`~visnav.bridge.ros1_node` (a ROS 1 node),
:mod:`~visnav.bridge.master` (a minimal master), :mod:`~visnav.bridge.bridge` (the bridging).
"""

from __future__ import annotations

from visnav.bridge.bridge import BridgeOptions, Ros1Bridge, topic_selected
from visnav.bridge.errors import (
    BridgeError,
    MasterError,
    MasterUnreachableError,
    TcprosError,
    UnconvertibleTypeError,
)
from visnav.bridge.master import Ros1Master
from visnav.bridge.master_api import MasterClient
from visnav.bridge.ros1_node import Ros1Node
from visnav.bridge.runner import Ros1BridgeNode, open_ros1_node, run_bridge
from visnav.bridge.typemap import Ros1Type, ros1_type

__all__ = [
    "BridgeError",
    "BridgeOptions",
    "MasterClient",
    "MasterError",
    "MasterUnreachableError",
    "Ros1Bridge",
    "Ros1BridgeNode",
    "Ros1Master",
    "Ros1Node",
    "Ros1Type",
    "TcprosError",
    "UnconvertibleTypeError",
    "open_ros1_node",
    "ros1_type",
    "run_bridge",
    "topic_selected",
]
