"""``visnav teleop``: drive a robot from the keyboard (teleop_twist_keyboard, TurtleBot3's).

* ``visnav teleop`` is ``rosrun teleop_twist_keyboard teleop_twist_keyboard.py``:
  ``u i o / j k l / m , .`` (shift: holonomic), ``t``/``b`` up/down, ``q/z w/x e/c``
  speed steps; ``--speed --turn --speed-limit --turn-limit --repeat-rate --key-timeout
  --stamped --frame-id`` are its ``_speed:=`` ... parameters.
* ``visnav teleop --turtlebot3 [--model burger|waffle|waffle_pi]`` is
  ``roslaunch turtlebot3_teleop turtlebot3_teleop_key.launch``: ``w/x`` ``a/d``
  steps, ``space``/``s`` stop, the model's speed limits (``--model`` defaults to
  ``$TURTLEBOT3_MODEL``, else burger) and its velocity smoothing.

Both publish on ``cmd_vel`` (``--topic`` or a ``cmd_vel:=TOPIC`` argument remaps it);
ROS-style ``_name:=value`` arguments set the node's parameters too. Ctrl-C stops the
robot (a zero Twist) and restores the terminal. Standard input must be a terminal.
"""

from __future__ import annotations

import argparse
import os
from typing import Any

__all__ = ["add_arguments", "teleop_overrides"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``teleop`` options."""
    parser.add_argument(
        "ros_args",
        nargs="*",
        metavar="NAME:=VALUE",
        help="ROS-style arguments: _speed:=0.3 (a parameter), cmd_vel:=/robot/cmd_vel (a remap)",
    )
    parser.add_argument(
        "--turtlebot3",
        "--tb3",
        action="store_true",
        help="turtlebot3_teleop_key's keys (w/x/a/d/space/s) instead of teleop_twist_keyboard's",
    )
    parser.add_argument(
        "--model",
        default=None,
        help="--turtlebot3: burger, waffle or waffle_pi (default $TURTLEBOT3_MODEL, else burger)",
    )
    parser.add_argument("--topic", default=None, help="publish on this topic (default cmd_vel)")
    parser.add_argument("--name", default=None, help="node name (default: the ROS node's)")
    parser.add_argument("--speed", type=float, default=None, help="initial speed (0.5 m/s)")
    parser.add_argument("--turn", type=float, default=None, help="initial turn (1.0 rad/s)")
    parser.add_argument("--speed-limit", type=float, default=None, help="max speed (1000)")
    parser.add_argument("--turn-limit", type=float, default=None, help="max turn (1000)")
    parser.add_argument(
        "--repeat-rate", type=float, default=None, help="re-publish at this rate (0: on keys)"
    )
    parser.add_argument(
        "--key-timeout", type=float, default=None, help="stop after S s without a key (0.5)"
    )
    parser.add_argument("--stamped", action="store_true", help="publish TwistStamped")
    parser.add_argument("--frame-id", default=None, help="TwistStamped header.frame_id")
    parser.set_defaults(func=cmd_teleop)


def _value(text: str) -> Any:
    from visnav.safe_yaml import YamlError, load_yaml

    try:
        return load_yaml(text, source="a _name:=value argument") if text else ""
    except YamlError:
        return text


_TWIST_OPTIONS = {
    "speed": "speed",
    "turn": "turn",
    "speed_limit": "speed_limit",
    "turn_limit": "turn_limit",
    "repeat_rate": "repeat_rate",
    "key_timeout": "key_timeout",
    "frame_id": "frame_id",
}


def teleop_overrides(args: argparse.Namespace) -> tuple[dict[str, Any], dict[str, str]]:
    """The node's parameter overrides and remappings from the command line.

    Raises:
        TeleopError: an argument that is not ``name:=value``, or a teleop_twist_keyboard
            option given with ``--turtlebot3``.
    """
    from visnav.teleop.errors import TeleopError

    params: dict[str, Any] = {}
    remaps: dict[str, str] = {}
    for item in args.ros_args:
        name, sep, value = item.partition(":=")
        if not sep or not name:
            msg = (
                f"teleop argument {item!r}: expected NAME:=VALUE, e.g. _speed:=0.3 (a "
                "parameter) or cmd_vel:=/robot/cmd_vel (a remap)"
            )
            raise TeleopError(msg)
        if name.startswith("__") or name == "_":
            msg = (
                f"teleop argument {item!r}: not a parameter (_name:=value) nor a remap; "
                "special ROS arguments (__name:=) are not taken: use --name"
            )
            raise TeleopError(msg)
        if name.startswith("_"):
            params[name[1:]] = _value(value)
        else:
            remaps[name] = value
    if args.topic is not None:
        remaps["cmd_vel"] = args.topic
    given = {
        key: getattr(args, attr) for attr, key in _TWIST_OPTIONS.items() if getattr(args, attr)
        is not None
    }  # fmt: skip
    if args.stamped:
        given["stamped"] = True
    if args.turtlebot3:
        if given:
            options = ", ".join("--" + k.replace("_", "-") for k in sorted(given))
            msg = (
                f"{options}: teleop_twist_keyboard options, but --turtlebot3 runs "
                "turtlebot3_teleop_key (its only parameter is --model). Fix: drop them or "
                "drop --turtlebot3"
            )
            raise TeleopError(msg)
        model = args.model or os.environ.get("TURTLEBOT3_MODEL") or "burger"
        params.setdefault("model", model)
    else:
        if args.model is not None:
            msg = "--model is turtlebot3_teleop_key's: add --turtlebot3 (or drop --model)"
            raise TeleopError(msg)
        params.update(given)
    return params, remaps


def cmd_teleop(args: argparse.Namespace) -> int:
    """``visnav teleop``."""
    from visnav.graph.context import Context
    from visnav.launch.param_check import report_unknown_parameters
    from visnav.teleop.nodes import TeleopTwistKeyboardNode, Turtlebot3TeleopKeyNode
    from visnav.teleop.terminal import TerminalKeys

    params, remaps = teleop_overrides(args)
    if args.turtlebot3:
        cls: Any = Turtlebot3TeleopKeyNode
        executable, default_name = "turtlebot3_teleop_key", "turtlebot3_teleop_keyboard"
    else:
        cls = TeleopTwistKeyboardNode
        executable, default_name = "teleop_twist_keyboard", "teleop_twist_keyboard"
    # the terminal first: a pipe is refused before the graph is opened
    keys = TerminalKeys(who=f"visnav teleop ({executable})")
    try:
        with Context(getattr(args, "domain", None)) as ctx:
            node = cls(
                args.name or default_name,
                keys=keys,
                exit_when_done=False,
                context=ctx,
                parameter_overrides=params,
                remappings=remaps,
            )
            report_unknown_parameters(node, params, executable=executable)
            try:
                while not node.finished:
                    ctx.spin_until(lambda: node.finished, timeout_s=0.5)
            finally:
                node.destroy_node()
    finally:
        keys.close()
    return 0
