"""Acceptance runs of the built-in scenarios over seeds, through the sweep library (issue 15).

``python bench/bench_scenarios.py car --seeds 0-9 --no-slam --jobs 2`` sweeps ``visnav run
car`` over seeds 0..9 (``visnav sweep`` underneath: each run in a process of its own) and
prints goals reached, collisions, path ratio (car) or speed / clearance / planning time
(drone). Options:

* ``--backend ray``: the runs as Ray tasks (a local Ray of ``--jobs`` CPUs).
* ``--compare-jobs``: sweep once with one job, then with ``--jobs``; print both wall times
  and their ratio (issue 15: two jobs <= 0.65x one job on the 2-core machine);
  ``--repeat N`` alternates N such pairs and prints the median ratio, ``--duration S``
  shortens every run to S simulated seconds (for the pairs on a busy machine).
* ``--check-run``: also run ``visnav run SCENARIO --seed S`` one at a time and check each
  sweep run has the same summary (but wall-clock keys) and a byte-identical ground-truth
  trajectory.
* ``--map TEMPLATE`` (car): localise in a saved map instead of mapping (``visnav run car
  --map``: SLAM in localisation mode in the ``slam_map.npz`` beside it; ``--map-localization
  amcl``: AMCL on the scan); ``{seed}`` in the path is replaced by each run's seed, so
  ``--map runs/first/{seed}/map.yaml`` gives every seed the map its own earlier run wrote
  (issue 14's "map once, then navigate"). It is the sweep option ``--set map=TEMPLATE``:
  the same sweep, outputs and backends as without it; a missing or broken map of any seed
  stops the bench before anything runs (one line naming the seed and the path).

The sweep directories go to a temporary ``bench-<scenario>-*`` directory (printed).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from visnav.errors import VisnavError
from visnav.scenarios.sweep import SweepBackend, run_sweep
from visnav.scenarios.sweep_check import run_differences
from visnav.scenarios.sweep_local import LocalBackend
from visnav.scenarios.sweep_spec import parse_seeds, parse_sets


def _backend(kind: str, jobs: int) -> SweepBackend:
    if kind == "ray":
        from visnav.scenarios.sweep_ray import RayBackend

        return RayBackend(jobs=jobs)
    return LocalBackend(jobs=jobs)


def _sweep(args: argparse.Namespace, out: Path, jobs: int) -> tuple[dict[str, Any], float]:
    sets: dict[str, list[Any]] = {"slam": [False]} if args.no_slam else {}
    if args.ideal_sensors:
        sets["ideal_sensors"] = [True]
    if args.duration is not None:
        sets["duration"] = [args.duration]
    if args.map is not None:
        sets.update(parse_sets([f"map={args.map}"]))
        sets.update(parse_sets([f"map_localization={args.map_localization}"]))
    t0 = time.perf_counter()
    state = run_sweep(
        args.scenario,
        out=out,
        backend=_backend(args.backend, jobs),
        seeds=parse_seeds(args.seeds),
        sets=sets,
        progress=sys.stderr,
        report=False,
    )
    return state, time.perf_counter() - t0


def _print_runs(scenario: str, state: dict[str, Any]) -> None:
    rows = [r["summary"] for r in state["runs"] if r["status"] == "ok"]
    for r in state["runs"]:
        if r["status"] != "ok":
            print(f"seed {r['seed']}: FAILED {r['reason']}")
    for s in rows:
        extra = (
            f"ratio {s.get('path_ratio')}"
            if scenario == "car"
            else f"speed {s['mean_speed_mps']} m/s clearance {s['min_clearance_m']} m "
            f"plan median {s['planning_time_ms']['median']} ms"
        )
        print(
            f"seed {s['seed']}: {s['goals_reached']}/{s['goals_total']} goals, "
            f"{s['collisions']} collisions, {extra}, sim {s['sim_duration_s']:.0f} s, "
            f"RTF {s['real_time_factor']}"
        )
        if "localization" in s:
            print(
                f"  localization {s['localization']}, odometry drift {s.get('odometry_drift_m')} m"
            )
        if "slam" in s:
            print(f"  slam {s['slam']}")
    if not rows:
        return
    goals = sum(r["goals_total"] for r in rows)
    reached = sum(r["goals_reached"] for r in rows)
    print(f"goals reached {reached}/{goals}, collisions {sum(r['collisions'] for r in rows)}")
    if scenario == "car":
        _print_loop_acceptance(rows, goals, reached)
    ratios = [r["path_ratio"] for r in rows if r.get("path_ratio")]
    if ratios:
        print(f"mean path ratio {statistics.mean(ratios):.3f} (target <= 1.3)")
    speeds = [r["mean_speed_mps"] for r in rows if "mean_speed_mps" in r and scenario == "drone"]
    if speeds:
        print(f"mean speed {statistics.mean(speeds):.2f} m/s (target >= 1.5)")


def _print_loop_acceptance(rows: list[dict[str, Any]], goals: int, reached: int) -> None:
    """Issue 14's acceptance of SLAM in the loop (noise on): one verdict line per figure."""
    slam = ("slam", "slam_localization")  # mapping, or localising in a saved SLAM map
    loc = [r["localization"] for r in rows if r.get("localization", {}).get("source") in slam]
    amcl = not loc  # --map with amcl: its figures, without the drift and real-time targets
    loc = loc or [
        r["localization"] for r in rows if r.get("localization", {}).get("source") == "amcl"
    ]
    if not loc:
        return
    rmse = [x["rmse_m"] for x in loc if x.get("rmse_m") is not None]
    worst = [x["max_m"] for x in loc if x.get("max_m") is not None]
    drift = [r["odometry_drift_m"] for r in rows if r.get("odometry_drift_m") is not None]
    rtf = statistics.median(r["real_time_factor"] for r in rows)
    checks = [
        ("goals reached", f"{reached / goals:.1%}", reached >= 0.95 * goals, ">= 95 %"),
        (
            "collisions",
            str(sum(r["collisions"] for r in rows)),
            not any(r["collisions"] for r in rows),
            "0",
        ),
        (
            "localization RMSE (worst run)",
            f"{max(rmse):.4f} m" if rmse else "-",
            bool(rmse) and max(rmse) <= 0.05,
            "<= 0.05 m",
        ),
        (
            "localization max (worst run)",
            f"{max(worst):.4f} m" if worst else "-",
            bool(worst) and max(worst) <= 0.15,
            "<= 0.15 m",
        ),
        (
            "odometry drift (smallest)",
            f"{min(drift):.3f} m" if drift else "-",
            bool(drift) and min(drift) >= 0.3,
            ">= 0.3 m",
        ),
        ("median real-time factor", f"{rtf:.3f}", rtf >= 1.0, ">= 1.0 (quiet machine)"),
    ]
    if amcl:
        checks = checks[:4]
    for name, value, ok, target in checks:
        print(f"  {name:<32} {value:>10}  {'ok' if ok else 'NOT MET'} (target {target})")


