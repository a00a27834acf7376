"""gmapping's time per update: 30 particles, 360 beams, a TurtleBot3 loop in turtlebot3_world.

Runs :class:`visnav.mapping.gmapping.GmappingFilter` (TurtleBot3's gmapping_params.yaml
with 30 particles) over the recorded drive in tests/mapping/gmapping/data, and prints:

* the median wall time of a processed update (motion, scan matching of every particle,
  weights, resampling, map registration), with 1 and with all numba threads;
* the scan matching of the same scans by a plain per-particle Python loop
  (:mod:`visnav.mapping.gmapping.reference`), on copies of the filter's state at a few
  updates, against the compiled kernels on one thread (CPU time, median of 5), and the
  ratio (the outputs are checked equal);
* the map rebuild time (slam_gmapping's updateMap) and the particle maps' memory;
* with ``--against REV``: the filter of git revision ``REV`` (its gmapping package, read
  with ``git show``) run on the same scans, update by update alternating with this tree's,
  the median CPU per update of each and whether poses, weights and map are equal bit for bit.

Run: ``python bench/bench_gmapping.py [--reference-updates N] [--against REV]``.
"""

from __future__ import annotations

import argparse
import copy
import importlib
import itertools
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numba
import numpy as np

from visnav.mapping.gmapping import GmappingFilter, GmappingParams, LaserGeometry
from visnav.mapping.gmapping import _scan_kernels as k
from visnav.mapping.gmapping.reference import scan_match_py

FIXTURE = Path(__file__).resolve().parent.parent / "tests/mapping/gmapping/data/tb3_world_loop.npz"
TB3 = {
    "maxUrange": 3.0, "sigma": 0.05, "kernelSize": 1, "lstep": 0.05, "astep": 0.05,
    "iterations": 5, "lsigma": 0.075, "ogain": 3.0, "lskip": 0, "minimumScore": 50.0,
    "srr": 0.1, "srt": 0.2, "str": 0.1, "stt": 0.2, "linearUpdate": 1.0, "angularUpdate": 0.2,
    "temporalUpdate": 0.5, "resampleThreshold": 0.5, "particles": 30, "xmin": -10.0,
    "ymin": -10.0, "xmax": 10.0, "ymax": 10.0, "delta": 0.05,
}  # fmt: skip


def _odometry(truth: np.ndarray) -> np.ndarray:
    rng = np.random.default_rng(0)
    odo = truth[0].copy()
    out = [odo.copy()]
    for a, b in itertools.pairwise(truth):
        c, s = math.cos(a[2]), math.sin(a[2])
        dx = c * (b[0] - a[0]) + s * (b[1] - a[1])
        dy = -s * (b[0] - a[0]) + c * (b[1] - a[1])
        dx2 = dx * 1.02 + rng.normal(0, 0.002)
        dt2 = (b[2] - a[2]) * 1.03 + 0.01 * abs(dx) + rng.normal(0, 0.002)
        c, s = math.cos(odo[2]), math.sin(odo[2])
        odo = odo + np.array([c * dx2 - s * dy, s * dx2 + c * dy, dt2])
        out.append(odo.copy())
    return np.array(out)


class _Capturing(GmappingFilter):
    """The filter, keeping copies of the scan matcher's inputs at chosen updates."""

    capture: frozenset[int] = frozenset()
    snaps: list[Any]

    def _scan_match(self, ranges: np.ndarray) -> None:
        if self.count in self.capture:
            self.snaps.append((copy.deepcopy(self.maps), self.poses.copy(), ranges.copy()))
        super()._scan_match(ranges)


