"""``visnav sweep car|drone|FILE --seeds 0-99 [--set k=v1,v2] --out DIR``; ``sweep report DIR``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from visnav.scenarios.sweep_spec import RUN_OPTIONS, SweepError, parse_seeds, parse_sets

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``sweep`` options."""
    keys = ", ".join(f"{k} ({o.type_name})" for k, o in RUN_OPTIONS.items())
    parser.add_argument(
        "scenario",
        help="car, drone or a scenario launch file (.yaml; --set keys: its args), or `report` "
        "to rebuild DIR/report.html: sweep report DIR",
    )
    parser.add_argument("dir", nargs="?", help="with `report`: the sweep directory")
    parser.add_argument("--seeds", default=None, help="seeds: 0-99, 0,3,7 or 4")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=V1,V2",
        help=f"vary a run option (one setting per value); keys: {keys} (a launch file: "
        "its args, record_all, record_images). car: map=runs/first/{seed}/map.yaml localises "
        "each run in the map its own seed's earlier run wrote (visnav run car --map)",
    )
    parser.add_argument("--jobs", type=int, default=None, help="runs at a time (default 1 local)")
    parser.add_argument("--backend", choices=["local", "ray"], default="local")
    parser.add_argument(
        "--address", default=None, help="ray: auto, HOST:PORT or ray://HOST:PORT (default: start)"
    )
    parser.add_argument("--cpus-per-run", type=float, default=1.0, help="ray: CPUs per run task")
    parser.add_argument("--resume", action="store_true", help="rerun only missing/failed runs")
    parser.add_argument("--timeout", type=float, default=None, help="fail a run after S wall s")
    parser.add_argument("--out", default=None, help="sweep directory (required)")
    parser.add_argument("--no-report", action="store_true", help="skip report.html")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=cmd_sweep)


def _report(args: argparse.Namespace) -> int:
    from visnav.scenarios.report import write_report
    from visnav.scenarios.sweep import load_state

    if args.dir is None:
        msg = "sweep report: the sweep directory is missing; run visnav sweep report DIR"
        raise SweepError(msg)
    sweep_dir = Path(args.dir).absolute()
    path = write_report(sweep_dir, load_state(sweep_dir))
    print(path)
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    """Run the sweep (or rebuild its report) and print where the outputs are."""
    if args.scenario == "report":
        return _report(args)
    if args.dir is not None:
        msg = f"sweep: unexpected argument {args.dir!r}; the output directory goes in --out DIR"
        raise SweepError(msg)
    if args.out is None:
        msg = "sweep: --out DIR is missing: the directory for the runs and the report"
        raise SweepError(msg)
    if args.timeout is not None and not args.timeout > 0:
        msg = f"--timeout is {args.timeout}: expected a positive number of seconds"
        raise SweepError(msg)
    seeds = parse_seeds(args.seeds) if args.seeds is not None else None
    from visnav.scenarios.sweep import SweepBackend, run_sweep
    from visnav.scenarios.sweep_spec import check_scenario, scenario_options

    scenario = check_scenario(args.scenario)
    options = scenario_options(scenario)
    sets = parse_sets(args.set, options) if args.set or seeds is not None else None
    backend: SweepBackend
    if args.backend == "ray":
        from visnav.scenarios.sweep_ray import RayBackend

        backend = RayBackend(
            jobs=args.jobs,
            timeout_s=args.timeout,
            address=args.address,
            cpus_per_run=args.cpus_per_run,
        )
    else:
        if args.address is not None:
            msg = "--address is for --backend ray; add --backend ray or leave --address out"
            raise SweepError(msg)
        from visnav.scenarios.sweep_local import LocalBackend

        jobs = 1 if args.jobs is None else args.jobs
        backend = LocalBackend(jobs=jobs, timeout_s=args.timeout)
    state = run_sweep(
        scenario,
        out=args.out,
        backend=backend,
        seeds=seeds,
        sets=sets,
        resume=args.resume,
        progress=None if args.quiet else sys.stderr,
        report=not args.no_report,
    )
    runs = state["runs"]
    ok = sum(1 for r in runs if r["status"] == "ok")
    print(f"{ok}/{len(runs)} runs ok; outputs in {Path(args.out).absolute()}")
    return 0 if ok == len(runs) else 1
