"""Entry point of the ``visnav`` command: argument parsing and the one error boundary.

Verb modules are imported lazily so that ``visnav --help`` stays fast. Every
error that reaches here prints as one line ``error: ...`` (exit 1): visnav's own
errors as they are, those of the OS, codecs, PyYAML, OpenCV and the serializer
translated by :func:`visnav.cli._errors.describe_error`; with ``--debug`` the
traceback is shown too.

Stop signals: SIGTERM is handled as Ctrl-C by every verb (:mod:`visnav.cli._signals`)
and exits 143 where Ctrl-C exits 130. A Ctrl-C (or SIGTERM) while the verb's modules
load, before the verb runs, prints one line, ``interrupted during start-up``, and exits
130 (143): nothing has been written yet. This module imports nothing at its top but
``sys``, so that the window in which Python itself would print a ``KeyboardInterrupt``
traceback is only the interpreter's own start-up.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import argparse
    from collections.abc import Sequence

    from visnav.cli._signals import TerminateAsInterrupt

__all__ = ["build_parser", "main"]

# verb -> (module, help)
VERBS: dict[str, tuple[str, str]] = {
    "run": ("visnav.cli.run", "run a built-in scenario: car (office) or drone (forest)"),
    "sweep": ("visnav.cli.sweep", "run a scenario over seeds x settings (local or Ray), report"),
    "topic": ("visnav.cli.topic", "inspect and publish topics (ros2 topic)"),
    "node": ("visnav.cli.node", "list and inspect nodes (ros2 node)"),
    "service": ("visnav.cli.service", "list, inspect and call services (ros2 service)"),
    "action": ("visnav.cli.action", "list actions, send goals with feedback (ros2 action)"),
    "param": ("visnav.cli.param", "list, get, set, dump and load node parameters (ros2 param)"),
    "tf": ("visnav.cli.tf", "echo transforms, publish static ones, show the TF tree"),
    "camera": ("visnav.cli.camera", "usb_cam / cv_camera: a camera, video file or stream"),
    "calibrate": ("visnav.cli.calibrate", "chessboard camera calibration -> camera_info YAML"),
    "slam": ("visnav.cli.slam", "offline RGB-D SLAM on a TUM folder or a bag -> TUM trajectory"),
    "eval": ("visnav.cli.eval", "trajectory errors ATE / RPE of TUM files (evo's numbers)"),
    "view": ("visnav.cli.view", "show live topics or a bag in Rerun (RViz); web viewer option"),
    "plot": ("visnav.cli.plot", "plot message fields live: /odom/twist/twist/linear/x (rqt_plot)"),
    "image": ("visnav.cli.image", "show one image topic; --snapshot writes a PNG (rqt_image_view)"),
    "launch": ("visnav.cli.launch", "start a launch file: YAML or roslaunch XML (ros2 launch)"),
    "bag": ("visnav.cli.bag", "record, inspect, play and convert bags (ros2 bag)"),
    "map": ("visnav.cli.map", "save a live /map as map.yaml + map.pgm, describe a saved map"),
    "teleop": ("visnav.cli.teleop", "drive cmd_vel from the keyboard (teleop_twist_keyboard)"),
    "goal": ("visnav.cli.goal", "send a navigation goal X Y [YAW] (RViz's 2D Nav Goal)"),
    "initialpose": (
        "visnav.cli.initialpose",
        "set the localisation's pose X Y [YAW] (RViz's 2D Pose Estimate)",
    ),
    "sim": ("visnav.cli.sim", "simulate a world and a robot (MuJoCo), sensors on the graph"),
    "doctor": ("visnav.cli.doctor", "find data-chain faults in a live graph or a bag, with fixes"),
    "bridge": ("visnav.cli.bridge", "join a ROS 1 graph: master XML-RPC + TCPROS (ros1_bridge)"),
    "foxglove": (
        "visnav.cli.foxglove",
        "serve the graph to Foxglove / Lichtblick: WebSocket on 8765 (foxglove_bridge)",
    ),
}


def build_parser() -> argparse.ArgumentParser:
    """Return the full argument parser (verb modules add their own sub-parsers)."""
    import argparse
    import importlib

    parser = argparse.ArgumentParser(
        prog="visnav",
        description="visnav: ROS-style robot perception and navigation tools, no ROS install.",
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument(
        "--domain", default=None, help="graph domain (default: $VISNAV_DOMAIN or 0)"
    )
    sub = parser.add_subparsers(dest="verb", metavar="VERB")
    sub.required = True
    for verb, (module, help_text) in VERBS.items():
        p = sub.add_parser(verb, help=help_text, description=help_text)
        importlib.import_module(module).add_arguments(p)
    return parser


def _verb_parser(argv: Sequence[str]) -> argparse.ArgumentParser:
    """Build a parser that only imports the verb being run (fast startup)."""
    import argparse
    import importlib

    verb = next((a for a in argv if not a.startswith("-")), None)
    if verb not in VERBS:
        return build_parser()
    parser = argparse.ArgumentParser(prog="visnav")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--domain", default=None, help="graph domain")
    sub = parser.add_subparsers(dest="verb", metavar="VERB")
    sub.required = True
    module, help_text = VERBS[verb]
    p = sub.add_parser(verb, help=help_text, description=help_text)
    importlib.import_module(module).add_arguments(p)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``visnav`` command; return the exit code.

    After Ctrl-C 130, after SIGTERM 143, with no traceback (see the module docstring).
    """
    stop: TerminateAsInterrupt | None = None
    try:
        from visnav.cli._signals import TerminateAsInterrupt

        stop = TerminateAsInterrupt()
        with stop.installed(), stop.watch_sigint():
            try:
                args = _parse(argv)
            except BaseException as exc:  # the verb's modules were loading: nothing written
                # (an interrupt inside a C extension's import can surface as an ImportError)
                if not isinstance(exc, KeyboardInterrupt) and not stop.signals:
                    raise
                _say_startup_interrupted(stop)
                return stop.exit_code(130)
            return stop.exit_code(_call(args, stop))
    except KeyboardInterrupt:  # before the handler was in place, or as the verb returned
        if stop is None:
            _say_startup_interrupted(stop)
        return 130 if stop is None else stop.exit_code(130)


