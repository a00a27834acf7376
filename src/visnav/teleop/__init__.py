"""Keyboard teleoperation: teleop_twist_keyboard and turtlebot3_teleop_key.

The key -> velocity logic is plain classes (:mod:`visnav.teleop.keymaps`), testable
without a terminal; :mod:`visnav.teleop.terminal` reads single keys from a real
terminal; :mod:`visnav.teleop.nodes` wires them to ``cmd_vel``.
"""

from __future__ import annotations

from visnav.teleop.errors import NotATerminalError, TeleopError
from visnav.teleop.keymaps import (
    TB3_LIMITS,
    KeyResult,
    Turtlebot3Keyboard,
    TwistKeyboard,
    Velocity,
)

__all__ = [
    "TB3_LIMITS",
    "KeyResult",
    "NotATerminalError",
    "TeleopError",
    "Turtlebot3Keyboard",
    "TwistKeyboard",
    "Velocity",
]
