"""Key -> velocity logic of teleop_twist_keyboard and turtlebot3_teleop_key, without a terminal.

Both classes take one key event at a time (a one-character string, or ``""`` when the
key timeout passed without a key) and say whether the node publishes after it, whether
it quits, and the lines it prints. :attr:`velocity` is then the command to publish.

**teleop_twist_keyboard** (ROS 1, the Python node of ros-teleop): a move key sets a
direction ``(x, y, z, th)`` that is multiplied by the current ``speed`` (linear) and
``turn`` (angular):

* ``u i o / j k l / m , .``: forward-left, forward, forward-right / turn left, (``k``
  is not bound: stop), turn right / back-right, back, back-left (``.`` turns left while
  reversing and ``m`` right, as the original does);
* shift (``U I O / J K L / M < >``): holonomic, ``y`` instead of turning;
* ``t`` / ``b``: up / down (``z``);
* ``q``/``z`` scale both speeds by 1.1 / 0.9, ``w``/``x`` only ``speed``, ``e``/``c``
  only ``turn``, never above ``speed_limit`` / ``turn_limit``; the help text is shown
  again every 15 such keys;
* any other key stops (all directions 0); a key timeout (``""``) stops too, unless the
  robot is already stopped (then nothing is published); Ctrl-C (:data:`CTRL_C`) quits.

**turtlebot3_teleop_key** (ROBOTIS): ``w``/``x`` add / subtract 0.01 m/s of target
linear velocity, ``a``/``d`` 0.1 rad/s of target angular velocity, clamped to the
model's limits (:data:`TB3_LIMITS`; an unknown model gets the burger's); ``space`` and
``s`` stop at once. Every event (key or the 0.1 s timeout) moves the published velocity
towards the target by at most half a step (0.005 m/s, 0.05 rad/s) and publishes it:
the node's own velocity smoothing. The help text is shown again every 20 velocity keys.
Ctrl-C quits; the node then publishes a zero Twist.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from visnav.msgs.types import Twist

__all__ = [
    "CTRL_C",
    "MOVE_BINDINGS",
    "SPEED_BINDINGS",
    "TB3_ANG_STEP",
    "TB3_LIMITS",
    "TB3_LIN_STEP",
    "KeyResult",
    "Turtlebot3Keyboard",
    "TwistKeyboard",
    "Velocity",
]

CTRL_C = "\x03"
"""The character a terminal in raw mode sends for Ctrl-C."""

MOVE_BINDINGS: Mapping[str, tuple[int, int, int, int]] = MappingProxyType(
    {
        "u": (1, 0, 0, 1),
        "i": (1, 0, 0, 0),
        "o": (1, 0, 0, -1),
        "j": (0, 0, 0, 1),
        "l": (0, 0, 0, -1),
        "m": (-1, 0, 0, -1),
        ",": (-1, 0, 0, 0),
        ".": (-1, 0, 0, 1),
        "U": (1, 1, 0, 0),
        "I": (1, 0, 0, 0),
        "O": (1, -1, 0, 0),
        "J": (0, 1, 0, 0),
        "L": (0, -1, 0, 0),
        "M": (-1, 1, 0, 0),
        "<": (-1, 0, 0, 0),
        ">": (-1, -1, 0, 0),
        "t": (0, 0, 1, 0),
        "b": (0, 0, -1, 0),
    }
)
"""teleop_twist_keyboard's direction keys: ``(x, y, z, th)`` multiplied by speed / turn."""

SPEED_BINDINGS: Mapping[str, tuple[float, float]] = MappingProxyType(
    {
        "q": (1.1, 1.1),
        "z": (0.9, 0.9),
        "w": (1.1, 1.0),
        "x": (0.9, 1.0),
        "e": (1.0, 1.1),
        "c": (1.0, 0.9),
    }
)
"""teleop_twist_keyboard's speed keys."""

TB3_LIMITS: Mapping[str, tuple[float, float]] = MappingProxyType(
    {"burger": (0.22, 2.84), "waffle": (0.26, 1.82), "waffle_pi": (0.26, 1.82)}
)
"""turtlebot3_teleop_key's ``(max linear m/s, max angular rad/s)`` per ``model``."""

