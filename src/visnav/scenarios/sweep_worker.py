"""One sweep run in a subprocess of its own: ``python -m visnav.scenarios.sweep_worker DIR``.

``DIR/run.json`` holds the :class:`~visnav.scenarios.sweep_spec.RunSpec`; the worker runs it
exactly as ``visnav run`` does (:func:`~visnav.scenarios.runner.run_scenario`, so the same
``summary.json``, bag and task files land in ``DIR``), in a graph of its own: the in-process
``local`` transport (a scenario needs no other process) with the run's private domain.
Its output goes to ``DIR/run.log``. A run in its own process group is isolated: a crash,
a hang killed at the timeout or a SIGKILL ends that run only, and the worker ends itself
when its parent (the sweep, or a Ray task) dies.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO, Any

from visnav.scenarios.sweep_spec import RunSpec

__all__ = ["RunResult", "finish_run", "kill_group", "run_blocking", "start_run"]

LOG_NAME = "run.log"
SPEC_NAME = "run.json"


@dataclasses.dataclass
class RunResult:
    """How one run ended: ``ok`` with its summary, or ``failed`` with the reason."""

    key: str
    status: str
    reason: str | None = None
    summary: dict[str, Any] | None = None
    wall_s: float = 0.0
    node: str = dataclasses.field(default_factory=socket.gethostname)


def start_run(spec: RunSpec, run_dir: Path) -> tuple[subprocess.Popen[bytes], IO[bytes]]:
    """Clear ``run_dir``, write its ``run.json`` and start the worker process on it.

    Returns:
        The process (leader of its own process group) and its open log file.
    """
    if run_dir.exists():
        shutil.rmtree(run_dir)
    run_dir.mkdir(parents=True)
    (run_dir / SPEC_NAME).write_text(json.dumps(spec.to_json(), indent=2) + "\n")
    log = (run_dir / LOG_NAME).open("wb")
    env = {**os.environ, "VISNAV_DOMAIN": str(spec.domain), "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "visnav.scenarios.sweep_worker", str(run_dir)],
        stdout=log,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        env=env,
        start_new_session=True,
    )
    return proc, log


def kill_group(proc: subprocess.Popen[bytes]) -> None:
    """SIGKILL the worker's process group and reap the worker."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def _last_line(log: Path) -> str:
    try:
        lines = [ln for ln in log.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1].strip()[:300] if lines else ""


def finish_run(
    spec: RunSpec, run_dir: Path, returncode: int, wall_s: float, *, timed_out: float | None
) -> RunResult:
    """The result of a worker that ended with ``returncode`` (negative: killed by a signal)."""
    log = run_dir / LOG_NAME
    if timed_out is not None:
        reason = f"timeout: still running after {timed_out:g} s (killed; log {log})"
        return RunResult(spec.key, "failed", reason, wall_s=wall_s)
    if returncode < 0:
        name = signal.Signals(-returncode).name if -returncode in signal.valid_signals() else ""
        reason = f"killed by signal {name or -returncode} (log {log})"
        return RunResult(spec.key, "failed", reason, wall_s=wall_s)
    summary_path = run_dir / "summary.json"
    if returncode != 0 or not summary_path.is_file():
        last = _last_line(log) or "no output"
        reason = f"exit code {returncode}: {last} (log {log})"
        return RunResult(spec.key, "failed", reason, wall_s=wall_s)
    try:
        summary = json.loads(summary_path.read_text())
    except (OSError, ValueError) as exc:
        reason = f"unreadable {summary_path}: {exc}"
        return RunResult(spec.key, "failed", reason, wall_s=wall_s)
    return RunResult(spec.key, "ok", None, summary=summary, wall_s=wall_s)


def run_blocking(spec: RunSpec, run_dir: Path, *, timeout_s: float | None) -> RunResult:
    """Run ``spec`` in a worker process, wait for it (at most ``timeout_s``), return the result."""
    t0 = time.monotonic()
    proc, log = start_run(spec, run_dir)
    timed_out: float | None = None
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        timed_out = timeout_s
    finally:
        if proc.returncode is None:
            kill_group(proc)
        log.close()
    return finish_run(spec, run_dir, proc.returncode, time.monotonic() - t0, timed_out=timed_out)


def _exit_with_parent() -> None:
    parent = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(1.0)
            if os.getppid() != parent:
                os._exit(3)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _say(line: str) -> None:
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def main(argv: list[str]) -> int:
    """Run the spec in ``argv[0]/run.json``; 0 on success, 1 on a visnav error."""
    from visnav.errors import VisnavError  # noqa: PLC0415 - keep the module light
    from visnav.graph.context import Context  # noqa: PLC0415
    from visnav.scenarios.runner import run_scenario  # noqa: PLC0415

    _exit_with_parent()
    run_dir = Path(argv[0])
    spec = RunSpec.from_json(json.loads((run_dir / SPEC_NAME).read_text()))
    _say(
        f"visnav sweep worker pid {os.getpid()} on {socket.gethostname()}: {spec.scenario} "
        f"{spec.setting} seed {spec.seed}, domain {spec.domain}"
    )
    try:
        with Context(spec.domain, transport="local") as ctx:
            summary = run_scenario(
                spec.scenario,
                out=run_dir,
                context=ctx,
                progress=None,
                log_file=False,  # this process's output is the run's run.log already
                **spec.run_kwargs(),
            )
    except VisnavError as exc:
        _say(f"error: {exc}")
        return 1
    _say(f"done: sim {summary['sim_duration_s']} s in {summary['wall_duration_s']} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
