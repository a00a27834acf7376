"""How a scenario run ends: Ctrl-C, the run's status and the folder of a refused run.

* :class:`RunInterrupt`: the SIGINT and SIGTERM handler of ``visnav run``. The first
  Ctrl-C (or SIGTERM: ``kill PID``, a CI timeout, ``docker stop``, systemd) asks the run
  to stop at the next simulation step; the run then stops its nodes, closes the bag,
  writes ``summary.json`` with ``"status": "interrupted"``, ``end_reason`` naming the
  signal and what was measured so far, and the command prints the summary and exits
  ``128 + signal`` (130 after Ctrl-C, 143 after SIGTERM). A second signal stops at once
  (``KeyboardInterrupt``); the summary is still written from what there is. This is
  ``ros2 launch``'s escalation: a first SIGINT is a request, not a kill.
* :data:`STATUSES`: ``completed`` (the duration ran out or the task was done),
  ``interrupted`` (Ctrl-C or SIGTERM), ``failed`` (an error after the run started, or a required
  node exited; ``error`` says which).
* :func:`remove_refused_output`: a run refused before it started (a bad argument, an
  unknown world) leaves no output folder behind, if the run made it.
* ``visnav launch`` of a scenario file (one with a ``scenario_observer`` and an ``out``
  arg) writes its summary where ``visnav run`` would (:func:`scenario_output_arg`,
  ``runs/<UTC time>`` unless ``out:=`` is given) and adds the ``status``
  (:func:`record_status`).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import shutil
import signal
import threading
from collections.abc import Iterator
from pathlib import Path
from types import FrameType
from typing import Any

__all__ = [
    "STATUSES",
    "RunInterrupt",
    "default_output_dir",
    "record_status",
    "remove_refused_output",
    "scenario_output_arg",
]

STATUSES = ("completed", "interrupted", "failed")
"""The values of ``summary.json``'s ``status``."""


class RunInterrupt:
    """Ctrl-C (or SIGTERM) of a scenario run (see the module docstring).

    Attributes:
        requested: True once a SIGINT or SIGTERM arrived (or :meth:`request` was called).
        count: stop signals received.
        signum: the first stop signal received (0: none, or :meth:`request` was called).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)
    """The signals :meth:`installed` handles."""

    def __init__(self) -> None:
        self.requested = False
        self.count = 0
        self.signum = 0
        self._targets: list[Any] = []

    @property
    def reason(self) -> str:
        """How the run was stopped: ``SIGINT (Ctrl-C)``, ``SIGTERM`` or ``stop requested``."""
        if not self.signum:
            return "stop requested"
        name = signal.Signals(self.signum).name
        return f"{name} (Ctrl-C)" if self.signum == signal.SIGINT else name

    @property
    def exit_code(self) -> int:
        """``128 + signal`` (130 after Ctrl-C, 143 after SIGTERM; 130 without a signal)."""
        return 128 + (self.signum or int(signal.SIGINT))

    def __call__(self) -> bool:
        """The stop predicate for ``run_lockstep(..., until=)``: True once requested."""
        return self.requested

    def attach(self, launcher: Any) -> None:
        """Have a request stop ``launcher`` too (its :meth:`request_stop`), now if made."""
        self._targets.append(launcher)
        if self.requested:
            launcher.request_stop()

    def request(self) -> None:
        """Ask the run to stop at the next step (what the first Ctrl-C does)."""
        self.requested = True
        for target in self._targets:
            target.request_stop()

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        del frame
        self.count += 1
        if self.requested:  # the second Ctrl-C (or SIGTERM): stop now
            raise KeyboardInterrupt
        self.signum = self.signum or int(signum)
        self.request()

    @contextlib.contextmanager
    def installed(self) -> Iterator[RunInterrupt]:
        """Handle SIGINT and SIGTERM with this object inside the block (main thread only)."""
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        previous = {sig: signal.signal(sig, self._on_signal) for sig in self.SIGNALS}
        try:
            yield self
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)


def remove_refused_output(out_dir: Path, *, existed: bool) -> None:
    """Remove the output folder of a run refused before it started, if the run made it."""
    if not existed:
        shutil.rmtree(out_dir, ignore_errors=True)


def default_output_dir() -> Path:
    """``runs/<UTC time>``: where a run writes when no output directory is given."""
    stamp = _dt.datetime.now(tz=_dt.timezone.utc).strftime("%Y%m%d-%H%M%S")
    return Path("runs") / stamp


def scenario_output_arg(declared: Any, given: dict[str, str], executables: list[str]) -> str:
    """The ``out`` to add to a scenario launch's arguments ('' when none is to be added).

    Args:
        declared: the launch file's declared args (``LaunchDescription.args``).
        given: the arguments given on the command line.
        executables: the launch's node executables (a scenario has ``scenario_observer``).
    """
    if "out" not in declared or given.get("out") or "scenario_observer" not in executables:
        return ""
    return str(default_output_dir().absolute())


def record_status(out_dir: str | Path, status: str, *, reason: str = "") -> Path | None:
    """Add ``status`` (and ``end_reason``) to the ``summary.json`` in ``out_dir``.

    Returns:
        The summary's path, or None when there is none (or it does not read).
    """
    path = Path(out_dir) / "summary.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict):
        return None
    data = {"status": status, **({"end_reason": reason} if reason else {}), **data}
    data["status"] = status
    tmp = path.with_name("summary.json.tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    tmp.replace(path)
    return path