def _run(
    d: Any, capture: frozenset[int] = frozenset()
) -> tuple[list[float], list[float], _Capturing]:
    p = GmappingParams(**TB3)  # type: ignore[arg-type]
    t = d["T_base_laser"]
    n = d["ranges"].shape[1]
    laser = LaserGeometry(
        x=float(t[0, 3]), y=float(t[1, 3]),
        angles=float(d["angle_min"]) + float(d["angle_increment"]) * np.arange(n),
        max_range=float(d["range_max"]) - 0.01, usable_range=p.maxUrange,
    )  # fmt: skip
    odo = _odometry(d["truth"])
    f = _Capturing(p, laser, initial_pose=tuple(odo[0]))
    f.capture = capture
    f.snaps = []
    times: list[float] = []
    cpu: list[float] = []
    ranges = d["ranges"].astype(np.float64)
    for i in range(len(ranges)):
        t0, c0 = time.perf_counter(), time.process_time()
        done = f.process_scan(tuple(odo[i]), ranges[i], float(d["stamps"][i]))
        if done and f.count > 1:
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    return times, cpu, f


_PACKAGE = "src/visnav/mapping/gmapping"
_FILES = ("_kernels.py", "_scan_kernels.py", "maps.py", "particle_filter.py", "params.py")


def _filter_class_at(rev: str, into: Path) -> Any:
    """``GmappingFilter`` of git revision ``rev``, imported as package ``gmapping_at_rev``."""
    root = Path(__file__).resolve().parent.parent
    pkg = into / "gmapping_at_rev"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for name in _FILES:
        text = subprocess.run(
            ["git", "show", f"{rev}:{_PACKAGE}/{name}"], cwd=root, check=True,
            capture_output=True, text=True,
        ).stdout  # fmt: skip
        text = text.replace("visnav.mapping.gmapping.", "gmapping_at_rev.")
        text = text.replace("from visnav.mapping.gmapping import", "from gmapping_at_rev import")
        (pkg / name).write_text(text)
    sys.path.insert(0, str(into))
    return importlib.import_module("gmapping_at_rev.particle_filter").GmappingFilter


