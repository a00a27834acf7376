"""The local sweep backend: isolated runs, failures with reasons, SIGKILL, Ctrl-C, --resume."""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from visnav.scenarios.sweep import load_state
from visnav.scenarios.sweep_check import run_differences
from visnav.scenarios.sweep_local import LocalBackend
from visnav.scenarios.sweep_spec import RunSpec, SweepError
from visnav.scenarios.sweep_worker import finish_run


def _spec(scenario: str, seed: int = 0, **options: Any) -> RunSpec:
    return RunSpec(0, scenario, "t", options, seed, 1_500_000_000 + os.getpid() + seed)


def test_a_crashing_run_fails_with_its_last_log_line(tmp_path: Path) -> None:
    results = list(LocalBackend(jobs=1).run([_spec("nope")], tmp_path))
    assert len(results) == 1
    assert results[0].status == "failed"
    assert results[0].reason is not None
    assert results[0].reason.startswith("exit code 1: error: unknown scenario 'nope'")
    assert (tmp_path / "runs/t/0/run.log").read_text().startswith("visnav sweep worker pid")


def test_a_run_past_the_timeout_is_killed_and_failed(tmp_path: Path) -> None:
    backend = LocalBackend(jobs=1, timeout_s=2.0)
    t0 = time.monotonic()
    [result] = backend.run([_spec("car", duration=120.0)], tmp_path)
    assert time.monotonic() - t0 < 15.0
    assert result.status == "failed"
    assert result.reason is not None
    assert result.reason.startswith("timeout: still running after 2 s (killed; log ")
    pid = backend.started["t/0"]
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)


def test_a_signal_is_named_in_the_reason(tmp_path: Path) -> None:
    result = finish_run(_spec("car"), tmp_path, -signal.SIGKILL, 1.0, timed_out=None)
    assert result.status == "failed"
    assert result.reason is not None
    assert result.reason.startswith("killed by signal SIGKILL")


def test_jobs_must_be_positive() -> None:
    with pytest.raises(SweepError, match="--jobs is 0: expected at least 1"):
        LocalBackend(jobs=0)


def _sweep(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", "sweep", "car", "--quiet", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _worker_pid(run_dir: Path, timeout_s: float = 60.0) -> int:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        log = run_dir / "run.log"
        if log.is_file():
            m = re.match(r"visnav sweep worker pid (\d+)", log.read_text())
            if m:
                return int(m.group(1))
        time.sleep(0.1)
    pytest.fail(f"no worker started in {run_dir}")


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(300)
def test_sigkilled_run_fails_others_complete_resume_completes(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    sets = ["--set", "slam=false", "--set", "duration=4"]
    proc = _sweep("--seeds", "0-2", *sets, "--jobs", "2", "--out", str(out))
    victim = out / "runs" / "slam=false,duration=4" / "1"
    pid = _worker_pid(victim)
    time.sleep(1.0)  # mid-run: past start-up, well before the 4 s of sim end
    os.kill(pid, signal.SIGKILL)
    stdout, stderr = proc.communicate(timeout=240)
    assert proc.returncode == 1, stderr
    assert "2/3 runs ok" in stdout
    state = load_state(out)
    status = {r["seed"]: (r["status"], r["reason"]) for r in state["runs"]}
    assert status[0] == ("ok", None)
    assert status[2] == ("ok", None)
    assert status[1][0] == "failed"
    assert status[1][1].startswith("killed by signal SIGKILL (log ")
    rows = list(csv.DictReader((out / "sweep.csv").open()))
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert rows[0]["topics./scan.type"] == "sensor_msgs/msg/LaserScan"
    assert "killed by signal SIGKILL" in (out / "report.html").read_text()
    ok_summary = (out / "runs/slam=false,duration=4/0/summary.json").read_text()

    resumed = _sweep("--resume", "--out", str(out))
    stdout, stderr = resumed.communicate(timeout=240)
    assert resumed.returncode == 0, stderr
    assert "3/3 runs ok" in stdout
    state = load_state(out)
    assert [r["status"] for r in state["runs"]] == ["ok", "ok", "ok"]
    assert (victim / "summary.json").is_file()
    # the runs that were ok are not run again
    assert (out / "runs/slam=false,duration=4/0/summary.json").read_text() == ok_summary


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_ctrl_c_leaves_a_consistent_directory(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    proc = _sweep(
        "--seeds", "0-1", "--set", "slam=false", "--set", "duration=30", "--out", str(out)
    )
    _worker_pid(out / "runs" / "slam=false,duration=30" / "0")
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    state = json.loads((out / "sweep.json").read_text())
    assert [r["status"] for r in state["runs"]] == ["interrupted", "interrupted"]
    assert not (out / "runs" / "slam=false,duration=30" / "0").exists()  # partial run removed
    assert (out / "sweep.csv").is_file()


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_sweep_runs_equal_visnav_run_one_at_a_time(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    done = subprocess.run(
        [
            sys.executable, "-m", "visnav.cli.main", "sweep", "car", "--quiet", "--seeds", "0-1",
            "--set", "slam=false", "--set", "duration=5", "--jobs", "2", "--out", str(out),
            "--no-report",
        ],
        capture_output=True, text=True, timeout=400, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    for seed in (0, 1):
        ref = tmp_path / f"run{seed}"
        subprocess.run(
            [
                sys.executable, "-m", "visnav.cli.main", "run", "car", "--quiet", "--no-slam",
                "--duration", "5", "--seed", str(seed), "--out", str(ref),
            ],
            capture_output=True, timeout=300, check=True,
            env={**os.environ, "VISNAV_DOMAIN": str(1_600_000_000 + os.getpid() + seed)},
        )  # fmt: skip
        assert run_differences(out / f"runs/slam=false,duration=5/{seed}", ref) == []


def test_visnav_run_progress_lines_from_rich(tmp_path: Path) -> None:
    import io

    from visnav.graph import Context
    from visnav.scenarios.runner import run_scenario

    stream = io.StringIO()  # not a terminal: one line per tenth of the run, then the last
    with Context(transport="local") as ctx:
        run_scenario("car", duration_s=0.5, out=tmp_path / "r", context=ctx, progress=stream)
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("[car] sim 0.1/0.5 s  RTF ")
    assert lines[-1].startswith("[car] sim 0.5/0.5 s  RTF ")
    assert 5 <= len(lines) <= 7
