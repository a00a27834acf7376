"""CPU time budget of ``visnav run car`` per stage, in CPU ms per simulated second.

Run: ``python bench/bench_car_budget.py [--duration S] [--seed N] [--ideal-sensors]
[--no-slam] [--worker inline|process]``.

Runs the car scenario (:func:`visnav.scenarios.runner.run_scenario`, SLAM in the loop by
default) once with light instrumentation and prints, per simulated second, the CPU time
of: ``render`` (the cameras' render calls: MuJoCo + llvmpipe, whose threads are in this
process, hence process CPU time around each call), ``physics`` (``mj_step1/2``),
``callbacks`` per node (every executor callback, process CPU time, attributed to its
node: navigation, mapper, scan, SLAM glue, recorder, observer, ...), ``slam worker``
(the worker's CPU time on frames, from its ``/diagnostics``; with ``--worker inline``
it is inside the ``slam`` callbacks), the rest of the main process (``other``: stepping
glue, Zenoh threads, imports and start-up) and the totals. CPU time, not wall time, so
the figures mean something on a machine other programs load; the real-time factor
printed beside them does not (it is the wall clock's).

With the SLAM worker in its own process the two cores share the load: the run can be
real time when each process needs less than 1000 CPU ms per simulated second (and the
barrier rarely waits). The reference measured in the same run is the simulator alone
(``render`` + ``physics``).
"""

from __future__ import annotations

import argparse
import contextlib
import resource
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from typing import Any

import mujoco

from visnav.graph import context as graph_context
from visnav.scenarios.runner import run_scenario
from visnav.sim import plugins as sim_plugins
from visnav.sim import simulator as sim_module

_CPU: dict[str, float] = defaultdict(float)
_START: list[float] = []  # process CPU time at the first physics step (start-up before it)


def _timed(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            _CPU[name] += time.process_time() - t0

    return wrapper


@contextlib.contextmanager
def _instrumented() -> Iterator[None]:
    """Patch render, physics and the executor's callback dispatch (bench only)."""
    saved: list[tuple[Any, str, Any]] = []

    def patch(obj: Any, attr: str, new: Any) -> None:
        saved.append((obj, attr, getattr(obj, attr)))
        setattr(obj, attr, new)

    class _Mj:  # the simulator module's view of mujoco, with the steps timed
        def __getattr__(self, name: str) -> Any:
            return getattr(mujoco, name)

    mj = _Mj()
    for fn in ("mj_step", "mj_step1", "mj_step2", "mj_forward"):
        setattr(mj, fn, _timed("physics", getattr(mujoco, fn)))
    first = mj.mj_step1

    def step1(*args: Any) -> Any:
        if not _START:
            _START.append(time.process_time())
        return first(*args)

    mj.mj_step1 = step1
    patch(sim_module, "mujoco", mj)

    original_sense = sim_plugins.CameraPlugin.sense

    def sense(self: Any, data: Any, now_ns: int) -> None:
        render = self.sensor.render
        self.sensor.render = _timed("render", render)
        try:
            original_sense(self, data, now_ns)
        finally:
            self.sensor.render = render

    patch(sim_plugins.CameraPlugin, "sense", sense)

    original_take = graph_context.Context._take_or_wait

    def take(self: Any, deadline: Any) -> Any:
        taken = original_take(self, deadline)
        if taken is None:
            return None
        entity, call = taken
        node = getattr(getattr(entity, "node", None), "get_name", lambda: "?")()
        return entity, _timed(f"callbacks: {node}", call)

    patch(graph_context.Context, "_take_or_wait", take)
    try:
        yield
    finally:
        for obj, attr, old in reversed(saved):
            setattr(obj, attr, old)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--ideal-sensors", action="store_true")
    parser.add_argument("--no-slam", action="store_true")
    args = parser.parse_args()
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    cpu_start = time.process_time()
    with tempfile.TemporaryDirectory(prefix="bench-car-budget-") as out, _instrumented():
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
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    sim_s = float(summary["sim_duration_s"])
    main_cpu = (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime)
    child_cpu = children.ru_utime + children.ru_stime
    per = 1000.0 / sim_s
    print(f"car seed {args.seed}, {sim_s:.1f} s simulated, wall RTF {summary['real_time_factor']}")
    print(f"{'stage':<44} {'CPU ms / sim s':>15}")
    accounted = 0.0
    for name in sorted(_CPU, key=lambda k: -_CPU[k]):
        if _CPU[name] * per < 1.0:
            continue
        print(f"{name:<44} {_CPU[name] * per:>15.0f}")
        accounted += _CPU[name]
    startup = (_START[0] - cpu_start) if _START else 0.0
    print(
        f"{'other (main process, after start-up)':<44} {(main_cpu - accounted - startup) * per:>15.0f}"
    )
    print(f"{'main process total, after start-up':<44} {(main_cpu - startup) * per:>15.0f}")
    print(f"{'(main process start-up, CPU s)':<44} {startup:>15.1f}")
    slam_cpu = summary.get("slam", {}).get("cpu_s")
    if slam_cpu is not None:
        print(f"{'SLAM worker on frames (its /diagnostics)':<44} {slam_cpu * per:>15.0f}")
    print(f"{'child processes (SLAM worker) total':<44} {child_cpu * per:>15.0f}")
    sim_only = _CPU["render"] + _CPU["physics"]
    print(f"{'reference: simulator alone (render+physics)':<44} {sim_only * per:>15.0f}")
    print(f"ratio main process / simulator alone: {main_cpu / max(sim_only, 1e-9):.2f}")
    loc = summary.get("localization")
    print(f"localization {loc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