def _against(d: Any, rev: str) -> None:
    """Both filters on the same scans, alternating per scan: CPU per update, equality."""
    numba.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        old_cls = _filter_class_at(rev, Path(tmp))
        p = GmappingParams(**TB3)  # type: ignore[arg-type]
        t = d["T_base_laser"]
        n = d["ranges"].shape[1]
        laser = LaserGeometry(
            x=float(t[0, 3]), y=float(t[1, 3]),
            angles=float(d["angle_min"]) + float(d["angle_increment"]) * np.arange(n),
            max_range=float(d["range_max"]) - 0.01, usable_range=p.maxUrange,
        )  # fmt: skip
        odo = _odometry(d["truth"])
        filters = [cls(p, laser, initial_pose=tuple(odo[0])) for cls in (old_cls, GmappingFilter)]
        cpu: list[list[float]] = [[], []]
        same = True
        ranges = d["ranges"].astype(np.float64)
        for i in range(len(ranges)):
            done = []
            for f, out in zip(filters, cpu, strict=True):
                c0 = time.process_time()
                done.append(f.process_scan(tuple(odo[i]), ranges[i], float(d["stamps"][i])))
                if done[-1] and f.count > 1:
                    out.append(time.process_time() - c0)
            a, b = filters
            same = same and done[0] == done[1] and a.poses.tobytes() == b.poses.tobytes()
            same = same and a.weight_sums.tobytes() == b.weight_sums.tobytes()
        ma, mb = (f.build_map() for f in filters)
        same = same and ma.data.tobytes() == mb.data.tobytes() and ma.origin == mb.origin
        same = same and ma.values.tobytes() == mb.values.tobytes()
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    before, after = (float(np.median(c)) for c in cpu)
    print(f"against {rev} (same scans, alternating, 1 thread, {len(cpu[1])} updates): median CPU "
          f"per update {1e3 * before:.1f} ms at {rev}, {1e3 * after:.1f} ms now, "
          f"{before / after:.2f}x; poses, weights and map bit for bit "
          f"{'equal' if same else 'DIFFERENT'}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--reference-updates", type=int, default=2)
    ap.add_argument("--runs", type=int, default=2, help="filter runs per thread count")
    ap.add_argument("--against", metavar="REV", help="also run git revision REV's filter (A/B)")
    args = ap.parse_args()
    d = dict(np.load(FIXTURE))
    print(f"fixture: {len(d['stamps'])} scans x {d['ranges'].shape[1]} beams, 30 particles")
    if args.against:
        _against(d, args.against)
    print(f"load average: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores "
          f"(numba threads {numba.get_num_threads()}, layer after first run below)")  # fmt: skip
    _run(d)  # compile
    print(f"numba threading layer: {numba.threading_layer()}")
    results = {}
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        numba.set_num_threads(threads)
        out = [_run(d) for _ in range(args.runs)]
        wall = np.concatenate([o[0] for o in out])
        cpu = np.concatenate([o[1] for o in out])
        med = float(np.median(wall))
        results[threads] = med
        print(f"update, {threads} thread(s): median wall {1e3 * med:.1f} ms, CPU "
              f"{1e3 * np.median(cpu):.1f} ms (all threads), p90 wall "
              f"{1e3 * np.percentile(wall, 90):.1f} ms, over {len(out[0][0])} updates x "
              f"{len(out)} runs")  # fmt: skip
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    capture = frozenset(range(10, 10 + 7 * args.reference_updates, 7))
    _, _, f = _run(d, capture)
    p = f.params
    lz = f.laser
    laser = np.array([lz.x, lz.y, 0.0])
    compiled, python = [], []
    snaps = f.snaps
    numba.set_num_threads(1)  # CPU time of one thread against the one-thread Python loop
    for maps, poses, ranges in snaps:
        out = np.empty_like(poses)
        scores, like = np.empty(len(poses)), np.empty(len(poses))
        runs = []
        for _ in range(5):
            t0 = time.process_time()
            k.scan_match_all(
                maps.tables, maps.accx, maps.accy, maps.hits, maps.visits, poses, ranges,
                lz.angles, laser, lz.usable_range, p.sigma, p.lsigma, p.delta, maps.cx0,
                maps.cy0, p.kernelSize, p.lskip, p.lstep, p.astep, p.iterations,
                p.minimumScore, out, scores, like,
            )  # fmt: skip
            runs.append(time.process_time() - t0)
        compiled.append(float(np.median(runs)))
        t0 = time.process_time()
        ref_poses, ref_like = scan_match_py(
            maps, poses, ranges, lz.angles, (lz.x, lz.y, 0.0), usable=lz.usable_range,
            sigma=p.sigma, lsigma=p.lsigma, minimum_score=p.minimumScore,
            kernel=p.kernelSize, lskip=p.lskip, lstep=p.lstep, astep=p.astep,
            iterations=p.iterations,
        )  # fmt: skip
        python.append(time.process_time() - t0)
        assert np.allclose(ref_poses, out, atol=1e-12), "compiled and Python poses differ"
        assert np.allclose(ref_like, like, rtol=1e-12), "compiled and Python weights differ"
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    mc, mp = float(np.median(compiled)), float(np.median(python))
    print(f"scan matching of 30 particles (same scans, same map state, {len(snaps)} updates, "
          f"CPU, one thread): compiled {1e3 * mc:.1f} ms (median of 5), plain Python loop "
          f"{1e3 * mp:.0f} ms, ratio {mp / mc:.0f}x")  # fmt: skip
    t0 = time.perf_counter()
    grid = f.build_map()
    print(f"map rebuild (updateMap, {f.count} scans replayed, {grid.data.shape[1]} x "
          f"{grid.data.shape[0]} cells): {1e3 * (time.perf_counter() - t0):.1f} ms")  # fmt: skip
    print(f"particle maps: {f.maps.patches_in_use} patches in use, {f.maps.nbytes / 1e6:.1f} MB "
          f"(30 private dense 20x20 m maps at 0.05 m would be {30 * 400 * 400 * 24 / 1e6:.0f} MB)")  # fmt: skip
    best = min(results.values())
    print(f"goal <= 10 ms median per update: {'met' if best <= 0.010 else 'NOT met'} "
          f"({1e3 * best:.1f} ms wall; the load average above inflates wall times)")  # fmt: skip


if __name__ == "__main__":
    main()
