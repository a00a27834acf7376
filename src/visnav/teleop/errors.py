"""Errors of :mod:`visnav.teleop`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["NotATerminalError", "TeleopError"]


class TeleopError(VisnavError):
    """Base class of the errors raised by :mod:`visnav.teleop`."""


class NotATerminalError(TeleopError, OSError):
    """Keyboard teleop was started with a standard input that is not a terminal."""
