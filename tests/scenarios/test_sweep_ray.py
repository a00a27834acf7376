"""The Ray sweep backend: missing Ray and unreachable clusters in one line; runs as Ray tasks."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import cast

import pytest

from visnav.scenarios.sweep import load_state
from visnav.scenarios.sweep_check import run_differences
from visnav.scenarios.sweep_spec import SweepError

_CLI = (sys.executable, "-m", "visnav.cli.main", "sweep", "car")


def test_backend_ray_without_ray_names_the_fix(monkeypatch: pytest.MonkeyPatch) -> None:
    from visnav.scenarios.sweep_ray import RayBackend

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(SweepError, match=r"pip install 'visnav\[ray\]' \(or run with --backend"):
        RayBackend(jobs=1)


def test_unreachable_address_is_refused_quickly() -> None:
    pytest.importorskip("ray")
    from visnav.scenarios.sweep_ray import RayBackend

    t0 = time.monotonic()
    with pytest.raises(SweepError, match=r"cannot reach Ray at 127\.0\.0\.1:9 .*ray start --head"):
        RayBackend(address="ray://127.0.0.1:9")
    with pytest.raises(SweepError, match=r"expected auto, HOST:PORT or ray://HOST:PORT"):
        RayBackend(address="nowhere")
    assert time.monotonic() - t0 < 10.0


def test_cli_unreachable_address_one_line(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    done = subprocess.run(
        [
            *_CLI,
            "--seeds",
            "0",
            "--backend",
            "ray",
            "--address",
            "ray://127.0.0.1:9",
            "--quiet",
            "--out",
            str(tmp_path / "s"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(
        "error: --address ray://127.0.0.1:9: cannot reach Ray at 127.0.0.1:9"
    )
    assert not (tmp_path / "s").exists()


def test_no_cluster_at_auto_names_the_fix(tmp_path: Path) -> None:
    from visnav.scenarios.sweep_ray import RayBackend
    from visnav.scenarios.sweep_spec import RunSpec

    def refuse(**_: object) -> None:
        raise ConnectionError("Could not find any running Ray instance. Please specify ...")

    backend = RayBackend.__new__(RayBackend)  # Ray's own answer, without a Ray on the machine
    backend.ray = cast("ModuleType", SimpleNamespace(init=refuse))
    backend.address, backend.jobs, backend.cpus_per_run = "auto", None, 1.0
    runs = backend.run([RunSpec(0, "car", "default", {}, 0, 2**30)], tmp_path)
    with pytest.raises(SweepError) as info:
        next(iter(runs))
    message = str(info.value)
    assert message.startswith("--address auto: no Ray cluster there (Could not find any running")
    assert message.endswith("or leave --address out to start a local Ray")


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(600)
def test_ray_runs_equal_visnav_run_and_a_sigkill_fails_one(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    out = tmp_path / "sweep"
    setting = "slam=false,duration=4"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "visnav.cli.main",
            "sweep",
            "car",
            "--quiet",
            "--seeds",
            "0-2",
            "--set",
            "slam=false",
            "--set",
            "duration=4",
            "--backend",
            "ray",
            "--jobs",
            "2",
            "--out",
            str(out),
            "--no-report",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    log = out / "runs" / setting / "1" / "run.log"
    deadline = time.monotonic() + 240
    pid = None
    while pid is None and time.monotonic() < deadline and proc.poll() is None:
        m = re.match(r"visnav sweep worker pid (\d+)", log.read_text() if log.is_file() else "")
        pid = int(m.group(1)) if m else None
        time.sleep(0.1)
    assert pid is not None, "seed 1 never started"
    time.sleep(1.0)
    os.kill(pid, signal.SIGKILL)
    stdout, stderr = proc.communicate(timeout=400)
    assert proc.returncode == 1, stderr
    assert "2/3 runs ok" in stdout
    runs = {r["seed"]: r for r in load_state(out)["runs"]}
    assert runs[1]["status"] == "failed"
    assert runs[1]["reason"].startswith("killed by signal SIGKILL")
    for seed in (0, 2):
        assert runs[seed]["status"] == "ok"
        ref = tmp_path / f"run{seed}"
        subprocess.run(
            [
                sys.executable,
                "-m",
                "visnav.cli.main",
                "run",
                "car",
                "--quiet",
                "--no-slam",
                "--duration",
                "4",
                "--seed",
                str(seed),
                "--out",
                str(ref),
            ],
            capture_output=True,
            timeout=300,
            check=True,
            env={**os.environ, "VISNAV_DOMAIN": str(1_700_000_000 + os.getpid() + seed)},
        )
        assert run_differences(out / "runs" / setting / str(seed), ref) == []


@pytest.mark.parametrize("bag_limit", [10_000_000, 0])
def test_files_of_a_run_on_another_node_are_gathered(tmp_path: Path, bag_limit: int) -> None:
    from visnav.scenarios.sweep_ray import RayBackend, _collect
    from visnav.scenarios.sweep_spec import RunSpec

    spec = RunSpec(0, "car", "default", {}, 3, 2**30)
    remote = tmp_path / "node-b" / spec.rel_dir  # the worker node's copy of the run
    (remote / "bag").mkdir(parents=True)
    (remote / "bag" / "bag_0.mcap").write_bytes(b"mcap" * 100)
    summary = {"scenario": "car", "seed": 3, "bag": str(remote / "bag")}
    (remote / "summary.json").write_text(json.dumps(summary))
    (remote / "run.log").write_text("log\n")
    backend = RayBackend.__new__(RayBackend)  # no Ray needed to gather a result
    backend.ray = cast(
        "ModuleType",
        SimpleNamespace(get=lambda ref: ref, exceptions=SimpleNamespace(RayError=OSError)),
    )
    out = {
        "key": spec.key,
        "status": "ok",
        "reason": None,
        "summary": dict(summary),
        "wall_s": 2.0,
        "node": "node-b",
        "files": _collect(remote, bag_limit),
        "run_dir": str(remote),
    }
    sweep_dir = tmp_path / "sweep"
    result = backend._result(out, spec, sweep_dir, 2.0)
    local = sweep_dir / spec.rel_dir
    assert (local / "run.log").read_text() == "log\n"
    assert result.node == "node-b"
    assert result.summary is not None
    on_disk = json.loads((local / "summary.json").read_text())
    assert on_disk == result.summary
    if bag_limit:
        assert (local / "bag" / "bag_0.mcap").read_bytes() == b"mcap" * 100
        assert result.summary["bag"] == str(local / "bag")
    else:  # too large to send: stays on the worker, named node:path
        assert not (local / "bag").exists()
        assert result.summary["bag"] == f"node-b:{remote / 'bag'}"
