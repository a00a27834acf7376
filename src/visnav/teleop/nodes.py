"""``teleop_twist_keyboard`` and ``turtlebot3_teleop_key``: the keyboard on ``cmd_vel``.

Both nodes read single keys from the terminal of their process
(:class:`~visnav.teleop.terminal.TerminalKeys`; a standard input that is not a terminal
is refused at start with :class:`~visnav.teleop.errors.NotATerminalError`), run the key
logic of :mod:`visnav.teleop.keymaps`, print their help and status lines and publish
``geometry_msgs/Twist`` on ``cmd_vel`` (remap it as usual). The keyboard is polled
every 20 ms of wall time (also under ``use_sim_time``), in the node's executor, so the
node shares a process with others as any node does.

``teleop_twist_keyboard`` parameters (ROS 1's, same defaults): ``speed`` (0.5 m/s),
``turn`` (1.0 rad/s), ``speed_limit`` / ``turn_limit`` (1000), ``repeat_rate`` (0:
publish on key events only; > 0: also repeat the last command at this rate),
``key_timeout`` (0.5 s: with no key for this long the robot is stopped, so holding a
key down keeps it moving; 0: never), ``stamped`` (false: ``geometry_msgs/TwistStamped``
when true) and ``frame_id`` ("", the TwistStamped's frame). As in ROS the node waits
for a subscriber of ``cmd_vel`` before it reads the first key (saying so every 2.5 s),
so the first key is not lost.

``turtlebot3_teleop_key`` parameter: ``model`` ("burger"; ``waffle``, ``waffle_pi``),
which sets the speed limits; the ROBOTIS node reads the global ``/model`` that
turtlebot3_teleop_key.launch sets from ``TURTLEBOT3_MODEL``. It publishes after every
key and every 0.1 s without one (its velocity smoothing).

On Ctrl-C both publish a zero Twist, restore the terminal, and end: the node is
destroyed and, when it was the last node of its process (``visnav launch`` with
``process: own``, or a launch of only this node), the process exits 0. The terminal is
restored and a zero Twist sent whenever the node is destroyed.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from visnav.graph.clock import Clock, ClockType
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.msgs.types import Header, Twist, TwistStamped
from visnav.teleop.keymaps import KeyResult, Turtlebot3Keyboard, TwistKeyboard, Velocity
from visnav.teleop.terminal import KeySource, TerminalKeys

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from visnav.graph.node import Publisher
    from visnav.graph.timer import Timer

__all__ = [
    "Turtlebot3TeleopKeyNode",
    "Turtlebot3TeleopParams",
    "TeleopTwistKeyboardNode",
    "TeleopTwistKeyboardParams",
]

_POLL_S = 0.02
_WAIT_NOTICE_S = 2.5
_TB3_TIMEOUT_S = 0.1


def _print(line: str) -> None:
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


@dataclass(frozen=True)
class TeleopTwistKeyboardParams:
    """teleop_twist_keyboard's parameters (ROS 1's names and defaults; read once)."""

    speed: float = param(0.5, description="initial linear speed (m/s)", range=(-1e6, 1e6))
    turn: float = param(1.0, description="initial angular speed (rad/s)", range=(-1e6, 1e6))
    speed_limit: float = param(1000.0, description="upper bound of speed", range=(0.0, 1e9))
    turn_limit: float = param(1000.0, description="upper bound of turn", range=(0.0, 1e9))
    repeat_rate: float = param(
        0.0, description="re-publish the command at this rate (Hz; 0: on keys only)",
        range=(0.0, 1000.0),
    )  # fmt: skip
    key_timeout: float = param(
        0.5, description="stop after this long without a key (s; 0: never)", range=(0.0, 3600.0)
    )
    stamped: bool = param(False, description="publish geometry_msgs/TwistStamped")
    frame_id: str = param("", description="header.frame_id when stamped")


@dataclass(frozen=True)
class Turtlebot3TeleopParams:
    """turtlebot3_teleop_key's parameter (read once)."""

    model: str = param("burger", description="burger, waffle or waffle_pi: the speed limits")