def _say_startup_interrupted(stop: TerminateAsInterrupt | None) -> None:
    from visnav.cli._signals import STARTUP_INTERRUPTED

    how = " (SIGTERM)" if stop is not None and stop.terminated else ""
    print(f"{STARTUP_INTERRUPTED}{how}", file=sys.stderr)


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    """Load the verb's module, parse the arguments and set up the terminal's logging."""
    from visnav.logsetup import configure_logging

    args_list = list(sys.argv[1:] if argv is None else argv)
    parser = _verb_parser(args_list)
    args = parser.parse_args(args_list)
    # [LEVEL] message on stderr; other libraries' INFO lines and Python warnings at debug
    configure_logging(debug=args.debug, stream=sys.stderr)
    return args


def _call(args: argparse.Namespace, stop: TerminateAsInterrupt) -> int:
    """Run the verb: every error it raises becomes one line (exit 1)."""
    from visnav.cli._errors import describe_error
    from visnav.cli._signals import StartupInterrupted

    try:
        code: int = args.func(args)
    except StartupInterrupted:
        _say_startup_interrupted(stop)
        return 130
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0
    except Exception as exc:  # noqa: BLE001  (the one boundary: every error becomes one line)
        if stop.signals and not args.debug:  # an interrupt a C extension turned into an error
            return 130
        if args.debug:
            import traceback

            traceback.print_exc()
        print(f"error: {describe_error(exc)}", file=sys.stderr)
        return 1
    return code


if __name__ == "__main__":
    sys.exit(main())
