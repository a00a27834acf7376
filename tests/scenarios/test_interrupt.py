"""Ctrl-C on ``visnav run car``: SIGINT to the process group, as a terminal sends it.

While the nodes start and while the simulation and the SLAM worker process run, the run
exits 130 without a traceback, prints the summary and writes ``summary.json`` with
``"status": "interrupted"`` and what was measured so far (a SIGINT while the CLI's modules
load prints ``interrupted during start-up`` and exits 130: test_interrupt_signals.py, with
SIGTERM and the other long-running verbs). A run refused before it starts leaves no output
folder.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from visnav.graph import Context
from visnav.scenarios.run_control import RunInterrupt, record_status, scenario_output_arg
from visnav.scenarios.runner import TopicCounter, run_scenario

_TIMEOUT_S = 400.0  # a loaded 2-core machine: start-up alone can take a minute


class _Run:
    """``visnav run car`` in its own process group, stderr collected as it comes."""

    def __init__(self, out: Path, domain: int, *extra: str, command: tuple[str, ...] = ()) -> None:
        env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
        args = command or ("run", "car", "--out", str(out), *extra)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "visnav.cli.main", *args],
            cwd=out.parent,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,  # its own group: killpg reaches it and its workers only
        )
        self.err: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.err.append(line)

    def wait_for(self, ready: Callable[[], bool], what: str) -> None:
        deadline = time.monotonic() + _TIMEOUT_S
        while not ready():
            if self.proc.poll() is not None:
                pytest.fail(f"the run ended before {what}:\n{''.join(self.err)}")
            if time.monotonic() > deadline:
                self.kill()
                pytest.fail(f"no {what} within {_TIMEOUT_S} s:\n{''.join(self.err)}")
            time.sleep(0.05)

    def interrupt(self) -> tuple[int, str, str]:
        os.killpg(self.proc.pid, signal.SIGINT)  # the whole group, as the terminal's Ctrl-C
        try:
            self.proc.wait(timeout=_TIMEOUT_S)  # stdout is a few lines: no pipe fills up
        except subprocess.TimeoutExpired:
            self.kill()
            pytest.fail(f"the run did not end after SIGINT:\n{''.join(self.err)}")
        self._reader.join(timeout=10)
        assert self.proc.stdout is not None
        return self.proc.returncode, self.proc.stdout.read(), "".join(self.err)

    def kill(self) -> None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(timeout=30)


def _check_interrupted(out_dir: Path, code: int, stdout: str, stderr: str) -> dict[str, object]:
    assert code == 130, stderr
    assert "Traceback" not in stderr, stderr
    assert "error:" not in stderr, stderr
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    for key in ("real_time_factor", "topics", "bag", "sim_duration_s", "wall_duration_s"):
        assert key in summary, key
    assert "scenario car" in stdout  # the summary is printed, saying how it ended
    assert "\nstatus interrupted\n" in stdout
    return dict(summary)


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(900)
def test_ctrl_c_while_the_car_drives_writes_an_interrupted_summary(
    tmp_path: Path, domain: int
) -> None:
    out = tmp_path / "run"
    run = _Run(out, domain, "--duration", "60")
    # the progress lines come once the simulation steps (SLAM worker process running)
    run.wait_for(lambda: any(" sim 0." in line for line in run.err), "a progress line")
    time.sleep(1.0)
    code, stdout, stderr = run.interrupt()
    summary = _check_interrupted(out, code, stdout, stderr)
    assert 0 < float(summary["sim_duration_s"]) < 60  # type: ignore[arg-type]
    topics = summary["topics"]
    assert isinstance(topics, dict)
    assert topics["/clock"]["count"] > 0
    assert summary["goals_total"] == 4  # the observer's figures up to then
    assert (out / "bag").exists()
    assert "interrupted (Ctrl-C)" in stderr


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("delay_s", [0.0, 0.4])
def test_ctrl_c_as_the_first_frames_reach_slam(tmp_path: Path, domain: int, delay_s: float) -> None:
    # the nodes are built; the SLAM worker process starts with the first camera frame
    out = tmp_path / "run"
    run = _Run(out, domain, "--duration", "60")
    run.wait_for(lambda: any("started" in line for line in run.err), "the started line")
    time.sleep(delay_s)
    code, stdout, stderr = run.interrupt()
    _check_interrupted(out, code, stdout, stderr)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_ctrl_c_while_the_nodes_start(tmp_path: Path, domain: int) -> None:
    out = tmp_path / "run"
    run = _Run(out, domain, "--duration", "60")
    run.wait_for((out / "run.log").exists, "the run's log file")  # nodes starting
    code, stdout, stderr = run.interrupt()
    summary = _check_interrupted(out, code, stdout, stderr)
    assert float(summary["sim_duration_s"]) < 60  # type: ignore[arg-type]


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_ctrl_c_on_launch_car_says_so_and_writes_the_summary(tmp_path: Path, domain: int) -> None:
    run = _Run(tmp_path / "unused", domain, command=("launch", "car", "duration:=60"))
    run.wait_for(lambda: any("started" in line for line in run.err), "the started line")
    time.sleep(2.0)
    code, _, stderr = run.interrupt()
    assert code == 130, stderr
    assert "Traceback" not in stderr
    assert "launch ended: SIGINT (Ctrl-C)" in stderr
    summaries = list((tmp_path / "runs").glob("*/summary.json"))  # where `visnav run` writes
    assert len(summaries) == 1, stderr
    summary = json.loads(summaries[0].read_text())
    assert summary["status"] == "interrupted"
    assert summary["scenario"] == "car"


@pytest.mark.slow
@pytest.mark.timeout(300)
@pytest.mark.parametrize("verb", ["run", "launch"])
def test_a_refused_run_leaves_no_folder(tmp_path: Path, domain: int, verb: str) -> None:
    source = Path(__file__).parents[2] / "src/visnav/scenarios/launch/car.launch.yaml"
    bad = tmp_path / "bad.launch.yaml"
    bad.write_text(source.read_text().replace("world: office", "world: no_such_world", 1))
    out = tmp_path / "run"
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    args = ["run", str(bad), "--out", str(out)] if verb == "run" else ["launch", str(bad)]
    done = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", *args],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert done.returncode == 1, done.stderr
    assert "no_such_world" in done.stderr.strip().splitlines()[-1]
    assert "Traceback" not in done.stderr
    assert not out.exists()
    assert not list(tmp_path.glob("runs/*"))  # `visnav launch`'s default folder neither


def test_a_bad_argument_leaves_no_folder(tmp_path: Path) -> None:
    out = tmp_path / "run"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "visnav.cli.main",
            "run",
            "car",
            "--duration",
            "0",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 1
    assert not out.exists()


def test_the_first_ctrl_c_asks_the_second_stops_at_once() -> None:
    class Launcher:
        stops = 0

        def request_stop(self) -> None:
            self.stops += 1

    launcher = Launcher()
    interrupt = RunInterrupt()
    before = signal.getsignal(signal.SIGINT)
    with interrupt.installed():
        interrupt.attach(launcher)
        assert not interrupt()
        signal.raise_signal(signal.SIGINT)  # the first: a request, no exception
        assert interrupt()
        assert launcher.stops == 1
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)  # the second: now
    assert interrupt.count == 2
    assert signal.getsignal(signal.SIGINT) is before  # the previous handler is back
    late = Launcher()
    interrupt.attach(late)  # attached after the request: stopped at once
    assert late.stops == 1


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_an_error_during_the_run_writes_a_failed_summary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = []
    poll = TopicCounter.poll

    def failing_poll(self: TopicCounter) -> None:
        calls.append(1)
        if len(calls) == 3:
            msg = "a fault injected by the test"
            raise RuntimeError(msg)
        poll(self)

    monkeypatch.setattr(TopicCounter, "poll", failing_poll)
    out = tmp_path / "run"
    with Context(transport="local") as ctx, pytest.raises(RuntimeError, match="injected"):
        run_scenario("car", duration_s=5.0, out=out, context=ctx, progress=None)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed"
    assert summary["error"] == "RuntimeError: a fault injected by the test"
    assert summary["sim_duration_s"] > 0
    for key in ("real_time_factor", "topics", "bag"):
        assert key in summary


def test_launch_of_a_scenario_gets_an_output_folder_and_a_status(tmp_path: Path) -> None:
    observer = ["sim", "scenario_observer"]
    out = scenario_output_arg({"out": None}, {}, observer)
    assert Path(out).parent.name == "runs"  # where `visnav run` writes
    assert scenario_output_arg({"out": None}, {"out": "mine"}, observer) == ""  # given
    assert scenario_output_arg({}, {}, observer) == ""  # no out arg
    assert scenario_output_arg({"out": None}, {}, ["sim"]) == ""  # no observer: no scenario
    assert record_status(tmp_path, "interrupted") is None  # nothing written: nothing to mark
    (tmp_path / "summary.json").write_text('{"scenario": "car", "goals_total": 4}\n')
    path = record_status(tmp_path, "interrupted", reason="SIGINT (Ctrl-C)")
    assert path == tmp_path / "summary.json"
    summary = json.loads(path.read_text())
    assert summary == {
        "status": "interrupted",
        "end_reason": "SIGINT (Ctrl-C)",
        "scenario": "car",
        "goals_total": 4,
    }