class _KeyboardNode(Node):
    """The terminal, the poll timer and the end of both teleop nodes."""

    finished: bool = False
    """True once the node quit (Ctrl-C) and was destroyed."""

    def _open_keys(self, keys: KeySource | None, executable: str) -> KeySource:
        if keys is not None:
            return keys
        try:
            return TerminalKeys(who=f"{executable} ({self.get_fully_qualified_name()})")
        except BaseException:
            Node.destroy_node(self)
            raise

    def _setup(
        self,
        keys: KeySource,
        out: Callable[[str], None] | None,
        *,
        exit_when_done: bool,
    ) -> None:
        self._keys: KeySource | None = keys
        self._out = out or _print
        self._exit_when_done = exit_when_done
        self._steady = Clock(ClockType.STEADY_TIME)
        self._last_event = time.monotonic()
        self._poll_timer: Timer = self.create_timer(_POLL_S, self._poll, clock=self._steady)

    def _say(self, lines: tuple[str, ...] | list[str]) -> None:
        for line in lines:
            self._out(line)

    def _poll(self) -> None:
        raise NotImplementedError

    def _publish_velocity(self, velocity: Velocity) -> None:
        raise NotImplementedError

    def _handle(self, result: KeyResult, velocity: Callable[[], Velocity]) -> bool:
        """Print, publish or quit for one key event; False once the node quit."""
        self._say(result.lines)
        if result.quit:
            self._quit()
            return False
        if result.publish:
            self._publish_velocity(velocity())
        return True

    def _quit(self) -> None:
        self.destroy_node()
        if self._exit_when_done and not [n for n in self.context.nodes if n is not self]:
            raise SystemExit(0)

    def destroy_node(self) -> None:
        """Send a zero Twist, restore the terminal, and remove the node."""
        keys = getattr(self, "_keys", None)
        if keys is not None and not self.finished:
            self.finished = True
            try:
                self._publish_velocity(Velocity())
            finally:
                self._keys = None
                keys.close()
        super().destroy_node()


class TeleopTwistKeyboardNode(_KeyboardNode):
    """teleop_twist_keyboard (module docstring).

    Args:
        name: Node name (default ``teleop_twist_keyboard``).
        keys: Where keys come from (default: this process's terminal).
        out: Where help and status lines go (default: standard output).
        exit_when_done: After Ctrl-C, end the process (``SystemExit(0)``) when this was
            its last node; ``visnav teleop`` passes False and ends by itself.
        **node_kwargs: Passed to :class:`~visnav.graph.Node`.

    Raises:
        NotATerminalError: ``keys`` is None and standard input is not a terminal.
        ParameterError: A parameter is out of range.
    """

    def __init__(
        self,
        name: str = "teleop_twist_keyboard",
        *,
        keys: KeySource | None = None,
        out: Callable[[str], None] | None = None,
        exit_when_done: bool = True,
        **node_kwargs: Unpack[NodeOptions],
    ) -> None:
        super().__init__(name, **node_kwargs)
        self.params = p = declare_params(self, TeleopTwistKeyboardParams)
        self.keyboard = TwistKeyboard(
            speed=p.speed, turn=p.turn, speed_limit=p.speed_limit, turn_limit=p.turn_limit
        )
        keys = self._open_keys(keys, "teleop_twist_keyboard")
        msg_type: type[Any] = TwistStamped if p.stamped else Twist
        self._pub: Publisher[Any] = self.create_publisher(msg_type, "cmd_vel", 1)
        self._waiting = True
        self._waiting_since = time.monotonic()
        self._notices = 0
        self._setup(keys, out, exit_when_done=exit_when_done)
        if p.repeat_rate > 0.0:
            self.create_timer(1.0 / p.repeat_rate, self._repeat, clock=self._steady)

    def _publish_velocity(self, velocity: Velocity) -> None:
        twist = velocity.to_twist()
        if not self.params.stamped:
            self._pub.publish(twist)
            return
        from visnav.msgs.time import ns_to_time  # noqa: PLC0415

        header = Header(stamp=ns_to_time(self.get_clock().now_ns()), frame_id=self.params.frame_id)
        self._pub.publish(TwistStamped(header=header, twist=twist))

    def _repeat(self) -> None:
        if not self._waiting and not self.finished:
            self._publish_velocity(self.keyboard.velocity)

    def _wait_for_subscriber(self) -> bool:
        if self._pub.get_subscription_count() > 0:
            self._waiting = False
            self._say([*self.keyboard.help_lines(), self.keyboard.status_line()])
            self._publish_velocity(self.keyboard.velocity)
            self._last_event = time.monotonic()
            return True
        waited = time.monotonic() - self._waiting_since
        if waited >= _WAIT_NOTICE_S * (self._notices + 1):
            self._notices += 1
            self._say([f"waiting for a subscriber of {self._pub.topic_name}"])
        return False

    def _poll(self) -> None:
        keys = self._keys
        if keys is None or (self._waiting and not self._wait_for_subscriber()):
            return
        for key in keys.read_keys(0.0):
            self._last_event = time.monotonic()
            if not self._handle(self.keyboard.press(key), lambda: self.keyboard.velocity):
                return
        timeout = self.params.key_timeout
        if timeout > 0.0 and time.monotonic() - self._last_event >= timeout:
            self._last_event = time.monotonic()
            self._handle(self.keyboard.press(""), lambda: self.keyboard.velocity)


