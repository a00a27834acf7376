"""The live viewer in a process of its own: what ``visnav run --view`` starts beside a run.

A viewer in the simulation's process competes with it for the GIL (TF placement, image
encoding, Rerun's logging calls), so ``visnav run --view`` starts
``python -m visnav.viz.view_process`` instead: it joins the run's graph domain over Zenoh,
as ``visnav view`` does, and streams it to the web viewer through a
:class:`~visnav.viz.live_view.LiveView` whose display-rated subscriptions are paced
(:mod:`visnav.viz.paced_feed`: the run's publishers serialize only the messages shown).
The simulation's process then does no viewer work beyond sending those messages.

The child's life follows the run's: :class:`ViewProcess` starts it and waits until it
serves (its one line on stdout: the page's address, or why it could not start, e.g. a
port in use); :meth:`ViewProcess.close` closes its stdin, and the child ends on that
end of file, closing the web viewer's server (no port left bound). It also ends on
SIGTERM, and on its parent's death (``prctl(PR_SET_PDEATHSIG)`` on Linux, and the end of
file of its stdin everywhere), so a run killed with SIGKILL leaves no viewer behind. It runs
in a session of its own: a terminal's Ctrl-C reaches the run, which stops the child in
order, and at a lower priority (:data:`NICE`): a busy machine's CPU goes to the simulation
first. Everything the child and the web viewer's server log goes to the log file (the
run's ``viewer.log``), never to the terminal.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib.util
import json
import logging
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import FrameType
from typing import IO, Any

from visnav.viz.errors import RerunMissingError, VizError
from visnav.viz.ports import (
    DEFAULT_GRPC_PORT,
    DEFAULT_MEMORY_LIMIT,
    DEFAULT_WEB_PORT,
    check_ports,
    die_with_parent,
)

__all__ = ["NICE", "ViewPorts", "ViewProcess", "main", "parse_ready", "peak_rss_mb"]

_LOG = logging.getLogger("visnav.viz")

STARTUP_TIMEOUT_S = 120.0
"""How long :class:`ViewProcess` waits for the child to serve (imports on a loaded machine)."""

NICE = 10
"""The viewer process's niceness increment: on a busy machine the simulation's process
(niceness 0) gets the CPU first, and the viewer shows fewer frames instead of slowing the
run down (its web viewer's server inherits it)."""

STOP_TIMEOUT_S = 20.0
"""How long :meth:`ViewProcess.close` waits for the child to end before SIGTERM, SIGKILL."""


@dataclasses.dataclass(frozen=True)
class ViewPorts:
    """The web viewer's ports (``--port``, ``--grpc-port``; 0: a free one)."""

    port: int = DEFAULT_WEB_PORT
    grpc_port: int = DEFAULT_GRPC_PORT

    def check(self) -> None:
        """Refuse ports that are taken, equal or out of range, and a missing Rerun SDK.

        Raises:
            VizError: naming the port and the option that changes it.
            RerunMissingError: the viewer extra is not installed.
        """
        if importlib.util.find_spec("rerun") is None:
            raise RerunMissingError
        check_ports(self.port, self.grpc_port)


def peak_rss_mb(pid: int) -> float | None:
    """A process's peak resident memory (``VmHWM``, MB), None where ``/proc`` does not tell."""
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return None


def parse_ready(line: bytes) -> tuple[str, str | None]:
    """The viewer process's start-up line: ``(page URL, gRPC URL)``.

    Raises:
        VizError: the line is the child's reason for not serving (a port in use, no Rerun
            SDK), or not a start-up line (the child ended without one).
    """
    try:
        ready = json.loads(line) if line.strip() else None
    except (json.JSONDecodeError, UnicodeDecodeError):
        ready = None
    if isinstance(ready, dict) and isinstance(ready.get("error"), str):
        raise VizError(ready["error"])
    if not isinstance(ready, dict) or not isinstance(ready.get("url"), str):
        text = f"the viewer process did not start (its first line: {line[:200]!r})"
        raise VizError(text)
    grpc = ready.get("grpc_url")
    return ready["url"], grpc if isinstance(grpc, str) else None


class ViewProcess:
    """Starts the viewer process for a graph domain and waits until it serves; close it.

    Args:
        domain: the graph domain of the run.
        log_path: the child's and the web viewer's log (created or appended to).
        ports: the web viewer's ports.
        save: also write this ``.rrd`` file (the child writes it).
        memory_limit: what the web viewer's server keeps for late pages.
        sensors_in_use_only: show camera images and clouds only while another node uses
            them (see :class:`~visnav.viz.live_view.LiveView`).
        startup_timeout_s: how long to wait for the child to serve.

    Raises:
        VizError: the child could not serve (its reason: a port in use, no Rerun SDK), or
            did not within ``startup_timeout_s``.
    """

    def __init__(
        self,
        domain: int,
        log_path: str | Path,
        *,
        ports: ViewPorts | None = None,
        save: str | Path | None = None,
        memory_limit: str = DEFAULT_MEMORY_LIMIT,
        sensors_in_use_only: bool = True,
        startup_timeout_s: float = STARTUP_TIMEOUT_S,
    ) -> None:
        ports = ports or ViewPorts()
        self.log_path = Path(log_path)
        cmd = [sys.executable, "-m", "visnav.viz.view_process", "--domain", str(domain)]
        cmd += ["--port", str(ports.port), "--grpc-port", str(ports.grpc_port)]
        cmd += ["--log", str(self.log_path), "--memory-limit", memory_limit]
        if save is not None:
            cmd += ["--save", str(save)]
        if not sensors_in_use_only:
            cmd.append("--all-sensors")
        self.url: str | None = None
        self.grpc_url: str | None = None
        self._closed = False
        try:
            with self.log_path.open("ab") as log:  # the child keeps its own descriptor
                self.process = subprocess.Popen(
                    cmd,
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    stderr=log,
                    env={**os.environ, "VISNAV_DOMAIN": str(domain), "NO_COLOR": "1"},
                    start_new_session=True,  # a terminal's Ctrl-C goes to the run only
                    preexec_fn=die_with_parent(),  # noqa: PLW1509 - one prctl call, looked up before
                )
        except OSError as exc:
            text = f"the viewer process could not start (log {self.log_path}): {exc}"
            raise VizError(text) from exc
        try:
            self._wait_ready(startup_timeout_s)
        except BaseException:
            self._kill()
            raise

    @property
    def pid(self) -> int:
        """The child's process id."""
        return self.process.pid

    def _wait_ready(self, timeout_s: float) -> None:
        stdout = self.process.stdout
        if stdout is None:  # Popen(stdout=PIPE) makes it
            raise VizError("the viewer process has no stdout pipe")
        lines: queue.Queue[bytes] = queue.Queue()
        reader = threading.Thread(
            target=lambda: lines.put(stdout.readline()), name="visnav-view-ready", daemon=True
        )
        reader.start()
        try:
            line = lines.get(timeout=timeout_s)
        except queue.Empty:
            text = (
                f"the viewer process did not start within {timeout_s:g} s (a loaded machine?); "
                f"its log is {self.log_path}"
            )
            raise VizError(text) from None
        try:
            self.url, self.grpc_url = parse_ready(line)
        except VizError as exc:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.process.wait(timeout=10)
            text = f"{exc}; exit code {self.process.returncode}, log {self.log_path}"
            raise VizError(text) from None

    def alive(self) -> bool:
        """Whether the child still runs."""
        return self.process.poll() is None

    def close(self, timeout_s: float = STOP_TIMEOUT_S) -> int | None:
        """Stop the child (end of file on its stdin, then SIGTERM, then SIGKILL); idempotent.

        Returns:
            The child's exit code (None if it had to be killed and did not report one).
        """
        if self._closed:
            return self.process.returncode
        self._closed = True
        rss = peak_rss_mb(self.process.pid)
        with contextlib.suppress(OSError):
            if self.process.stdin is not None:
                self.process.stdin.close()
        try:
            self.process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            _LOG.warning("viewer: the viewer process did not end in %g s: terminated", timeout_s)
            self._signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self._kill()
        if self.process.stdout is not None:
            self.process.stdout.close()
        _LOG.debug(
            "viewer: process %d ended with %s, peak RSS %s MB",
            self.process.pid,
            self.process.returncode,
            "?" if rss is None else f"{rss:.0f}",
        )
        return self.process.returncode

    def _signal(self, signum: int) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.process.pid, signum)  # the child and its web viewer's server

    def _kill(self) -> None:
        self._signal(signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(timeout=5)


class _Stop:
    """Set by SIGTERM, SIGHUP or the end of file of stdin (the parent closed it or died)."""

    def __init__(self) -> None:
        self.event = threading.Event()

    def on_signal(self, signum: int, frame: FrameType | None) -> None:
        del signum, frame
        self.event.set()

    def watch(self, stream: IO[bytes]) -> None:
        def read() -> None:
            with contextlib.suppress(OSError, ValueError):
                while stream.read(4096):
                    pass
            self.event.set()

        threading.Thread(target=read, name="visnav-view-stdin", daemon=True).start()


def _say(out: IO[str], **fields: Any) -> None:
    out.write(json.dumps(fields) + "\n")
    out.flush()


def main(argv: list[str] | None = None) -> int:
    """The child: serve the viewer for a graph domain until stopped (see the module doc)."""
    parser = argparse.ArgumentParser(prog="python -m visnav.viz.view_process")
    parser.add_argument("--domain", type=int, required=True)
    parser.add_argument("--port", type=int, default=DEFAULT_WEB_PORT)
    parser.add_argument("--grpc-port", type=int, default=DEFAULT_GRPC_PORT)
    parser.add_argument("--log", required=True)
    parser.add_argument("--memory-limit", default=DEFAULT_MEMORY_LIMIT)
    parser.add_argument("--save", default=None)
    parser.add_argument("--all-sensors", action="store_true")
    args = parser.parse_args(argv)
    stop = _Stop()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the run stops this process in order
    signal.signal(signal.SIGTERM, stop.on_signal)
    signal.signal(signal.SIGHUP, stop.on_signal)
    stop.watch(sys.stdin.buffer)
    with contextlib.suppress(OSError):
        os.nice(NICE)
    out = sys.stdout
    sys.stdout = sys.stderr  # anything else printed goes to the log, as stderr does
    from visnav.logsetup import add_log_file  # noqa: PLC0415 - the child's start-up

    handler = add_log_file(args.log)
    logging.captureWarnings(True)
    try:
        return _serve(args, stop, out)
    finally:
        logging.getLogger().removeHandler(handler)
        handler.close()


def _serve(args: argparse.Namespace, stop: _Stop, out: IO[str]) -> int:
    from visnav.graph.context import Context  # noqa: PLC0415 - the child's start-up
    from visnav.graph.introspect import wait_for_discovery  # noqa: PLC0415

    try:
        from visnav.viz.live_view import LiveView  # noqa: PLC0415
    except RerunMissingError as exc:
        _say(out, error=str(exc))
        return 2
    with Context(args.domain) as ctx:
        try:
            view = LiveView(
                ctx,
                port=args.port,
                grpc_port=args.grpc_port,
                save=args.save,
                memory_limit=args.memory_limit,
                log_path=args.log,
                sensors_in_use_only=not args.all_sensors,
                paced=True,
            )
        except VizError as exc:
            _say(out, error=str(exc))
            return 2
        try:
            wait_for_discovery(ctx)
            view.poll()
            _say(out, url=view.url, grpc_url=view.viewer.grpc_url, pid=os.getpid())
            started = time.monotonic()
            while not stop.event.is_set():
                view.spin_once(0.05)
            _LOG.debug("viewer: served %.1f s", time.monotonic() - started)
        finally:
            _close(view)
    return 0


def _close(view: Any) -> None:
    import resource  # noqa: PLC0415 - POSIX

    server = view.viewer.web_process
    server_rss = peak_rss_mb(server.pid) if server is not None else None
    view.close()
    own = peak_rss_mb(os.getpid())
    usage = resource.getrusage(resource.RUSAGE_SELF)
    _LOG.info(
        "viewer: peak RSS of the viewer process %s MB, of the web viewer's server %s MB; "
        "viewer process CPU %.2f s",
        "?" if own is None else f"{own:.0f}",
        "?" if server_rss is None else f"{server_rss:.0f}",
        usage.ru_utime + usage.ru_stime,
    )


if __name__ == "__main__":
    sys.exit(main())
