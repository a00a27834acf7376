"""Errors of :mod:`visnav.bridge`: each names the master URI, topic, peer or type and the fix."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = [
    "BridgeError",
    "MasterError",
    "MasterUnreachableError",
    "Ros1ServiceError",
    "TcprosError",
    "UnconvertibleTypeError",
]


class BridgeError(VisnavError):
    """Base class of the bridge errors."""


class MasterUnreachableError(BridgeError, ConnectionError):
    """No ROS 1 master answers at ``ROS_MASTER_URI``."""


class MasterError(BridgeError, RuntimeError):
    """The ROS 1 master answered a call with an error code."""


class Ros1ServiceError(BridgeError, RuntimeError):
    """A call of a ROS 1 service failed (refused, unreachable, or the server's error text)."""


class TcprosError(BridgeError, ValueError):
    """A TCPROS peer sent bytes that are not a valid header or message frame."""


class UnconvertibleTypeError(BridgeError, TypeError):
    """A message type has no ROS 1 counterpart with the same wire format."""