TB3_LIN_STEP = 0.01
"""turtlebot3_teleop_key's linear step per ``w`` / ``x`` (m/s)."""
TB3_ANG_STEP = 0.1
"""turtlebot3_teleop_key's angular step per ``a`` / ``d`` (rad/s)."""

_TWIST_HELP = """\
teleop_twist_keyboard: keys -> geometry_msgs/Twist on cmd_vel
  move:    u  i  o      holonomic   U  I  O
           j  k  l      (shift):    J  K  L
           m  ,  .                  M  <  >
  t / b: up / down          any other key: stop
  q / z: speed and turn x1.1 / x0.9
  w / x: speed only         e / c: turn only
  Ctrl-C: quit"""

_TB3_HELP = """\
turtlebot3_teleop_key ({model}): keys -> geometry_msgs/Twist on cmd_vel
        w
    a   s   d
        x
  w / x: linear velocity +/- {lin:g} m/s (up to {max_lin:g})
  a / d: angular velocity +/- {ang:g} rad/s (up to {max_ang:g})
  space or s: stop at once
  Ctrl-C: quit"""


@dataclass(frozen=True)
class Velocity:
    """A velocity command (the non-zero fields of a Twist these nodes publish)."""

    linear_x: float = 0.0
    linear_y: float = 0.0
    linear_z: float = 0.0
    angular_z: float = 0.0

    def to_twist(self) -> Twist:
        """This command as a ``geometry_msgs/Twist``."""
        from visnav.msgs.types import Twist, Vector3  # noqa: PLC0415

        return Twist(
            linear=Vector3(x=float(self.linear_x), y=float(self.linear_y), z=float(self.linear_z)),
            angular=Vector3(x=0.0, y=0.0, z=float(self.angular_z)),
        )


@dataclass(frozen=True)
class KeyResult:
    """What a key event does.

    Attributes:
        publish: The node publishes :attr:`~TwistKeyboard.velocity` after this event.
        quit: Ctrl-C: the node stops (publishing a zero Twist) and exits.
        lines: Text to print on the terminal.
    """

    publish: bool
    quit: bool = False
    lines: tuple[str, ...] = ()


class TwistKeyboard:
    """teleop_twist_keyboard's state machine (module docstring).

    Args:
        speed: Initial linear speed (m/s), the node's ``speed``.
        turn: Initial angular speed (rad/s), the node's ``turn``.
        speed_limit: Upper bound of ``speed`` (``speed_limit``).
        turn_limit: Upper bound of ``turn`` (``turn_limit``).
    """

    def __init__(
        self,
        *,
        speed: float = 0.5,
        turn: float = 1.0,
        speed_limit: float = 1000.0,
        turn_limit: float = 1000.0,
    ) -> None:
        self.speed = speed
        self.turn = turn
        self.speed_limit = speed_limit
        self.turn_limit = turn_limit
        self.direction: tuple[int, int, int, int] = (0, 0, 0, 0)
        self._speed_keys = 0

    @staticmethod
    def help_lines() -> tuple[str, ...]:
        """The key help printed at start."""
        return tuple(_TWIST_HELP.splitlines())

    def status_line(self) -> str:
        """The current speeds."""
        return f"currently: speed {self.speed:.6g} m/s, turn {self.turn:.6g} rad/s"

    @property
    def velocity(self) -> Velocity:
        """The command: direction times speed / turn."""
        x, y, z, th = self.direction
        return Velocity(
            linear_x=x * self.speed,
            linear_y=y * self.speed,
            linear_z=z * self.speed,
            angular_z=th * self.turn,
        )

    def press(self, key: str) -> KeyResult:
        """Apply one key event (``""``: the key timeout passed)."""
        if key in MOVE_BINDINGS:
            self.direction = MOVE_BINDINGS[key]
            return KeyResult(publish=True)
        if key in SPEED_BINDINGS:
            f_speed, f_turn = SPEED_BINDINGS[key]
            self.speed = min(self.speed_limit, self.speed * f_speed)
            self.turn = min(self.turn_limit, self.turn * f_turn)
            lines: list[str] = []
            if self.speed == self.speed_limit:
                lines.append(f"linear speed is at speed_limit ({self.speed_limit:g})")
            if self.turn == self.turn_limit:
                lines.append(f"angular speed is at turn_limit ({self.turn_limit:g})")
            lines.append(self.status_line())
            if self._speed_keys == 14:
                lines.extend(self.help_lines())
            self._speed_keys = (self._speed_keys + 1) % 15
            return KeyResult(publish=True, lines=tuple(lines))
        if key == "" and self.direction == (0, 0, 0, 0):
            return KeyResult(publish=False)
        self.direction = (0, 0, 0, 0)
        if key == CTRL_C:
            return KeyResult(publish=False, quit=True)
        return KeyResult(publish=True)


