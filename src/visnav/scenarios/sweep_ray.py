"""The Ray sweep backend (``pip install 'visnav[ray]'``): runs as Ray tasks, on one machine or many.

Each run is a Ray task declaring ``cpus_per_run`` CPUs; the task starts the run's worker
process (:mod:`visnav.scenarios.sweep_worker`, isolated as with the local backend) and
returns the result together with the run directory's files. Results are taken with
``ray.wait`` as they finish. Without ``address`` the command starts a private local Ray
sized to ``jobs`` runs; ``address="auto"``, ``HOST:PORT`` or ``ray://HOST:PORT`` joins an
existing cluster (see docs/sweep.md for the multi-machine setup).

Where the output goes: a task writes the run into the same path as the sweep directory
on its node (a temporary directory if that path is not writable there). When the task
ran on another node than the sweep, its files come back in the result and are written
into the sweep directory; a bag larger than ``bag_limit_mb`` stays on the worker node
and ``summary.json``'s ``bag`` names ``node:path``.
"""

from __future__ import annotations

import collections
import json
import os
import socket
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any
from urllib.parse import urlparse

from visnav.scenarios.sweep_spec import RunSpec, SweepError
from visnav.scenarios.sweep_worker import RunResult, run_blocking

__all__ = ["RayBackend", "import_ray", "ray_task"]

_GRACE_S = 60.0
"""Beyond ``timeout_s``, how long the driver waits for a task before cancelling it."""


def import_ray() -> ModuleType:
    """Import Ray or raise a one-line error naming the fix."""
    try:
        import ray  # noqa: PLC0415 - optional extra
    except ImportError:
        msg = (
            "--backend ray needs Ray, which is not installed: pip install 'visnav[ray]' "
            "(or run with --backend local)"
        )
        raise SweepError(msg) from None
    return ray


def _check_reachable(address: str) -> None:
    """Refuse quickly (one line) when ``HOST:PORT`` / ``ray://HOST:PORT`` does not answer."""
    parsed = urlparse(address if "://" in address else f"tcp://{address}")
    host, port = parsed.hostname, parsed.port
    if host is None or port is None:
        msg = f"--address {address!r}: expected auto, HOST:PORT or ray://HOST:PORT"
        raise SweepError(msg)
    try:
        with socket.create_connection((host, port), timeout=3.0):
            pass
    except OSError as exc:
        msg = (
            f"--address {address}: cannot reach Ray at {host}:{port} ({exc.strerror or exc}); "
            "start the head there with `ray start --head` (ray:// needs its client port, "
            "10001), or check the host and port"
        )
        raise SweepError(msg) from None


def _writable_root(sweep_dir: str) -> Path:
    root = Path(sweep_dir)
    try:
        root.mkdir(parents=True, exist_ok=True)
        probe = root / f".probe-{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError:
        root = Path(tempfile.gettempdir()) / "visnav-sweep" / root.name
        root.mkdir(parents=True, exist_ok=True)
    return root


def _collect(run_dir: Path, bag_limit: int) -> dict[str, bytes]:
    files: dict[str, bytes] = {}
    bag_size = sum(p.stat().st_size for p in run_dir.glob("bag/**/*") if p.is_file())
    for path in sorted(run_dir.rglob("*")):
        if not path.is_file():
            continue
        rel = path.relative_to(run_dir).as_posix()
        if rel.startswith("bag/") and bag_size > bag_limit:
            continue
        files[rel] = path.read_bytes()
    return files


def ray_task(
    spec_json: dict[str, Any],
    sweep_dir: str,
    timeout_s: float | None,
    driver_node: str,
    bag_limit: int,
) -> dict[str, Any]:
    """The body of a run's Ray task: run it, return the result and (remote node) its files."""
    import ray  # noqa: PLC0415 - runs on a Ray worker

    spec = RunSpec.from_json(spec_json)
    root = _writable_root(sweep_dir)
    run_dir = root / spec.rel_dir
    result = run_blocking(spec, run_dir, timeout_s=timeout_s)
    node = ray.get_runtime_context().get_node_id()
    local = node == driver_node and root == Path(sweep_dir)
    return {
        "key": result.key,
        "status": result.status,
        "reason": result.reason,
        "summary": result.summary,
        "wall_s": result.wall_s,
        "node": f"{socket.gethostname()}",
        "files": {} if local else _collect(run_dir, bag_limit),
        "run_dir": str(run_dir),
    }


