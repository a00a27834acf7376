"""Issue 13's soak: sim + recorder + a viewer feed + one deliberately slow subscriber.

Runs ``VISNAV_SOAK_S`` seconds (default 120: a check that it still holds; the acceptance
figures in BENCHMARKS.md are from ``VISNAV_SOAK_S=600``, ten minutes) in a private domain,
every part a real process:
``visnav sim`` (car in the office, RGB 10 Hz, depth 5 Hz, real time), ``visnav bag record``
of the small topics, a viewer-like subscriber and a slow one (``subscriber.py``). Checks:

* RSS of every process flat: within +-5 % between the end of the warm-up (a fifth of the
  run, at least 30 s) and the end;
* nothing lost that QoS did not allow: in both subscribers every gap in a publisher's
  sequence numbers is a message its own keep-last queue dropped (and counted), the slow one
  (300 ms per image, keep-last 2) really drops, the fast topics of the viewer drop nothing;
  the bag holds every /odom message of its time span (50 Hz in sim time, no gap).

Figures go to BENCHMARKS.md ("Soak").
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import pytest

HERE = Path(__file__).parent
SECONDS = float(os.environ.get("VISNAV_SOAK_S", "120"))
RSS_KEY = "rss_mib (warm-up, end, peak)"
RECORDED = ["/clock", "/tf", "/odom", "/joint_states", "/ground_truth/odom"]


def _rss(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


class Procs:
    """The soak's processes; killed at the end whatever happens."""

    def __init__(self, env: dict[str, str], logs: Path) -> None:
        self.env = env
        self.logs = logs
        self.procs: dict[str, subprocess.Popen[str]] = {}

    def start(self, name: str, args: list[str], *, ready: bool = False) -> subprocess.Popen[str]:
        # logs go to files: a full pipe nobody reads would block the process for the whole run
        with (
            (self.logs / f"{name}.err").open("w") as err,
            (self.logs / f"{name}.out").open("w") as out,
        ):
            proc = subprocess.Popen(
                [sys.executable, *args],
                env=self.env,
                stdout=subprocess.PIPE if ready else out,
                stderr=err,
                text=True,
                start_new_session=True,
            )
        self.procs[name] = proc
        if ready:
            stdout: IO[str] | None = proc.stdout
            assert stdout is not None
            line = stdout.readline().strip()
            assert line == "ready", f"{name} did not start: {line!r} {self.log(name)}"
        return proc

    def log(self, name: str) -> str:
        """The end of a process's stderr."""
        return (self.logs / f"{name}.err").read_text()[-6000:]

    def kill(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=10)


@pytest.fixture
def procs(domain: int, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[Procs]:
    if os.environ.get("MUJOCO_GL", "").strip().lower() not in ("egl", "osmesa"):
        monkeypatch.setenv("MUJOCO_GL", "egl")
    env = {**os.environ, "VISNAV_DOMAIN": str(domain), "PYTHONFAULTHANDLER": "1"}
    env.pop("VISNAV_TRANSPORT", None)
    # a pytest started in the background ignores SIGINT, and children inherit that; a Python
    # handler here is reset to the default in them, so they stop on SIGINT
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    p = Procs(env, tmp_path)
    try:
        yield p
    finally:
        p.kill()
        signal.signal(signal.SIGINT, old)


def _reports(procs: Procs, name: str) -> list[dict[str, Any]]:
    proc = procs.procs[name]
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 0, procs.log(name)
    return [json.loads(line) for line in out.splitlines() if line.startswith("{")]


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(SECONDS + 600)
def test_soak(procs: Procs, tmp_path: Path) -> None:
    from visnav.bag import bag_info, read_bag
    from visnav.msgs.time import time_to_ns

    warmup = max(30.0, SECONDS / 5)
    cli = ["-m", "visnav.cli.main"]
    sim_args = ["--world", "office", "--robot", "car", "--realtime", "--seed", "3"]
    sim_args += ["--arg", "camera_rate:=10", "--arg", "depth_rate:=5"]
    sim = procs.start("sim", [*cli, "sim", *sim_args, "--duration", str(SECONDS + 120)])
    procs.start("viewer", [str(HERE / "subscriber.py"), "viewer", str(SECONDS)], ready=True)
    procs.start("slow", [str(HERE / "subscriber.py"), "slow", str(SECONDS)], ready=True)
    bag = tmp_path / "soak"
    recorder = procs.start(
        "recorder", [*cli, "bag", "record", "-o", str(bag), "--duration", str(SECONDS), *RECORDED]
    )
    started = time.monotonic()
    rss: dict[str, list[tuple[float, int]]] = {"sim": [], "recorder": []}
    while (elapsed := time.monotonic() - started) < SECONDS - 3:
        time.sleep(min(5.0, SECONDS - 3 - elapsed))
        assert sim.poll() is None, procs.log("sim")
        elapsed = time.monotonic() - started
        rss["sim"].append((elapsed, _rss(sim.pid)))
        rss["recorder"].append((elapsed, _rss(recorder.pid)))
    viewer_reports = _reports(procs, "viewer")
    slow_reports = _reports(procs, "slow")
    assert recorder.wait(timeout=120) == 0, procs.log("recorder")
    rec_out = (tmp_path / "recorder.out").read_text()
    sim.send_signal(signal.SIGINT)
    try:
        sim.wait(timeout=60)
    except subprocess.TimeoutExpired:
        sim.send_signal(signal.SIGABRT)  # PYTHONFAULTHANDLER: every thread's stack to the log
        sim.wait(timeout=30)
        pytest.fail(f"visnav sim did not stop within 60 s of SIGINT:\n{procs.log('sim')}")

    figures: dict[str, Any] = {"seconds": SECONDS, RSS_KEY: {}}

    def flat(name: str, samples: list[tuple[float, int]]) -> None:
        first = min(samples, key=lambda s: abs(s[0] - warmup))[1]
        last, peak = samples[-1][1], max(s[1] for s in samples if s[0] >= warmup)
        figures[RSS_KEY][name] = [round(x / 2**20, 1) for x in (first, last, peak)]
        assert abs(last - first) <= 0.05 * first, f"{name} RSS {first} -> {last}"

    for name, samples in rss.items():
        flat(name, samples)
    for name, reports in (("viewer", viewer_reports), ("slow", slow_reports)):
        flat(name, [(r["elapsed"], r["rss"]) for r in reports])
        final = reports[-1]
        assert final["final"]
        figures[name] = final["topics"]
        for topic, stats in final["topics"].items():
            assert stats["received"] > 0, f"{name} got nothing on {topic}"
            assert stats["gaps"] == stats["dropped"], f"{name} lost {topic} silently: {stats}"
    images = slow_reports[-1]["topics"]["/camera/image_raw"]
    assert images["dropped"] > 0  # the slow callback really was slower than the stream
    for topic in ("/odom", "/tf"):
        assert viewer_reports[-1]["topics"][topic]["dropped"] == 0, topic

    info = bag_info(bag)
    stamps = [time_to_ns(m.msg.header.stamp) for m in read_bag(bag, ["/odom"])]
    span_steps = round((stamps[-1] - stamps[0]) / 20_000_000)
    figures["bag"] = {
        "odom": len(stamps),
        "odom_expected": span_steps + 1,
        "odom_sim_span_s": (stamps[-1] - stamps[0]) / 1e9,
        "messages": info.message_count,
        "bytes": info.size_bytes,
    }
    figures["recorder_stdout"] = rec_out[-400:]
    (tmp_path / "figures.json").write_text(json.dumps(figures, indent=1))
    print(json.dumps(figures, indent=1))
    assert len(stamps) == span_steps + 1
