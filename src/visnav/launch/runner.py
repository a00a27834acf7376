"""The process of ``process: own`` nodes: ``python -m visnav.launch.runner SPEC.json``.

The spec (written by :class:`~visnav.launch.supervisor.Launcher`) is
``{"label", "parent_pid", "domain", "nodes": [NodeSpec.to_json(), ...]}``. The
runner builds the nodes on one Context and spins until SIGINT or SIGTERM, then
shuts down and exits 0. A node that fails to build prints ``error: ...`` and
exits 1. An exception in a callback is logged and the node keeps running, unless
the node's ``on_error`` is ``restart`` or ``shutdown``: then the process prints
``error: ...`` and exits 1 (the launcher restarts it or stops the launch);
``SystemExit(n)`` from a node exits ``n``. On Linux the runner also exits when
the launcher dies (``PR_SET_PDEATHSIG``), so a killed launcher leaves no orphans.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import json
import logging
import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from types import FrameType
from typing import Any

from visnav.logsetup import configure_logging, kernel_compilation_notice

__all__ = ["main", "run_nodes"]

_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent_pid: int | None) -> None:
    if parent_pid is None or not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    if os.getppid() != parent_pid:  # the launcher died before prctl took effect
        raise SystemExit(0)


def _interrupt(signum: int, frame: FrameType | None) -> None:
    del signum, frame
    raise KeyboardInterrupt


def run_nodes(specs: Sequence[Any], domain: int | str | None) -> None:
    """Build the nodes of ``specs`` (:class:`NodeSpec`) on one Context and spin until interrupted.

    Raises:
        VisnavError: a node could not be resolved or built.
    """
    from visnav.graph.context import Context  # noqa: PLC0415
    from visnav.launch.param_check import report_unknown_parameters  # noqa: PLC0415
    from visnav.node_registry import resolve_node_class  # noqa: PLC0415

    classes = [resolve_node_class(s.executable) for s in specs]
    with Context(domain) as ctx:
        nodes = [
            cls(s.name, context=ctx, **s.node_kwargs())
            for cls, s in zip(classes, specs, strict=True)
        ]
        for node, s in zip(nodes, specs, strict=True):
            report_unknown_parameters(node, s.params, where=s.source, executable=s.executable)
        for node, spec in zip(nodes, specs, strict=True):
            if spec.on_error != "log":
                ctx.set_error_policy(node.get_fully_qualified_name(), "raise")
        try:
            ctx.spin()
        finally:
            del nodes


def main(argv: Sequence[str] | None = None) -> int:
    """Run the nodes of one spec file; return the exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m visnav.launch.runner SPEC.json", file=sys.stderr)  # noqa: T201
        return 2
    data = json.loads(Path(args[0]).read_text())
    _die_with_parent(data.get("parent_pid"))
    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, _interrupt)
    configure_logging(stream=sys.stderr)  # as the visnav command: library noise filtered
    from visnav.errors import VisnavError  # noqa: PLC0415
    from visnav.launch.description import NodeSpec  # noqa: PLC0415

    specs = [NodeSpec.from_json(n) for n in data["nodes"]]
    try:
        with kernel_compilation_notice():
            run_nodes(specs, data.get("domain"))
    except KeyboardInterrupt:
        return 0
    except VisnavError as exc:
        where = f"{specs[0].source}: " if len(specs) == 1 and specs[0].source else ""
        print(f"error: {where}{data.get('label', '')}: {exc}", file=sys.stderr)  # noqa: T201
        return 1
    return 0


def _exit(code: int) -> None:
    """Leave now that the nodes and the Context are closed.

    A SIGTERM (the launcher died: ``PR_SET_PDEATHSIG``) that lands while the Context is
    opening or closing can leave the Zenoh session open, and with it Zenoh's non-daemon
    callback threads: the interpreter would then wait for them at exit and the child would
    outlive its launcher. Everything a node writes is written by then, so exit at once.
    """
    logging.shutdown()
    with contextlib.suppress(OSError, ValueError):
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    _exit(main())
