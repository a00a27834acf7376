"""``visnav launch FILE [name:=value ...]``: start a launch file (ros2 launch / roslaunch)."""

from __future__ import annotations

import argparse
import logging
import signal
from dataclasses import replace
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from visnav.cli._signals import StartupInterrupted
from visnav.launch.errors import LaunchArgError
from visnav.logsetup import add_log_file, kernel_compilation_notice, remove_log_file
from visnav.scenarios.run_control import (
    record_status,
    remove_refused_output,
    scenario_output_arg,
)

if TYPE_CHECKING:
    from visnav.launch.description import LaunchDescription

__all__ = ["add_arguments", "cmd_launch", "parse_packages"]

_LOG = logging.getLogger("visnav.launch")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``launch`` arguments."""
    parser.description = (
        "Start the nodes of a visnav YAML launch file or a roslaunch XML file (.launch), "
        "given as a path, a built-in name, or PACKAGE FILE as roslaunch takes it (the package "
        "from --package or ROS_PACKAGE_PATH, the file found by name inside it). Arguments are "
        "name:=value. Ctrl-C stops every node (SIGINT, then SIGTERM, then SIGKILL). Format: "
        "docs/launch.md."
    )
    parser.add_argument(
        "file", help="launch file (.yaml, .launch/.xml), a built-in one, or PACKAGE (then FILE)"
    )
    parser.add_argument(
        "launch_args",
        nargs=argparse.REMAINDER,
        metavar="name:=value",
        help="launch arguments (options may come after them too)",
    )
    _add_options(parser)
    parser.set_defaults(func=cmd_launch)


def _add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--print",
        action="store_true",
        dest="print_only",
        help="print the resolved nodes, params and remaps, and exit without starting anything",
    )
    parser.add_argument("--json", action="store_true", help="with --print: print JSON")
    parser.add_argument(
        "--package",
        action="append",
        default=[],
        metavar="NAME=DIR",
        help="directory of a ROS package for $(find NAME) (repeatable)",
    )
    parser.add_argument(
        "--skip-unmapped",
        action="store_true",
        help="roslaunch files: leave out the nodes and elements visnav cannot map (each one a "
        "note) instead of refusing the file",
    )
    parser.add_argument(
        "--skip-missing-models",
        action="store_true",
        help="load a world whose model:// includes are not all on this machine without them "
        "(one warning; sets the sim node's skip_missing_models)",
    )
    parser.add_argument(
        "--sigterm-timeout",
        type=float,
        default=5.0,
        metavar="S",
        help="seconds a node has to stop after SIGINT before SIGTERM (then as long to SIGKILL)",
    )


def _late_options(args: argparse.Namespace) -> list[str]:
    """Read options given after FILE (argparse leaves them in the REMAINDER); return the rest."""
    late = argparse.ArgumentParser(prog="visnav launch", add_help=False)
    _add_options(late)
    found, rest = late.parse_known_args(args.launch_args)
    defaults = late.parse_args([])
    for key, value in vars(found).items():
        if value != getattr(defaults, key):
            current = getattr(args, key)
            setattr(args, key, current + value if isinstance(value, list) else value)
    return rest


def parse_packages(items: list[str]) -> dict[str, str]:
    """Parse ``--package NAME=DIR`` options.

    Raises:
        LaunchArgError: an item that is not ``NAME=DIR``.
    """
    out: dict[str, str] = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            msg = (
                f"--package {item!r}: expected NAME=DIR (e.g. --package my_robot=~/ws/src/my_robot)"
            )
            raise LaunchArgError(msg)
        out[name] = path
    return out


def cmd_launch(args: argparse.Namespace) -> int:
    """``launch``: a Ctrl-C before the nodes start is one line (nothing was started)."""
    try:
        prepared = _prepare(args)
    except KeyboardInterrupt:
        raise StartupInterrupted from None
    if prepared is None:  # --print
        return 0
    return _launch(args, *prepared)


def _prepare(args: argparse.Namespace) -> tuple[LaunchDescription, dict[str, str]] | None:
    """Load the launch file (None: printed with ``--print``)."""
    from visnav.launch.loader import find_package_launch_file, load_launch, parse_launch_args

    launch_args = _late_options(args)
    packages = parse_packages(args.package)
    file: str | Path = args.file
    if launch_args and ":=" not in launch_args[0] and not Path(args.file).is_file():
        # roslaunch PACKAGE FILE [args]
        file = find_package_launch_file(args.file, launch_args[0], packages=packages)
        launch_args = launch_args[1:]
    given = parse_launch_args(launch_args)
    description = load_launch(file, given, packages=packages, skip_unmapped=args.skip_unmapped)
    out = scenario_output_arg(description.args, given, [n.executable for n in description.nodes])
    if out and not args.print_only:  # a scenario: its summary goes where `visnav run`'s would
        given = {**given, "out": out}
        description = load_launch(file, given, packages=packages, skip_unmapped=args.skip_unmapped)
    if args.skip_missing_models:
        description.nodes = [
            replace(node, params={**node.params, "skip_missing_models": True})
            if node.executable == "sim"
            else node
            for node in description.nodes
        ]
    if args.print_only:
        print(description.dumps() if args.json else description.format())
        return None
    from visnav.launch.sim_clock import follow_running_clock

    clock_note = follow_running_clock(description, domain=args.domain)
    if clock_note:
        description.notes.append(clock_note)
    return description, given


def _launch(args: argparse.Namespace, description: LaunchDescription, given: dict[str, str]) -> int:
    """Run the launch until it ends, Ctrl-C or SIGTERM; write a scenario's status."""
    from visnav.launch.supervisor import Launcher

    for note in description.notes:  # what the import mapped or left out: expected, not faults
        _LOG.info("%s", note)
    launcher = Launcher(
        description,
        domain=args.domain,
        sigterm_timeout=args.sigterm_timeout,
        sigkill_timeout=args.sigterm_timeout,
    )
    interrupted: list[int] = []

    def on_signal(signum: int, frame: FrameType | None) -> None:
        del frame
        interrupted.append(signum)
        launcher.request_stop()

    out_dir = given.get("out", "") if "out" in description.args else ""
    log_file = None
    created = bool(out_dir) and not Path(out_dir).exists()
    if out_dir:  # a scenario's folder gets the launch's whole log (DEBUG included)
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        log_file = add_log_file(Path(out_dir) / "run.log")
    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with kernel_compilation_notice():
            code = launcher.run()
    except Exception:
        if created and not (Path(out_dir) / "summary.json").exists():  # refused: no folder
            if log_file is not None:
                remove_log_file(log_file)
            remove_refused_output(Path(out_dir), existed=False)
        raise
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if log_file is not None:
            remove_log_file(log_file)
    reason = (
        f"{signal.Signals(interrupted[0]).name} (Ctrl-C)"
        if interrupted and interrupted[0] == signal.SIGINT
        else signal.Signals(interrupted[0]).name
        if interrupted
        else launcher.end_reason or "every node ended"
    )
    code = 128 + interrupted[0] if interrupted else code  # 130 after Ctrl-C, 143 after SIGTERM
    _LOG.info("launch ended: %s (exit code %d)", reason, code)
    if out_dir:
        status = "interrupted" if interrupted else "failed" if code else "completed"
        written = record_status(out_dir, status, reason=reason)
        if written is not None:
            _LOG.info("summary: %s (status %s)", written, status)
    return code
