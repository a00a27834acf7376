"""The local sweep backend: up to ``jobs`` worker processes at a time on this machine.

Each run is a process of its own (:mod:`visnav.scenarios.sweep_worker`) in a process group
of its own, so a crash, a hang (killed at ``timeout_s``) or a SIGKILL ends that run only.
Results come back as runs finish. Leaving the iteration early (Ctrl-C, an error in the
caller) kills the runs still going; the caller records them as interrupted.
"""

from __future__ import annotations

import collections
import dataclasses
import subprocess
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO

from visnav.scenarios.sweep_spec import RunSpec, SweepError
from visnav.scenarios.sweep_worker import RunResult, finish_run, kill_group, start_run

__all__ = ["LocalBackend"]


@dataclasses.dataclass
class _Running:
    spec: RunSpec
    proc: subprocess.Popen[bytes]
    log: IO[bytes]
    t0: float


class LocalBackend:
    """Runs sweep runs as local processes, ``jobs`` at a time.

    Args:
        jobs: runs at a time (>= 1).
        timeout_s: a run still going after this many wall seconds is killed and failed
            (None: no limit).
        poll_s: how often the processes are checked.
    """

    name = "local"

    def __init__(self, *, jobs: int = 1, timeout_s: float | None = None, poll_s: float = 0.2):
        if jobs < 1:
            msg = f"--jobs is {jobs}: expected at least 1 run at a time"
            raise SweepError(msg)
        self.jobs = jobs
        self.timeout_s = timeout_s
        self.poll_s = poll_s
        self.started: dict[str, int] = {}
        """Run key -> worker pid of the runs started so far (for tests and logs)."""

    def run(self, specs: Sequence[RunSpec], sweep_dir: Path) -> Iterator[RunResult]:
        """Run ``specs`` into ``sweep_dir/<spec.rel_dir>``; yield each result as it ends."""
        pending = collections.deque(specs)
        running: list[_Running] = []
        try:
            while pending or running:
                while pending and len(running) < self.jobs:
                    spec = pending.popleft()
                    proc, log = start_run(spec, sweep_dir / spec.rel_dir)
                    self.started[spec.key] = proc.pid
                    running.append(_Running(spec, proc, log, time.monotonic()))
                finished = []
                for job in running:
                    wall = time.monotonic() - job.t0
                    timed_out = None
                    if job.proc.poll() is None:
                        if self.timeout_s is None or wall < self.timeout_s:
                            continue
                        kill_group(job.proc)
                        timed_out = self.timeout_s
                    job.log.close()
                    finished.append(job)
                    code = job.proc.returncode
                    run_dir = sweep_dir / job.spec.rel_dir
                    yield finish_run(job.spec, run_dir, code, wall, timed_out=timed_out)
                running = [j for j in running if j not in finished]
                if not finished:
                    time.sleep(self.poll_s)
        finally:
            for job in running:
                if job.proc.returncode is None:
                    kill_group(job.proc)
                job.log.close()
