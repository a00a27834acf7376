"""The viewer's cost: real-time factor of short runs with and without ``--view``, bag playback.

Run: ``python bench/bench_viewer.py [--duration 8] [--repeats 2] [--scenarios car drone]``.

Live: ``visnav run SCENARIO --duration D`` alternately without and with ``--view`` (the web
viewer serving on 127.0.0.1, no page open), each ``--repeats`` times in this one run; the
real-time factor is the run's own (``summary.json``: simulated / wall seconds of the
stepping loop, start-up excluded). Reported: the medians and the ratio view / no view
(goal >= 0.9). The car runs without SLAM so the runs stay short on a loaded machine.

Bag: a car run with ``--record-images`` is played into the viewer's path (``DisplaySink``:
display rate, JPEG, worker thread) with the web viewer serving; reported: wall seconds
per simulated second of the bag (goal <= 1) and the viewer's latency, the time from the
longest a message waited between being read from the bag and handed to the viewer's
server (goal <= 1 s). The world's geometry is loaded first, on the worker (included).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["main"]


def _env() -> dict[str, str]:
    """A graph domain of its own: other simulations on the machine stay out of the runs."""
    return {**os.environ, "VISNAV_DOMAIN": str(random.SystemRandom().randint(20_000, 60_000))}


def _run(scenario: str, duration: float, out: Path, *, view: bool) -> float:
    cmd = ["visnav", "run", scenario, "--duration", str(duration), "--out", str(out), "--quiet"]
    if scenario == "car":
        cmd.append("--no-slam")
    if view:
        cmd.append("--view")
    subprocess.run(
        cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=_env()
    )
    summary = json.loads((out / "summary.json").read_text())
    if view and (out / "run.rrd").exists():
        sys.exit(f"{out}: --view wrote run.rrd")
    return float(summary["real_time_factor"])


def _bag_playback(tmp: Path, duration: float) -> tuple[float, float, float]:
    """(wall s per sim s, latency s, sim s) of a car bag with images played to the viewer."""
    from visnav.bag import BagReader
    from visnav.viz import RerunSink, open_viewer
    from visnav.viz.display_sink import DisplaySink
    from visnav.viz.scene import world_for_bag
    from visnav.viz.sources import feed_bag

    out = tmp / "bagrun"
    cmd = ["visnav", "run", "car", "--no-slam", "--record-images", "--duration", str(duration)]
    subprocess.run(
        [*cmd, "--out", str(out), "--quiet"],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=_env(),
    )
    bag = out / "bag"
    with BagReader(bag) as reader:
        sim_s = (reader.end_ns - reader.start_ns) / 1e9
    with open_viewer(web=True, port=0, grpc_port=0, log_path=tmp / "viewer.log") as viewer:
        sink = DisplaySink(
            RerunSink(viewer.recording),
            block=True,
            max_pending=16,
            world_loader=lambda: world_for_bag(bag),
        )
        start = time.perf_counter()
        feed_bag(sink, bag)  # closes the sink: the worker has logged everything
        viewer.recording.flush()
        done = time.perf_counter()
    # latency: the longest a message waited between being read and handed to the server
    return (done - start) / max(sim_s, 1e-9), sink.max_latency_s, sim_s


def main() -> None:
    """Measure and print."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=8.0)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--scenarios", nargs="*", default=["car", "drone"])
    parser.add_argument("--no-bag", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_viewer_") as name:
        tmp = Path(name)
        for scenario in args.scenarios:
            rtf: dict[bool, list[float]] = {False: [], True: []}
            for i in range(args.repeats):
                for view in (False, True):
                    out = tmp / f"{scenario}-{i}-{int(view)}"
                    rtf[view].append(_run(scenario, args.duration, out, view=view))
            base, viewed = statistics.median(rtf[False]), statistics.median(rtf[True])
            print(
                f"{scenario} {args.duration:g} s: RTF without view {base:.3f} "
                f"(runs {', '.join(f'{v:.3f}' for v in rtf[False])}), with --view {viewed:.3f} "
                f"(runs {', '.join(f'{v:.3f}' for v in rtf[True])}); ratio {viewed / base:.2f} "
                "(goal >= 0.9)"
            )
        if not args.no_bag:
            per_s, latency, sim_s = _bag_playback(tmp, args.duration)
            print(
                f"car bag with images ({sim_s:.1f} sim s) into the web viewer: "
                f"{per_s:.3f} wall s per sim s (goal <= 1), latency {latency:.2f} s (goal <= 1)"
            )


if __name__ == "__main__":
    main()
