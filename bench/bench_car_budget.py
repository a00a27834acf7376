"""CPU budget of ``visnav run car`` per stage and per process, in CPU s per simulated second.

Run: ``python bench/bench_car_budget.py [--duration S] [--seed N] [--repeat N]
[--ideal-sensors] [--no-slam]``.

Runs the car scenario (:func:`visnav.scenarios.runner.run_scenario`, SLAM in the loop by
default) ``--repeat`` times with light instrumentation and prints the median, per
simulated second, of the CPU time of:

* the main (launch) process: ``render`` (the cameras' render calls: MuJoCo + llvmpipe,
  whose threads are in this process, hence process CPU time around each call),
  ``physics`` (``mj_step1/2``), ``callbacks`` per node (every executor callback,
  process CPU time, attributed to its node: navigation, mapper, scan, SLAM hand-off,
  recorder, observer, ...), the rest (``other``: stepping glue, publishing, Zenoh
  threads) and the process total after start-up;
* the main process's threads, summed by name (the main thread, including start-up,
  ``llvmpipe`` rasterisers, ``visnav-bag-writer``, Zenoh's, ...; ``/proc/self/task``);
* the SLAM worker process: its CPU time on frames per stage (from the worker's
  counters: features, matching, pose, mapping, ...), and the process total after its
  start-up (``/proc/<pid>/stat`` read after the worker answered ``init`` and before it
  is closed: receiving and unpickling frames included, imports excluded).

CPU time, not wall time, so the figures mean something on a machine other programs
load (the wall-clock real-time factor printed beside them does not). From them the
bench prints the real-time factor the run could reach on two free cores: each process
can use at most one core for its Python thread (the render's llvmpipe threads aside), so
``RTF <= min(1 / main, 1 / worker, 2 / (main + worker))`` in CPU s per sim s; it is
an upper bound (the SLAM barrier can still make one process wait for the other).

``barrier`` is the wall time the simulation waited for SLAM results (the deterministic
barrier: the result of the frame stamped ``t`` is applied at ``t + result_latency``);
``--result-latency`` overrides the launch file's 0.1 s to see how much a longer pipeline
absorbs the worker's bursts (a keyframe's local BA). Under load it is inflated like every wall
figure, but its share of the run's wall time still says whether SLAM holds the simulation up.

The reference measured in the same run is the simulator alone (``render`` +
``physics``), printed with its ratio to the main process.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
import statistics
import sys
import tempfile
import threading
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import mujoco

from visnav.graph import context as graph_context
from visnav.scenarios.runner import run_scenario
from visnav.sim import plugins as sim_plugins
from visnav.sim import simulator as sim_module
from visnav.slam import node as slam_node
from visnav.slam import worker as slam_worker


class _Probe:
    """What one instrumented run measures (CPU seconds)."""

    def __init__(self) -> None:
        self.cpu: dict[str, float] = defaultdict(float)
        self.start: float | None = None  # process CPU time at the first physics step
        self.worker_cpu: list[float] = []  # worker process CPU after init, before close
        self.worker_stages: dict[str, float] = {}
        self.depth_passes: dict[int, int] = {}  # per camera sensor
        self.barrier_wall = 0.0  # wall seconds the simulation waited for SLAM results
        self.frames = 0

    def timed(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        cpu = self.cpu

        def wrapper(*args: Any, **kwargs: Any) -> Any:
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                cpu[name] += time.process_time() - t0

        return wrapper


def _thread_cpu_s() -> dict[str, float]:
    """CPU seconds of this process's threads, summed by name (digits dropped: llvmpipe-N)."""
    out: dict[str, float] = defaultdict(float)
    tick = os.sysconf("SC_CLK_TCK")
    main_tid = threading.main_thread().native_id
    for task in Path("/proc/self/task").iterdir():
        with contextlib.suppress(OSError, IndexError, ValueError):
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
            name = (task / "comm").read_text().strip()
            if int(task.name) == main_tid:
                name = "main thread"
            name = name.rstrip("0123456789").rstrip("-:$") or name
            out[name] += (int(fields[11]) + int(fields[12])) / tick
    return out


