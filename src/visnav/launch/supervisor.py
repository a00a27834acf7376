"""Start a :class:`LaunchDescription`: shared nodes in this process, the others in their own.

* ``process: shared`` nodes are built in the launch process on one
  :class:`~visnav.graph.Context` (in-process, zero-copy delivery between them) and
  spun by :meth:`Launcher.run` in the thread that calls it.
* ``process: own`` nodes each run in a child ``python -m visnav.launch.runner SPEC``
  (its own Context, same domain) and talk to the rest over the graph (Zenoh).
* A child that exits is reported with its exit code (or signal); with ``respawn``
  it is started again after ``respawn_delay`` (at most ``respawn_max_retries``
  times); a ``required`` node that exits stops the whole launch.
* An exception in a node's callback is logged and the node keeps running
  (``on_error: log``, the default, as rospy). ``on_error: restart`` ends the node's
  process on such an exception and restarts it as ``respawn`` does;
  ``on_error: shutdown`` stops the launch (exit code 1) as ``required`` does, for a
  shared node as for an ``own`` one.
* A shared ``sim`` node with ``lockstep: true`` is the shared process's executor loop
  (:meth:`Launcher.lockstep_driver`): the simulation advances step by step and the shared
  nodes react at each step's sim time, as in ``visnav run``; the launch ends when its
  ``duration`` is over. A shared node that calls ``sys.exit(n)`` in a callback ends the
  launch with exit code ``n`` (the scenario observer does when its task is done).
* :meth:`Launcher.request_stop` (the CLI's SIGINT handler) stops everything: children
  get SIGINT, then SIGTERM after ``sigterm_timeout`` and SIGKILL after
  ``sigkill_timeout`` more seconds, as ros2 launch does. Children are in their own
  session (the terminal's Ctrl-C reaches only the launcher, which stops them in
  order) and die with the launcher if it is killed (``PR_SET_PDEATHSIG`` on Linux).
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import logging
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from visnav.errors import VisnavError
from visnav.graph.faults import CallbackError
from visnav.launch.description import LaunchDescription, NodeSpec
from visnav.launch.errors import LaunchProcessError
from visnav.launch.param_check import report_unknown_parameters
from visnav.node_registry import (
    UnknownNodeError,
    check_node_name,
    resolve_node_class,
)

__all__ = ["Launcher", "ProcessEvent", "check_executables", "describe_exit"]

_LOG = logging.getLogger("visnav.launch")
_POLL_S = 0.02
_SPIN_S = 0.05
_LOCKSTEP_SLICE_S = 0.1  # sim seconds between supervision polls of a lock-step launch


@dataclass(frozen=True)
class ProcessEvent:
    """Something that happened to a node process.

    Attributes:
        name: the node's fully qualified name.
        kind: ``started``, ``exited``, ``respawning``, ``gave_up`` or ``stopped``.
        pid: the process id.
        returncode: the exit code (negative: killed by that signal), for exits.
        restarts: how many times the node had been restarted at that point.
        time: ``time.monotonic()`` of the event.
    """

    name: str
    kind: str
    pid: int
    returncode: int | None
    restarts: int
    time: float


def describe_exit(returncode: int) -> str:
    """``exited with code 3`` / ``was killed by SIGSEGV``."""
    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            name = f"signal {-returncode}"
        return f"was killed by {name}"
    return f"exited with code {returncode}"


def _at(spec: NodeSpec) -> str:
    return f"{spec.source}: " if spec.source else ""


def check_executables(description: LaunchDescription) -> dict[str, type[Any]]:
    """Check every node's executable before anything starts; import the shared ones.

    Returns:
        fully qualified name -> class, for the shared nodes.

    Raises:
        UnknownNodeError: an unknown name (closest suggested) or a module that does not exist.
    """
    classes: dict[str, type[Any]] = {}
    for spec in description.nodes:
        at = _at(spec)
        try:
            kind = check_node_name(spec.executable)
            if spec.process == "shared":
                classes[spec.fqn] = resolve_node_class(spec.executable)
            elif kind == "path":
                module = spec.executable.partition(":")[0]
                try:
                    found = importlib.util.find_spec(module)
                except (ImportError, ValueError):
                    found = None
                if found is None:
                    msg = (
                        f"node {spec.executable!r}: module {module!r} is not importable; check "
                        "the name and PYTHONPATH"
                    )
                    raise UnknownNodeError(msg)
        except UnknownNodeError as exc:
            raise type(exc)(f"{at}{exc}") from None
    return classes


class _Child:
    """One ``own`` node process and its restart bookkeeping."""

    def __init__(self, spec: NodeSpec, spec_file: Path) -> None:
        self.spec = spec
        self.name = spec.fqn
        self.spec_file = spec_file
        self.popen: subprocess.Popen[bytes] | None = None
        self.restarts = 0
        self.respawn_at: float | None = None
        self.done = False
        self.last_code: int | None = None


class Launcher:
    """Runs a launch description (see the module docstring).

    Args:
        description: what to start.
        domain: graph domain for every node (default ``VISNAV_DOMAIN`` or 0).
        env: environment of the child processes (default ``os.environ``).
        sigterm_timeout: seconds between SIGINT and SIGTERM at shutdown.
        sigkill_timeout: seconds between SIGTERM and SIGKILL at shutdown.
        python: interpreter for child processes.
        context: the :class:`~visnav.graph.Context` of the shared nodes (default: a new one
            in ``domain``); :meth:`shutdown` shuts it down either way.
    """

    def __init__(
        self,
        description: LaunchDescription,
        *,
        domain: int | str | None = None,
        env: Mapping[str, str] | None = None,
        sigterm_timeout: float = 5.0,
        sigkill_timeout: float = 5.0,
        python: str = sys.executable,
        context: Any = None,
    ) -> None:
        self.description = description
        self._given_context = context
        self.domain = domain
        self.env = dict(os.environ if env is None else env)
        if domain is not None:
            self.env["VISNAV_DOMAIN"] = str(domain)
        self.env.setdefault("PYTHONUNBUFFERED", "1")
        self.sigterm_timeout = sigterm_timeout
        self.sigkill_timeout = sigkill_timeout
        self.python = python
        self.events: list[ProcessEvent] = []
        self.context: Any = None
        self.shared_nodes: list[Any] = []
        self._children: list[_Child] = []
        self._tmp: Path | None = None
        self._stop = False
        self._force = False
        self._failed = False
        self._exit_request: int | None = None
        self.end_reason = ""
        """Why :meth:`run` ended, for its last log line (``duration reached``, ...)."""
        self._started = False
        self._shut = False
        self._events_lock = threading.Lock()

    # ---------------------------------------------------------------- control
    def request_stop(self) -> None:
        """Ask :meth:`run` to stop everything (safe from a signal handler: sets flags only)."""
        if self._stop:
            self._force = True
        self._stop = True
        if not self.end_reason:
            self.end_reason = "stop requested"

    @property
    def stopping(self) -> bool:
        """True once the launch is stopping (a stop request, a required node exited)."""
        return self._stop

    @property
    def pids(self) -> dict[str, int]:
        """Fully qualified node name -> pid of the running ``own`` processes."""
        return {c.name: c.popen.pid for c in self._children if c.popen is not None}

    def _event(self, child: _Child, kind: str, pid: int, code: int | None) -> None:
        with self._events_lock:
            self.events.append(
                ProcessEvent(child.name, kind, pid, code, child.restarts, time.monotonic())
            )

    # ---------------------------------------------------------------- start
    def start(self) -> None:
        """Check every node, start the ``own`` processes, build the shared nodes.

        Raises:
            UnknownNodeError: an executable is unknown or not built yet (nothing started).
            LaunchProcessError: a process could not be started or a shared node failed to
                build (everything started so far is stopped again).
        """
        if self._started:
            return
        self._started = True
        classes = check_executables(self.description)
        self._tmp = Path(tempfile.mkdtemp(prefix="visnav-launch-"))
        try:
            for index, spec in enumerate(self.description.nodes):
                if spec.process != "own" or self._stop:  # a stop request ends the start-up
                    continue
                spec_file = self._tmp / f"{index:03d}.json"
                spec_file.write_text(
                    json.dumps(
                        {
                            "label": spec.fqn,
                            "parent_pid": os.getpid(),
                            "domain": self.domain,
                            "nodes": [spec.to_json()],
                        }
                    )
                )
                child = _Child(spec, spec_file)
                self._children.append(child)
                self._spawn(child)
            self._build_shared(classes)
        except BaseException:
            self.shutdown()
            raise

    def _spawn(self, child: _Child) -> None:
        try:
            popen = subprocess.Popen(
                [self.python, "-m", "visnav.launch.runner", str(child.spec_file)],
                env=self.env,
                start_new_session=True,
            )
        except OSError as exc:
            msg = f"{_at(child.spec)}cannot start a process for {child.name}: {exc}"
            raise LaunchProcessError(msg) from exc
        child.popen = popen
        child.respawn_at = None
        self._event(child, "started", popen.pid, None)
        _LOG.info("started %s [%s] (pid %d)", child.name, child.spec.executable, popen.pid)

    def _build_shared(self, classes: Mapping[str, type[Any]]) -> None:
        shared = [s for s in self.description.nodes if s.process == "shared"]
        if not shared:
            return
        from visnav.graph.context import Context  # noqa: PLC0415 - only with shared nodes

        self.context = self._given_context or Context(self.domain)
        for spec in shared:
            if self._stop:  # Ctrl-C during the start-up: build no more nodes
                _LOG.debug("start-up stopped before %s", spec.fqn)
                return
            try:
                node = classes[spec.fqn](spec.name, context=self.context, **spec.node_kwargs())
            except VisnavError as exc:
                msg = f"{_at(spec)}node {spec.fqn} [{spec.executable}] failed to start: {exc}"
                raise LaunchProcessError(msg) from exc
            self.shared_nodes.append(node)
            report_unknown_parameters(
                node, spec.params, where=spec.source, executable=spec.executable
            )
            if spec.on_error == "shutdown":
                self.context.set_error_policy(node.get_fully_qualified_name(), "raise")
        names = ", ".join(s.fqn for s in shared)
        _LOG.info(
            "started %d shared node(s) in this process (pid %d): %s",
            len(shared),
            os.getpid(),
            names,
        )

    # ---------------------------------------------------------------- supervise
    def poll(self) -> None:
        """Reap exited children, report them, schedule and perform restarts."""
        now = time.monotonic()
        for child in self._children:
            popen = child.popen
            if popen is not None:
                code = popen.poll()
                if code is None:
                    continue
                child.popen = None
                child.last_code = code
                self._exited(child, popen.pid, code, now)
            elif child.respawn_at is not None and now >= child.respawn_at and not self._stop:
                child.restarts += 1
                self._spawn(child)

    def _exited(self, child: _Child, pid: int, code: int, now: float) -> None:
        self._event(child, "exited", pid, code)
        if self._stop:
            return
        spec = child.spec
        log = _LOG.info if code == 0 else _LOG.error
        log("%s (pid %d) %s", child.name, pid, describe_exit(code))
        if spec.required or spec.on_error == "shutdown":
            why = "is required" if spec.required else "has on_error: shutdown"
            _LOG.error("%s %s: stopping the launch", child.name, why)
            self.end_reason = f"{child.name} {describe_exit(code)} and {why}"
            self._failed = True
            child.done = True
            self._stop = True
            return
        retries = spec.respawn_max_retries
        respawn = spec.respawn or spec.on_error == "restart"
        if respawn and (retries is None or child.restarts < retries):
            child.respawn_at = now + spec.respawn_delay
            limit = "" if retries is None else f" of {retries}"
            _LOG.info(
                "restarting %s in %.3g s (restart %d%s)",
                child.name,
                spec.respawn_delay,
                child.restarts + 1,
                limit,
            )
            self._event(child, "respawning", pid, code)
            return
        if respawn:
            _LOG.error(
                "%s will not be restarted: respawn_max_retries (%s) reached", child.name, retries
            )
            self._event(child, "gave_up", pid, code)
        child.done = True

    def _finished(self) -> bool:
        if self.context is not None:
            return False
        return all(c.done for c in self._children)

    def lockstep_driver(self) -> Any:
        """The shared node that drives the launch lock-step, or None.

        A shared node with ``lockstep`` true and a ``run_lockstep(slice_s, until=)``
        method (the ``sim`` node with ``lockstep: true``) is the executor loop of the
        shared process: :meth:`run` advances it a slice at a time.
        """
        for node in self.shared_nodes:
            if getattr(node, "lockstep", False) and callable(getattr(node, "run_lockstep", None)):
                return node
        return None

    @property
    def exit_code(self) -> int:
        """1 if a required node died or a node process ended with an error, else 0.

        A shared node that ended the launch with ``sys.exit(n)`` from a callback gives ``n``.
        """
        if self._exit_request is not None:
            return self._exit_request
        if self._failed:
            return 1
        if any(c.done and c.last_code not in (0, None) for c in self._children):
            return 1
        return 0

    def run(self, stop: threading.Event | None = None, *, duration_s: float | None = None) -> int:
        """Start (if needed) and supervise until stopped, then shut everything down.

        Args:
            stop: an event another thread sets to stop the launch.
            duration_s: stop after this many seconds.

        Returns:
            :attr:`exit_code`.
        """
        end = None if duration_s is None else time.monotonic() + duration_s

        def stopping() -> bool:
            return self._stop or (stop is not None and stop.is_set())

        try:
            self.start()
            driver = self.lockstep_driver()
            last_poll = 0.0
            while not stopping():
                if end is not None and time.monotonic() >= end:
                    self._ended(f"duration reached ({duration_s:g} s)")
                    break
                if self.context is not None:
                    try:
                        if driver is None:
                            self.context.spin_once(_SPIN_S)
                        elif not driver.run_lockstep(_LOCKSTEP_SLICE_S, until=stopping):
                            if not stopping():  # the lock-step simulation's duration is over
                                self._ended(f"duration reached ({driver.duration_s:g} s sim time)")
                            break
                    except SystemExit as exc:  # a shared node ended the launch (sys.exit)
                        self._exit_request = exc.code if isinstance(exc.code, int) else 1
                        self._ended(f"a node ended the launch (exit code {self._exit_request})")
                        break
                    except CallbackError as exc:
                        _LOG.error("%s has on_error: shutdown: stopping the launch", exc.node_name)
                        self._ended(f"{exc.node_name} failed and has on_error: shutdown")
                        self._failed = True
                        break
                    except Exception:
                        _LOG.error("the shared nodes' executor failed: stopping every node")
                        self._ended("the shared nodes' executor failed")
                        self._failed = True
                        raise
                else:
                    time.sleep(_POLL_S)
                now = time.monotonic()
                if now - last_poll >= _POLL_S:
                    last_poll = now
                    self.poll()
                    if self._finished():
                        self._ended("every node process ended")
                        break
            if stop is not None and stop.is_set():
                self._ended("stop requested")
        finally:
            self.shutdown()
        return self.exit_code

    def _ended(self, reason: str) -> None:
        if not self.end_reason:
            self.end_reason = reason

    # ---------------------------------------------------------------- stop
    def _signal_all(self, sig: signal.Signals) -> None:
        for child in self._children:
            if child.popen is not None and child.popen.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    child.popen.send_signal(sig)

    def _wait_all(self, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while True:
            alive = [c for c in self._children if c.popen is not None and c.popen.poll() is None]
            if not alive:
                return True
            if time.monotonic() >= deadline or self._force:
                return False
            time.sleep(0.01)

    def shutdown(self) -> None:
        """Stop every child (SIGINT, SIGTERM, SIGKILL) and the shared nodes (idempotent)."""
        if self._shut:
            return
        self._shut = True
        self._stop = True
        self._signal_all(signal.SIGINT)
        if self.context is not None:
            self.context.shutdown()
        if not self._wait_all(self.sigterm_timeout):
            for child in self._children:
                if child.popen is not None and child.popen.poll() is None:
                    _LOG.warning("%s did not stop on SIGINT: sending SIGTERM", child.name)
            self._signal_all(signal.SIGTERM)
            if not self._wait_all(self.sigkill_timeout):
                for child in self._children:
                    if child.popen is not None and child.popen.poll() is None:
                        _LOG.warning("%s did not stop on SIGTERM: sending SIGKILL", child.name)
                self._signal_all(signal.SIGKILL)
        for child in self._children:
            if child.popen is not None:
                code = child.popen.wait()
                self._event(child, "stopped", child.popen.pid, code)
                if code not in (0, -signal.SIGINT):
                    _LOG.warning(
                        "%s (pid %d) %s while stopping",
                        child.name,
                        child.popen.pid,
                        describe_exit(code),
                    )
                child.popen = None
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None