class RayBackend:
    """Runs sweep runs as Ray tasks.

    Args:
        jobs: runs at a time (None: as many as the cluster's CPUs allow); also the size of
            the local Ray this starts when ``address`` is None.
        timeout_s: a run still going after this many seconds is killed and failed.
        address: None (start a local Ray), ``auto``, ``HOST:PORT`` or ``ray://HOST:PORT``.
        cpus_per_run: CPUs each task declares.
        bag_limit_mb: bags up to this size come back from remote nodes.
    """

    name = "ray"

    def __init__(
        self,
        *,
        jobs: int | None = None,
        timeout_s: float | None = None,
        address: str | None = None,
        cpus_per_run: float = 1.0,
        bag_limit_mb: float = 256.0,
    ) -> None:
        if jobs is not None and jobs < 1:
            msg = f"--jobs is {jobs}: expected at least 1 run at a time"
            raise SweepError(msg)
        self.ray = import_ray()
        if address not in (None, "auto"):
            _check_reachable(address)
        self.jobs, self.timeout_s, self.address = jobs, timeout_s, address
        self.cpus_per_run = cpus_per_run
        self.bag_limit = int(bag_limit_mb * 1e6)

    def _init(self) -> None:
        ray = self.ray
        quiet: dict[str, Any] = {"log_to_driver": False, "configure_logging": False}
        if self.address is None:
            cpus = max(1, round((self.jobs or os.cpu_count() or 1) * self.cpus_per_run))
            # "local": a private instance even when another Ray runs on this machine
            ray.init(address="local", num_cpus=cpus, include_dashboard=False, **quiet)
            return
        try:
            ray.init(address=self.address, **quiet)
        except ConnectionError as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            msg = (
                f"--address {self.address}: no Ray cluster there ({first}); start one with "
                "`ray start --head` (a cluster with token authentication also needs "
                "RAY_AUTH_MODE=token and its token here), or leave --address out to start a "
                "local Ray"
            )
            raise SweepError(msg) from None

    def run(self, specs: Sequence[RunSpec], sweep_dir: Path) -> Iterator[RunResult]:
        """Run ``specs`` as Ray tasks; yield each result as it finishes."""
        ray = self.ray
        self._init()
        try:
            yield from self._stream(specs, sweep_dir)
        finally:
            ray.shutdown()

    def _stream(self, specs: Sequence[RunSpec], sweep_dir: Path) -> Iterator[RunResult]:
        ray = self.ray
        task = ray.remote(num_cpus=self.cpus_per_run, max_retries=0)(ray_task)
        # a ray:// client is no node of the cluster: every task's files must come back
        remote_driver = (self.address or "").startswith("ray://")
        driver = "" if remote_driver else ray.get_runtime_context().get_node_id()
        pending = collections.deque(specs)
        flying: dict[Any, tuple[RunSpec, float]] = {}
        limit = self.jobs or len(specs)
        try:
            while pending or flying:
                while pending and len(flying) < limit:
                    spec = pending.popleft()
                    args = (spec.to_json(), str(sweep_dir), self.timeout_s, driver, self.bag_limit)
                    flying[task.remote(*args)] = (spec, time.monotonic())
                done, _ = ray.wait(list(flying), num_returns=1, timeout=0.5)
                for ref in done:
                    spec, t0 = flying.pop(ref)
                    yield self._result(ref, spec, sweep_dir, time.monotonic() - t0)
                if self.timeout_s is not None:
                    yield from self._cancel_overdue(flying)
        finally:
            for ref in flying:
                ray.cancel(ref, force=True)
            if flying:  # their run processes notice the dead task within a second
                time.sleep(1.5)

    def _cancel_overdue(self, flying: dict[Any, tuple[RunSpec, float]]) -> Iterator[RunResult]:
        if self.timeout_s is None:
            return
        now = time.monotonic()
        for ref, (spec, t0) in list(flying.items()):
            if now - t0 > self.timeout_s + _GRACE_S:
                self.ray.cancel(ref, force=True)
                del flying[ref]
                reason = f"timeout: the Ray task did not end {self.timeout_s:g} s (cancelled)"
                yield RunResult(spec.key, "failed", reason, wall_s=now - t0)

    def _result(self, ref: Any, spec: RunSpec, sweep_dir: Path, wall: float) -> RunResult:
        ray = self.ray
        try:
            out: dict[str, Any] = ray.get(ref)
        except ray.exceptions.RayError as exc:
            text = str(exc).strip().splitlines()
            first = text[0] if text else type(exc).__name__
            reason = f"Ray task failed ({type(exc).__name__}): {first}"[:300]
            return RunResult(spec.key, "failed", reason, wall_s=wall)
        run_dir = sweep_dir / spec.rel_dir
        summary = out["summary"]
        if out["files"]:
            run_dir.mkdir(parents=True, exist_ok=True)
            for rel, data in out["files"].items():
                target = run_dir / rel
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_bytes(data)
            if summary is not None:
                bag_back = any(rel.startswith("bag/") for rel in out["files"])
                remote = f"{out['node']}:{Path(out['run_dir']) / 'bag'}"
                summary["bag"] = str(run_dir / "bag") if bag_back else remote
                (run_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
        return RunResult(
            out["key"], out["status"], out["reason"], summary, float(out["wall_s"]), out["node"]
        )