class Turtlebot3TeleopKeyNode(_KeyboardNode):
    """turtlebot3_teleop_key (module docstring).

    Args:
        name: Node name (default ``turtlebot3_teleop_keyboard``, the launch file's).
        keys: Where keys come from (default: this process's terminal).
        out: Where help and status lines go (default: standard output).
        exit_when_done: As :class:`TeleopTwistKeyboardNode`'s.
        **node_kwargs: Passed to :class:`~visnav.graph.Node`.

    Raises:
        NotATerminalError: ``keys`` is None and standard input is not a terminal.
    """

    def __init__(
        self,
        name: str = "turtlebot3_teleop_keyboard",
        *,
        keys: KeySource | None = None,
        out: Callable[[str], None] | None = None,
        exit_when_done: bool = True,
        **node_kwargs: Unpack[NodeOptions],
    ) -> None:
        super().__init__(name, **node_kwargs)
        self.params = declare_params(self, Turtlebot3TeleopParams)
        self.keyboard = Turtlebot3Keyboard(model=self.params.model)
        if not self.keyboard.known_model:
            self.get_logger().warning(
                f"model is {self.params.model!r}: expected burger, waffle or waffle_pi; "
                "using the burger's speed limits (as turtlebot3_teleop_key does). Fix: set "
                "model (TURTLEBOT3_MODEL) to your robot"
            )
        keys = self._open_keys(keys, "turtlebot3_teleop_key")
        self._pub: Publisher[Twist] = self.create_publisher(Twist, "cmd_vel", 10)
        self._setup(keys, out, exit_when_done=exit_when_done)
        self._say(self.keyboard.help_lines())

    def _publish_velocity(self, velocity: Velocity) -> None:
        self._pub.publish(velocity.to_twist())

    def _poll(self) -> None:
        keys = self._keys
        if keys is None:
            return
        for key in keys.read_keys(0.0):
            self._last_event = time.monotonic()
            if not self._handle(self.keyboard.press(key), lambda: self.keyboard.velocity):
                return
        if time.monotonic() - self._last_event >= _TB3_TIMEOUT_S:
            self._last_event = time.monotonic()
            self._handle(self.keyboard.press(""), lambda: self.keyboard.velocity)