def _clamp(value: float, limit: float) -> float:
    return min(max(value, -limit), limit)


def _toward(current: float, target: float, slop: float) -> float:
    """Move ``current`` towards ``target`` by at most ``slop`` (the TB3 node's profile)."""
    if target > current:
        return min(target, current + slop)
    if target < current:
        return max(target, current - slop)
    return target


class Turtlebot3Keyboard:
    """turtlebot3_teleop_key's state machine (module docstring).

    Args:
        model: ``burger``, ``waffle`` or ``waffle_pi`` (TURTLEBOT3_MODEL); another name
            gets the burger's limits, as the ROBOTIS node does (:attr:`known_model` is
            then False).
    """

    def __init__(self, *, model: str = "burger") -> None:
        self.model = model
        self.known_model = model in TB3_LIMITS
        self.max_linear, self.max_angular = TB3_LIMITS.get(model, TB3_LIMITS["burger"])
        self.target_linear = 0.0
        self.target_angular = 0.0
        self.control_linear = 0.0
        self.control_angular = 0.0
        self._velocity_keys = 0

    def help_lines(self) -> tuple[str, ...]:
        """The key help printed at start (with this model's limits)."""
        text = _TB3_HELP.format(
            model=self.model,
            lin=TB3_LIN_STEP,
            ang=TB3_ANG_STEP,
            max_lin=self.max_linear,
            max_ang=self.max_angular,
        )
        return tuple(text.splitlines())

    def status_line(self) -> str:
        """The target velocities."""
        return (
            f"target: linear {self.target_linear:.6g} m/s, angular {self.target_angular:.6g} rad/s"
        )

    @property
    def velocity(self) -> Velocity:
        """The smoothed command last computed by :meth:`press`."""
        return Velocity(linear_x=self.control_linear, angular_z=self.control_angular)

    def press(self, key: str) -> KeyResult:
        """Apply one key event (``""``: 0.1 s without a key) and step the smoothing."""
        lines: list[str] = []
        if key in ("w", "x", "a", "d"):
            if key == "w":
                self.target_linear = _clamp(self.target_linear + TB3_LIN_STEP, self.max_linear)
            elif key == "x":
                self.target_linear = _clamp(self.target_linear - TB3_LIN_STEP, self.max_linear)
            elif key == "a":
                self.target_angular = _clamp(self.target_angular + TB3_ANG_STEP, self.max_angular)
            else:
                self.target_angular = _clamp(self.target_angular - TB3_ANG_STEP, self.max_angular)
            self._velocity_keys += 1
            lines.append(self.status_line())
        elif key in (" ", "s"):
            self.target_linear = self.control_linear = 0.0
            self.target_angular = self.control_angular = 0.0
            lines.append(self.status_line())
        elif key == CTRL_C:
            return KeyResult(publish=False, quit=True)
        if self._velocity_keys == 20:
            lines.extend(self.help_lines())
            self._velocity_keys = 0
        self.control_linear = _toward(self.control_linear, self.target_linear, TB3_LIN_STEP / 2)
        self.control_angular = _toward(self.control_angular, self.target_angular, TB3_ANG_STEP / 2)
        return KeyResult(publish=True, lines=tuple(lines))