def _check_run(args: argparse.Namespace, root: Path, state: dict[str, Any]) -> int:
    bad = 0
    for run in state["runs"]:
        ref = (args.reference or root / "visnav-run") / str(run["seed"])
        if (ref / "summary.json").is_file():  # from an earlier bench (--reference DIR)
            diffs = run_differences(root / "jobs" / run["dir"], ref)
            verdict = "identical" if not diffs else "DIFFERENT: " + "; ".join(diffs)
            print(f"seed {run['seed']}: sweep run vs {ref}: {verdict}", flush=True)
            bad += bool(diffs)
            continue
        cmd = [sys.executable, "-m", "visnav.cli.main", "run", args.scenario, "--quiet"]
        cmd += ["--seed", str(run["seed"]), "--out", str(ref)]
        cmd += ["--no-slam"] if args.no_slam else []
        cmd += ["--ideal-sensors"] if args.ideal_sensors else []
        map_path = run["options"].get("map")  # the run's map, {seed} replaced
        cmd += ["--map", map_path] if map_path else []
        loc = run["options"].get("map_localization")
        cmd += ["--map-localization", loc] if map_path and loc else []
        env = {**os.environ, "VISNAV_DOMAIN": str(3_000_000 + os.getpid() % 100_000)}
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        diffs = run_differences(root / "jobs" / run["dir"], ref)
        verdict = "identical" if not diffs else "DIFFERENT: " + "; ".join(diffs)
        print(f"seed {run['seed']}: visnav run {wall:.1f} s; sweep run {verdict}", flush=True)
        bad += bool(diffs)
    return bad


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("scenario", choices=["car", "drone"])
    parser.add_argument("--seeds", default="0-9", help="0-9, 0,3,7, ...")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time")
    parser.add_argument("--backend", choices=["local", "ray"], default="local")
    parser.add_argument("--no-slam", action="store_true", help="car: navigation only")
    parser.add_argument(
        "--ideal-sensors", action="store_true", help="car: ground truth odometry, SLAM beside"
    )
    parser.add_argument("--compare-jobs", action="store_true", help="also time one job")
    parser.add_argument("--repeat", type=int, default=1, help="--compare-jobs: pairs to time")
    parser.add_argument("--duration", type=float, default=None, help="sim seconds per run")
    parser.add_argument(
        "--map", default=None, help="car: localise in this map ({seed}: each run's seed)"
    )
    parser.add_argument(
        "--map-localization",
        choices=["slam", "amcl"],
        default="slam",
        help="car with --map: what localises in it (visnav run car --map-localization)",
    )
    parser.add_argument("--check-run", action="store_true", help="compare with visnav run")
    parser.add_argument(
        "--reference", type=Path, default=None, help="--check-run: visnav-run/ of an earlier bench"
    )
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix=f"bench-{args.scenario}-"))
    print(f"output in {root}; load average {os.getloadavg()}", flush=True)
    ratios = []
    for rep in range(args.repeat if args.compare_jobs else 1):
        if args.compare_jobs:  # alternate, so that a change of the machine's load hits both
            _, wall_one = _sweep(args, root / f"one-job-{rep}", 1)
            print(f"one job: {wall_one:.1f} s wall; load average {os.getloadavg()}", flush=True)
        out = root / ("jobs" if rep == 0 else f"jobs-{rep}")
        state, wall = _sweep(args, out, args.jobs)
        print(f"{args.jobs} job(s), {args.backend}: {wall:.1f} s wall; load {os.getloadavg()}")
        if args.compare_jobs:
            ratios.append(wall / wall_one)
            print(f"ratio {args.jobs} jobs / one job: {ratios[-1]:.3f}", flush=True)
        if rep == 0:
            _print_runs(args.scenario, state)
    if ratios:
        print(f"median ratio over {len(ratios)}: {statistics.median(ratios):.3f} (target <= 0.65)")
    if args.check_run and _check_run(args, root, state):
        sys.exit(1)


if __name__ == "__main__":
    try:
        main()
    except VisnavError as exc:  # bad --seeds / --map: one line, not a traceback
        sys.exit(f"error: {exc}")
