"""Errors of the Foxglove WebSocket server."""

from __future__ import annotations

from visnav.bridge.errors import BridgeError

__all__ = ["FoxgloveError", "FoxgloveProtocolError"]


class FoxgloveError(BridgeError):
    """The Foxglove server cannot start or serve (port taken, bad parameter, ...)."""


class FoxgloveProtocolError(FoxgloveError, ValueError):
    """A client sent a frame that is not a valid message of the Foxglove WebSocket protocol."""