def _proc_cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (Linux ``/proc``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@contextlib.contextmanager
def _instrumented(probe: _Probe, latency_s: float | None) -> Iterator[None]:
    """Patch render, physics, the executor's dispatch and the SLAM worker (bench only)."""
    saved: list[tuple[Any, str, Any]] = []

    def patch(obj: Any, attr: str, new: Any) -> None:
        saved.append((obj, attr, getattr(obj, attr)))
        setattr(obj, attr, new)

    class _Mj:  # the simulator module's view of mujoco, with the steps timed
        def __getattr__(self, name: str) -> Any:
            return getattr(mujoco, name)

    mj = _Mj()
    for fn in ("mj_step", "mj_step1", "mj_step2", "mj_forward"):
        setattr(mj, fn, probe.timed("physics", getattr(mujoco, fn)))
    first = getattr(mj, "mj_step1")  # noqa: B009

    def step1(*args: Any) -> Any:
        if probe.start is None:
            probe.start = time.process_time()
        return first(*args)

    setattr(mj, "mj_step1", step1)  # noqa: B010 - an instance attribute of the stub
    patch(sim_module, "mujoco", mj)

    original_sense = sim_plugins.CameraPlugin.sense

    def sense(self: Any, data: Any, now_ns: int) -> None:
        render = self.sensor.render
        self.sensor.render = probe.timed("render", render)
        try:
            original_sense(self, data, now_ns)
        finally:
            self.sensor.render = render
            probe.depth_passes[id(self.sensor)] = getattr(self.sensor, "depth_passes", 0)

    patch(sim_plugins.CameraPlugin, "sense", sense)

    original_take = graph_context.Context._take_or_wait

    def take(self: Any, deadline: Any) -> Any:
        taken = original_take(self, deadline)
        if taken is None:
            return None
        entity, call = taken
        node = getattr(getattr(entity, "node", None), "get_name", lambda: "?")()
        return entity, probe.timed(f"callbacks: {node}", call)

    patch(graph_context.Context, "_take_or_wait", take)

    original_init = slam_worker.ProcessWorker.__init__
    original_close = slam_worker.ProcessWorker.close

    def init(self: Any, *args: Any, **kwargs: Any) -> None:
        original_init(self, *args, **kwargs)
        probe.worker_cpu.append(_proc_cpu_s(self._proc.pid))

    def close(self: Any) -> None:
        if not self._closed and self._proc.poll() is None:
            with contextlib.suppress(slam_worker.SlamWorkerError, OSError):
                stats = self.stats()
                probe.worker_stages = dict(stats.stage_cpu_s)
                probe.frames = stats.frames
            probe.worker_cpu.append(_proc_cpu_s(self._proc.pid))
        original_close(self)

    original_next = slam_worker.ProcessWorker.next_result

    def next_result(self: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return original_next(self)
        finally:
            probe.barrier_wall += time.perf_counter() - t0

    patch(slam_worker.ProcessWorker, "__init__", init)
    patch(slam_worker.ProcessWorker, "close", close)
    patch(slam_worker.ProcessWorker, "next_result", next_result)
    if latency_s is not None:  # bench only: another result_latency than the launch file's
        original_node_init = slam_node.SlamNode.__init__

        def node_init(self: Any, *args: Any, **kwargs: Any) -> None:
            original_node_init(self, *args, **kwargs)
            self._latency_ns = round(latency_s * 1e9)

        patch(slam_node.SlamNode, "__init__", node_init)
    try:
        yield
    finally:
        for obj, attr, old in reversed(saved):
            setattr(obj, attr, old)


def _run_once(args: argparse.Namespace) -> dict[str, Any]:
    probe = _Probe()
    load0 = os.getloadavg()[0]
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    threads0 = _thread_cpu_s()
    with (
        tempfile.TemporaryDirectory(prefix="bench-car-budget-") as out,
        _instrumented(probe, args.result_latency),
    ):
        summary = run_scenario(
            "car",
            seed=args.seed,
            duration_s=args.duration,
            out=out,
            slam=not args.no_slam,
            ideal_sensors=args.ideal_sensors,
            progress=None,
        )
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    threads1 = _thread_cpu_s()
    sim_s = float(summary["sim_duration_s"])
    main_cpu = (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime)
    startup = 0.0 if probe.start is None else probe.start - (cpu0.ru_utime + cpu0.ru_stime)
    rows: dict[str, float] = {}
    accounted = 0.0
    for name, value in probe.cpu.items():
        rows[f"main: {name}"] = value / sim_s
        accounted += value
    main_after = main_cpu - max(startup, 0.0)
    rows["main: other"] = (main_after - accounted) / sim_s
    rows["MAIN PROCESS (after start-up)"] = main_after / sim_s
    for name, value in threads1.items():  # threads that ended during the run are missed
        rows[f"main thread group: {name}"] = (value - threads0.get(name, 0.0)) / sim_s
    for stage, value in probe.worker_stages.items():
        rows[f"worker: {stage}"] = value / sim_s
    slam = summary.get("slam") or {}
    if slam.get("cpu_s") is not None:
        rows["worker: on frames (its /diagnostics)"] = float(slam["cpu_s"]) / sim_s
    if len(probe.worker_cpu) == 2:
        rows["WORKER PROCESS (after start-up)"] = (
            probe.worker_cpu[1] - probe.worker_cpu[0]
        ) / sim_s
    rows["barrier: wall s waiting for SLAM results"] = probe.barrier_wall / sim_s
    rows["reference: simulator alone (render+physics)"] = (
        probe.cpu["render"] + probe.cpu["physics"]
    ) / sim_s
    return {
        "rows": rows,
        "sim_s": sim_s,
        "rtf": float(summary["real_time_factor"]),
        "barrier_share": probe.barrier_wall / max(float(summary["wall_duration_s"]), 1e-9),
        "load": (load0, os.getloadavg()[0]),
        "localization": summary.get("localization"),
        "depth_passes": sum(probe.depth_passes.values()),
        "frames": probe.frames,
    }


def _bound(main: float, worker: float) -> float:
    limits = [1.0 / main if main > 0 else float("inf")]
    if worker > 0:
        limits += [1.0 / worker, 2.0 / (main + worker)]
    return min(limits)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=4)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--ideal-sensors", action="store_true")
    parser.add_argument("--no-slam", action="store_true")
    parser.add_argument(
        "--result-latency",
        type=float,
        default=None,
        help="override the SLAM node's result_latency (s; the launch file's is 0.1)",
    )
    args = parser.parse_args()
    runs = [_run_once(args) for _ in range(max(1, args.repeat))]
    names: list[str] = []
    for run in runs:
        names += [n for n in run["rows"] if n not in names]

    def median(name: str) -> float:
        return float(statistics.median(r["rows"].get(name, 0.0) for r in runs))

    first = runs[0]
    rtfs = ", ".join(f"{r['rtf']:.2f}" for r in runs)
    loads = ", ".join(f"{r['load'][0]:.1f}-{r['load'][1]:.1f}" for r in runs)
    print(
        f"car seed {args.seed}, {first['sim_s']:.1f} s simulated, {len(runs)} run(s); "
        f"wall RTF {rtfs} (load average {loads}: wall figures mean little under load)"
    )
    print(f"{'stage (median over runs)':<48} {'CPU s / sim s':>14}")
    order = sorted(names, key=lambda n: (n.split(":")[0].split()[0].lower(), -median(n)))
    for name in order:
        value = median(name)
        if abs(value) < 0.0005 and not name.isupper():
            continue
        print(f"{name:<48} {value:>14.3f}")
    main_total = median("MAIN PROCESS (after start-up)")
    worker_total = median("WORKER PROCESS (after start-up)")
    reference = median("reference: simulator alone (render+physics)")
    print(f"ratio main process / simulator alone: {main_total / max(reference, 1e-9):.2f}")
    print(
        f"implied real-time factor bound on 2 free cores: {_bound(main_total, worker_total):.2f} "
        f"(1/main {1 / max(main_total, 1e-9):.2f}, 1/worker "
        f"{1 / max(worker_total, 1e-9):.2f}, 2/(main+worker) "
        f"{2 / max(main_total + worker_total, 1e-9):.2f})"
    )
    share = statistics.median(r["barrier_share"] for r in runs)
    print(f"share of the wall time the simulation waited for SLAM results: {100 * share:.0f} %")
    print(f"separate depth passes: {first['depth_passes']}; SLAM frames {first['frames']}")
    print(f"localization {first['localization']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
