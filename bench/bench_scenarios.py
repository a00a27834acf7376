"""Acceptance runs of the built-in scenarios (issues 7 and 8), over seeds.

``python bench/bench_scenarios.py car --seeds 10`` runs ``visnav run car`` for seeds
0..9 (4 goals each in the office) and prints goals reached, collisions and the mean
path-length ratio to the shortest grid path on the true map; ``drone --seeds 20`` flies
20 seeded forests and prints reached / collisions / mean speed / clearance / planning
times. Each run's summary.json goes to a temporary bench-<scenario>-*/<seed>/ directory.
``--no-slam`` leaves the car's visual SLAM out (navigation only, ~2.5x faster);
``--jobs 2`` runs two seeds at a time in separate processes (each run is lock-step and
deterministic, so the figures do not depend on it; only the real-time factors do).
"""

from __future__ import annotations

import argparse
import multiprocessing
import statistics
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from visnav.graph import Context
from visnav.scenarios.runner import run_scenario


def _run(scenario: str, seed: int, out: Path, slam: bool) -> dict[str, Any]:
    with Context(transport="local") as ctx:
        return run_scenario(scenario, seed=seed, out=out, slam=slam, context=ctx, progress=None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", choices=["car", "drone"])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=1, help="seeds run at a time")
    parser.add_argument("--no-slam", action="store_true", help="car: navigation only")
    args = parser.parse_args()
    out_root = Path(tempfile.mkdtemp(prefix=f"bench-{args.scenario}-"))
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    pool = ProcessPoolExecutor(
        max_workers=max(1, args.jobs), mp_context=multiprocessing.get_context("spawn")
    )
    futures = [
        pool.submit(_run, args.scenario, seed, out_root / str(seed), not args.no_slam)
        for seed in seeds
    ]
    rows = []
    for seed, future in zip(seeds, futures, strict=True):
        s = future.result()
        rows.append(s)
        extra = (
            f"ratio {s.get('path_ratio')}"
            if args.scenario == "car"
            else f"speed {s['mean_speed_mps']} m/s clearance {s['min_clearance_m']} m "
            f"plan median {s['planning_time_ms']['median']} ms"
        )
        print(
            f"seed {seed}: {s['goals_reached']}/{s['goals_total']} goals, {s['collisions']} collisions, "
            f"{extra}, sim {s['sim_duration_s']:.0f} s, RTF {s['real_time_factor']}",
            flush=True,
        )
        if "slam" in s:
            print(f"  slam {s['slam']}", flush=True)
    pool.shutdown()
    goals = sum(r["goals_total"] for r in rows)
    reached = sum(r["goals_reached"] for r in rows)
    collisions = sum(r["collisions"] for r in rows)
    print(
        f"goals reached {reached}/{goals} ({100 * reached / goals:.1f} %), collisions {collisions}"
    )
    if args.scenario == "car":
        ratios = [r["path_ratio"] for r in rows if r.get("path_ratio")]
        if ratios:
            print(f"mean path ratio {statistics.mean(ratios):.3f} (target <= 1.3)")
    else:
        print(
            f"mean speed {statistics.mean(r['mean_speed_mps'] for r in rows):.2f} m/s (target >= 1.5)"
        )
        print(f"min clearance {min(r['min_clearance_m'] for r in rows):.3f} m")


if __name__ == "__main__":
    main()
