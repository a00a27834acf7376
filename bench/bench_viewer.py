"""The viewer's cost: real-time factor of short runs with and without ``--view``, bag playback.

Run: ``python bench/bench_viewer.py [--duration 8] [--repeats 2] [--scenarios car drone]``.

Live: ``visnav run SCENARIO --duration D`` alternately without ``--view``, with ``--view``
(the web viewer serving on 127.0.0.1, no page open) and with ``--view`` and a headless
Chromium page open on the viewer (``/usr/bin/chromium``, software rendering through
SwiftShader, sharing the machine's cores with the run: ``--no-page`` or no Chromium
skips that case), each ``--repeats`` times in this one run; the real-time factor is the
run's own (``summary.json``: simulated / wall seconds of the stepping loop, start-up
excluded). Reported: the medians and the ratios to the runs without the viewer (goals:
>= 0.9 serving with no page, >= 0.7 with a page), and CPU seconds per simulated second
(user + system, start-up included; on a loaded machine the wall-clock real-time factor
swings with the load, the CPU time much less): of the run with its viewer process, of
the viewer process alone and of its worker thread (the viewer's ``viewer.log``), and the
viewer process's peak resident memory. The car runs without SLAM so the runs stay short
on a loaded machine.

The ``--view`` runs serve on free ports (``--port 0 --grpc-port 0``), so a viewer serving
on the fixed defaults (9090 page, 9876 gRPC) does not make them fail.

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
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import NamedTuple

__all__ = ["main"]


def _env() -> dict[str, str]:
    """A graph domain of its own: other simulations on the machine stay out of the runs."""
    return {**os.environ, "VISNAV_DOMAIN": str(random.SystemRandom().randint(20_000, 60_000))}


CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_FLAGS = (  # as tests/viz/_cdp.py starts it for the screenshot tests
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--window-size=1280,800",
    "--remote-debugging-address=127.0.0.1",
    "--remote-debugging-port=0",  # keeps the headless browser open on the page
)

CASES = ("none", "view", "page")
"""No viewer; ``--view`` serving with no page; ``--view`` with a Chromium page open."""


class RunResult(NamedTuple):
    """One run: its real-time factor and the run process's CPU seconds per simulated second."""

    rtf: float
    cpu_per_sim_s: float
    worker_cpu_per_sim_s: float | None
    """The viewer's worker thread (``viewer.log``'s "viewer: worker CPU" line)."""
    viewer_cpu_per_sim_s: float | None
    """The viewer process (``viewer.log``'s "viewer process CPU" line)."""
    viewer_rss_mb: float | None
    """The viewer process's peak resident memory (``viewer.log``)."""


def _open_page(url: str, tmp: Path) -> subprocess.Popen[bytes]:
    profile = tmp / f"chromium-{time.monotonic_ns()}"
    profile.mkdir()
    log = (tmp / "chromium.log").open("ab")
    return subprocess.Popen(
        [str(CHROMIUM), *CHROMIUM_FLAGS, f"--user-data-dir={profile}", url],
        stdout=log,
        stderr=subprocess.STDOUT,
    )


def _run(scenario: str, duration: float, out: Path, *, case: str, tmp: Path) -> RunResult:
    cmd = ["visnav", "run", scenario, "--duration", str(duration), "--out", str(out), "--quiet"]
    if scenario == "car":
        cmd.append("--no-slam")
    if case != "none":
        cmd += ["--view", "--port", "0", "--grpc-port", "0"]
    proc = subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=_env(), cwd=tmp
    )
    assert proc.stderr is not None
    page: subprocess.Popen[bytes] | None = None
    err: list[bytes] = []
    try:
        for line in proc.stderr:  # "viewer: URL" comes before the simulation starts
            err.append(line)
            text = line.decode(errors="replace").strip()
            if case == "page" and page is None and text.startswith("viewer: http"):
                page = _open_page(text.split(" ", 1)[1], tmp)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    finally:
        if page is not None:
            page.terminate()
            page.wait(timeout=30)
    if proc.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{b''.join(err[-20:]).decode(errors='replace')}")
    if case == "page" and page is None:
        sys.exit(f"{out}: the run printed no viewer address: no page was opened")
    summary = json.loads((out / "summary.json").read_text())
    if case != "none" and (out / "run.rrd").exists():
        sys.exit(f"{out}: --view wrote run.rrd")
    cpu = usage.ru_utime + usage.ru_stime
    sim_s = max(float(summary["sim_duration_s"]), 1e-9)
    log = (out / "viewer.log").read_text(errors="replace") if case != "none" else ""
    found = _WORKER_CPU.search(log)
    worker = float(found.group(1)) / sim_s if found else None
    found = _PROCESS.search(log)
    own = float(found.group(2)) / sim_s if found else None
    rss = float(found.group(1)) if found else None
    return RunResult(float(summary["real_time_factor"]), cpu / sim_s, worker, own, rss)


_WORKER_CPU = re.compile(r"viewer: worker CPU ([0-9.]+) s")
_PROCESS = re.compile(
    r"peak RSS of the viewer process ([0-9.]+) MB.*viewer process CPU ([0-9.]+) s"
)


def _live(args: argparse.Namespace, scenario: str, tmp: Path) -> None:
    cases = [c for c in CASES if c != "page" or (not args.no_page and CHROMIUM.exists())]
    runs: dict[str, list[RunResult]] = {c: [] for c in cases}
    for i in range(args.repeats):
        for case in cases:  # interleaved: every case sees the same machine load
            out = tmp / f"{scenario}-{i}-{case}"
            runs[case].append(_run(scenario, args.duration, out, case=case, tmp=tmp))
    rtf = {c: statistics.median(r.rtf for r in runs[c]) for c in cases}
    cpu = {c: statistics.median(r.cpu_per_sim_s for r in runs[c]) for c in cases}
    label = {"none": "without view", "view": "with --view", "page": "with --view + page"}
    for case in cases:
        each = ", ".join(f"{r.rtf:.3f}" for r in runs[case])
        line = (
            f"{scenario} {args.duration:g} s {label[case]:>19}: RTF {rtf[case]:.3f} "
            f"(runs {each}), CPU {cpu[case]:.2f} s per sim s"
        )
        owns = [r.viewer_cpu_per_sim_s for r in runs[case] if r.viewer_cpu_per_sim_s is not None]
        workers = [r.worker_cpu_per_sim_s for r in runs[case] if r.worker_cpu_per_sim_s is not None]
        rss = [r.viewer_rss_mb for r in runs[case] if r.viewer_rss_mb is not None]
        if owns and workers and rss:
            line += (
                f" (viewer process {statistics.median(owns):.2f}, its worker thread "
                f"{statistics.median(workers):.3f}; peak RSS {max(rss):.0f} MB)"
            )
        if case != "none":
            goal = 0.9 if case == "view" else 0.7
            line += (
                f"; ratio RTF {rtf[case] / rtf['none']:.2f} (goal >= {goal}), "
                f"CPU x{cpu[case] / cpu['none']:.2f}"
            )
        print(line, flush=True)


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
    parser.add_argument("--no-page", action="store_true", help="no run with a Chromium page")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_viewer_") as name:
        tmp = Path(name)
        for scenario in args.scenarios:
            _live(args, scenario, tmp)
        if not args.no_bag:
            per_s, latency, sim_s = _bag_playback(tmp, args.duration)
            print(
                f"car bag with images ({sim_s:.1f} sim s) into the web viewer: "
                f"{per_s:.3f} wall s per sim s (goal <= 1), latency {latency:.2f} s (goal <= 1)"
            )


if __name__ == "__main__":
    main()
