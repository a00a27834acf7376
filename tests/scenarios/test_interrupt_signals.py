"""SIGTERM is Ctrl-C for every long-running verb, and Ctrl-C during start-up is one line.

A ``kill PID``, a CI job's timeout, ``docker stop`` and systemd stop a program with SIGTERM
sent to its process only (not to its group, as a terminal's Ctrl-C is). Each verb that
runs until stopped (``run``, ``launch``, ``sweep``, ``bridge``, ``foxglove``, ``bag record``)
must then stop its children, close what it writes (the summary with ``"status":
"interrupted"`` and ``"end_reason": "SIGTERM"``, the bag), exit 143 (128 + 15; ``bag
record`` 0, as after Ctrl-C and as ``ros2 bag record``) without a traceback and leave no
process behind (every descendant seen while it ran, the SLAM worker
included, which runs in a session of its own, is checked with psutil).

Start-up: a SIGINT to the process group 0.1 .. 3 s after the command is spawned, while
Python and visnav's modules load and before the verb runs, prints ``interrupted during
start-up`` and exits 130, with no output folder: nothing was written yet. (A signal in the
first tenths of a second can land while the interpreter itself starts, importing its
``site`` module, before any of visnav's code runs: Python then reports it itself; the test
accepts only that report there.)
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from visnav.bag.info import bag_info
from visnav.cli._signals import TerminateAsInterrupt
from visnav.scenarios.run_control import RunInterrupt

psutil = pytest.importorskip("psutil")

_TIMEOUT_S = 600.0  # a loaded 2-core machine: a car's start-up alone can take minutes
_CAR_KEYS = ("real_time_factor", "topics", "bag", "sim_duration_s", "wall_duration_s")
_COMMAND = Path(sys.executable).with_name("visnav")


def _default_signals() -> None:
    """In the child: SIGINT as a terminal's program gets it (a background job ignores it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _command() -> list[str]:
    """The installed ``visnav`` script (as a user starts it), else ``python -m``."""
    if _COMMAND.is_file():
        return [sys.executable, str(_COMMAND)]
    return [sys.executable, "-m", "visnav.cli.main"]


class _Proc:
    """A visnav command in its own session; output collected; its descendants tracked."""

    def __init__(self, args: list[str], cwd: Path, domain: int) -> None:
        cwd.mkdir(parents=True, exist_ok=True)
        env = {**os.environ, "VISNAV_DOMAIN": str(domain), "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen(
            [*_command(), *args],
            cwd=cwd,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
            preexec_fn=_default_signals,  # noqa: PLW1509 - signal.signal only, before exec
        )
        self.t0 = time.monotonic()
        self.out: list[str] = []
        self.err: list[str] = []
        self.seen: dict[int, Any] = {}
        self._readers = [
            threading.Thread(target=self._read, args=(s, b), daemon=True)
            for s, b in ((self.proc.stdout, self.out), (self.proc.stderr, self.err))
        ]
        for reader in self._readers:
            reader.start()

    @staticmethod
    def _read(stream: Any, into: list[str]) -> None:
        for line in stream:
            into.append(line)

    def text(self) -> str:
        return "".join(self.out) + "".join(self.err)

    def track(self) -> None:
        """Remember the process's descendants now (they must all be gone at the end)."""
        with contextlib.suppress(psutil.Error):
            for child in psutil.Process(self.proc.pid).children(recursive=True):
                self.seen[child.pid] = child

    def wait_for(self, ready: Callable[[], bool], what: str) -> None:
        deadline = time.monotonic() + _TIMEOUT_S
        while not ready():
            self.track()
            if self.proc.poll() is not None:
                pytest.fail(f"the command ended before {what}:\n{self.text()}")
            if time.monotonic() > deadline:
                self.kill()
                pytest.fail(f"no {what} within {_TIMEOUT_S} s:\n{self.text()}")
            time.sleep(0.05)
        self.track()

    def signal(self, sig: int, *, group: bool = False) -> tuple[int, str, str]:
        self.track()
        (os.killpg if group else os.kill)(self.proc.pid, sig)
        try:
            self.proc.wait(timeout=_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.kill()
            pytest.fail(f"the command did not end after signal {sig}:\n{self.text()}")
        for reader in self._readers:
            reader.join(timeout=10)
        return self.proc.returncode, "".join(self.out), "".join(self.err)

    def left_behind(self, grace_s: float = 20.0) -> list[str]:
        """The descendants seen that are still running ``grace_s`` after the exit."""
        deadline = time.monotonic() + grace_s
        while True:
            alive = []
            for pid, child in self.seen.items():
                with contextlib.suppress(psutil.Error):
                    if child.is_running() and child.status() != psutil.STATUS_ZOMBIE:
                        alive.append(f"{pid} {' '.join(child.cmdline())[:120]}")
            if not alive or time.monotonic() > deadline:
                return alive
            time.sleep(0.2)

    def kill(self) -> None:
        for child in self.seen.values():
            with contextlib.suppress(psutil.Error):
                child.kill()
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(timeout=30)


def _assert_clean_exit(code: int, stderr: str, expected: int = 143) -> None:
    assert code == expected, stderr
    assert "Traceback" not in stderr, stderr
    assert "error:" not in stderr, stderr


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


# ---------------------------------------------------------------- visnav run car


def _progress_at(run: _Proc, sim_s: float) -> Callable[[], bool]:
    pattern = re.compile(r"\] sim (\d+(?:\.\d+)?)/")

    def ready() -> bool:
        for line in reversed(run.err):
            found = pattern.search(line)
            if found:
                return float(found.group(1)) >= sim_s
        return False

    return ready


_PHASES = {
    # nodes being built (kernels loading): the folder and its log exist, no step yet
    "start-up": lambda run, out: run.wait_for((out / "run.log").exists, "the run's log file"),
    # the nodes are up; the first camera frames start the SLAM worker process
    "first-frames": lambda run, out: run.wait_for(
        lambda: any("started" in line for line in run.err), "the started line"
    ),
    # the simulation steps with the SLAM worker running
    "driving": lambda run, out: run.wait_for(_progress_at(run, 1.5), "sim time 1.5 s"),
    # the duration ran out: nodes stopping, SLAM map being saved, summary being written
    "wrap-up": lambda run, out: run.wait_for(_progress_at(run, 4.0), "the last progress line"),
}


@pytest.mark.slow
@pytest.mark.timeout(1500)
@pytest.mark.parametrize("phase", list(_PHASES))
def test_sigterm_on_run_car_stops_summarises_and_leaves_nothing(
    tmp_path: Path, domain: int, phase: str
) -> None:
    out = tmp_path / "run"
    run = _Proc(["run", "car", "--duration", "4", "--out", str(out)], tmp_path, domain)
    _PHASES[phase](run, out)
    if phase == "wrap-up":
        time.sleep(0.5)  # into the shutdown
    code, stdout, stderr = run.signal(signal.SIGTERM)  # the process only, as `kill PID`
    assert run.left_behind() == [], stderr
    summary = json.loads((out / "summary.json").read_text())
    for key in _CAR_KEYS:
        assert key in summary, key
    assert "scenario car" in stdout  # the summary is printed
    # stopped before the simulation stepped, the run recorded nothing: no bag, "bag": null
    assert (out / "bag").exists() == (summary["bag"] is not None), summary["bag"]
    bag = bag_info(out / "bag") if summary["bag"] else None  # closed: it reads
    clock = summary["topics"].get("/clock", {}).get("count")
    print(f"{phase}: exit {code}, {summary['status']} at sim {summary['sim_duration_s']} s")
    if summary["status"] == "completed":  # the signal came after the simulation's end
        assert phase == "wrap-up", stderr
        _assert_clean_exit(code, stderr, expected=0)
        assert summary["sim_duration_s"] == pytest.approx(4.0, abs=0.01)
        assert "end_reason" not in summary
        return
    _assert_clean_exit(code, stderr)
    assert summary["status"] == "interrupted"
    assert summary["end_reason"] == "SIGTERM"
    assert "\nstatus interrupted\n" in stdout
    assert "interrupted (SIGTERM)" in stderr
    assert 0 <= summary["sim_duration_s"] < 4.0
    if phase == "driving":
        assert summary["sim_duration_s"] >= 1.5
        assert clock is not None
        assert clock > 0
        assert summary["goals_total"] == 4  # the observer's figures up to then
        assert bag is not None
        assert bag.message_count > 0


@pytest.mark.slow
@pytest.mark.timeout(1500)
def test_sigterm_to_the_group_as_systemd_sends_it(tmp_path: Path, domain: int) -> None:
    # systemd (KillMode=control-group) signals every process of the service at once
    out = tmp_path / "run"
    run = _Proc(["run", "car", "--duration", "4", "--out", str(out)], tmp_path, domain)
    _PHASES["driving"](run, out)
    code, _, stderr = run.signal(signal.SIGTERM, group=True)
    assert run.left_behind() == [], stderr
    _assert_clean_exit(code, stderr)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    assert summary["end_reason"] == "SIGTERM"


@pytest.mark.slow
@pytest.mark.timeout(1500)
@pytest.mark.parametrize("seed", [1, 2])
def test_ctrl_c_at_a_random_sim_time(tmp_path: Path, domain: int, seed: int) -> None:
    # a terminal's Ctrl-C (SIGINT to the group) at a sim time drawn from the seed
    at_s = random.Random(seed).uniform(0.3, 3.6)
    out = tmp_path / "run"
    run = _Proc(["run", "car", "--duration", "4", "--out", str(out)], tmp_path, domain)
    run.wait_for(_progress_at(run, at_s), f"sim time {at_s:.2f} s")
    code, stdout, stderr = run.signal(signal.SIGINT, group=True)
    assert run.left_behind() == [], stderr
    _assert_clean_exit(code, stderr, expected=130)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted", f"at {at_s:.2f} s: {stderr}"
    assert summary["end_reason"] == "SIGINT (Ctrl-C)"
    assert at_s <= summary["sim_duration_s"] < 4.0
    for key in _CAR_KEYS:
        assert key in summary, key
    assert summary["topics"]["/clock"]["count"] > 0
    assert summary["goals_total"] == 4  # the observer's figures up to then
    assert "slam" in summary
    assert bag_info(out / "bag").message_count > 0
    assert "\nstatus interrupted\n" in stdout


# ---------------------------------------------------------------- launch, sweep


@pytest.mark.slow
@pytest.mark.timeout(1500)
def test_sigterm_on_launch_car(tmp_path: Path, domain: int) -> None:
    run = _Proc(["launch", "car", "duration:=60"], tmp_path, domain)
    run.wait_for(lambda: any("started" in line for line in run.err), "the started line")
    time.sleep(2.0)
    code, _, stderr = run.signal(signal.SIGTERM)
    assert run.left_behind() == [], stderr
    _assert_clean_exit(code, stderr)
    assert "launch ended: SIGTERM (exit code 143)" in stderr
    summaries = list((tmp_path / "runs").glob("*/summary.json"))
    assert len(summaries) == 1, stderr
    summary = json.loads(summaries[0].read_text())
    assert summary["status"] == "interrupted"
    assert summary["end_reason"] == "SIGTERM"


@pytest.mark.slow
@pytest.mark.timeout(1500)
def test_sigterm_on_a_sweep_stops_its_runs(tmp_path: Path, domain: int) -> None:
    sweep = tmp_path / "sweep"
    args = ["sweep", "car", "--seeds", "0-1", "--set", "duration=30", "--out", str(sweep)]
    run = _Proc(args, tmp_path, domain)
    logs = sweep / "runs"

    def running() -> bool:  # a run's worker steps its simulation: its recorder made the bag
        return any(logs.glob("*/*/bag"))

    run.wait_for(running, "a run that started recording")
    time.sleep(1.0)
    code, _, stderr = run.signal(signal.SIGTERM)
    assert run.left_behind() == [], stderr  # the run workers and their SLAM workers
    _assert_clean_exit(code, stderr)
    state = json.loads((sweep / "sweep.json").read_text())
    statuses = [r["status"] for r in state["runs"]]
    assert "interrupted" in statuses, statuses
    assert set(statuses) <= {"ok", "interrupted"}, statuses


# ---------------------------------------------------------------- bridge, foxglove, record


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_sigterm_on_bridge_ros1(tmp_path: Path, domain: int) -> None:
    args = ["bridge", "ros1", "--serve-master", str(_free_port())]
    run = _Proc(args, tmp_path, domain)
    run.wait_for(lambda: "bridging ROS 1 master" in run.text(), "the bridging line")
    code, _, stderr = run.signal(signal.SIGTERM)
    assert run.left_behind() == [], stderr
    _assert_clean_exit(code, stderr)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_sigterm_on_foxglove(tmp_path: Path, domain: int) -> None:
    run = _Proc(["foxglove", "--port", "0", "--wall-time"], tmp_path, domain)
    run.wait_for(lambda: "Foxglove WebSocket server at" in run.text(), "the server line")
    code, _, stderr = run.signal(signal.SIGTERM)
    assert run.left_behind() == [], stderr
    _assert_clean_exit(code, stderr)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_sigterm_on_bag_record_closes_the_bag(tmp_path: Path, domain: int) -> None:
    bag = tmp_path / "rec"
    talker = _Proc(
        ["topic", "pub", "/chatter", "std_msgs/msg/String", "data: hi", "-r", "20"],
        tmp_path,
        domain,
    )
    try:
        run = _Proc(["bag", "record", "/chatter", "-o", str(bag)], tmp_path, domain)
        run.wait_for(lambda: "Recording to" in run.text(), "the recording line")
        time.sleep(3.0)
        code, stdout, stderr = run.signal(signal.SIGTERM)
    finally:
        talker.kill()
    assert run.left_behind() == [], stderr
    # exit 0, as after Ctrl-C: `kill $pid` is how a script ends a recording (ros2 bag record
    # handles SIGTERM as SIGINT and exits 0 too); tests/bag/test_cli.py checks the contents
    _assert_clean_exit(code, stderr, expected=0)
    assert "Recorded" in stdout
    assert bag_info(bag).message_count > 0  # closed and indexed: it reads


# ---------------------------------------------------------------- Ctrl-C during start-up

_PYTHON_OWN = "init_import_site"  # CPython's report of an interrupt in its own start-up


_START_UP = [("run", d) for d in (0.1, 0.3, 0.6, 1.0, 1.5, 2.0, 3.0)] + [
    ("launch", d) for d in (1.0, 2.5)
]


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize(("verb", "delay_s"), _START_UP)
def test_ctrl_c_during_start_up_is_one_line(
    tmp_path: Path, domain: int, verb: str, delay_s: float
) -> None:
    out = tmp_path / "run"
    args = ["run", "car", "--duration", "2", "--out", str(out)]
    if verb == "launch":
        args = ["launch", "car", "duration:=2", f"out:={out}"]
    run = _Proc(args, tmp_path, domain)
    time.sleep(delay_s)
    folder_before = out.exists()
    code, _, stderr = run.signal(signal.SIGINT, group=True)
    assert run.left_behind() == [], stderr
    if code == -signal.SIGINT:  # before Python's handler: the default action, a silent end
        assert stderr == "", stderr
        return
    if _PYTHON_OWN in stderr:  # the interpreter was still importing `site`: not visnav's
        assert "visnav" not in stderr, stderr
        return
    assert code == 130, stderr
    assert "Traceback" not in stderr, stderr
    if not folder_before and not out.exists():  # the modules were loading: one line
        assert stderr.strip() == "interrupted during start-up", stderr
        return
    # the run had made its folder (a slow start): it is complete, with the summary
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted", stderr


@pytest.mark.slow
@pytest.mark.timeout(300)
@pytest.mark.parametrize("delay_s", [0.5, 1.5])
def test_sigterm_during_start_up(tmp_path: Path, domain: int, delay_s: float) -> None:
    out = tmp_path / "run"
    run = _Proc(["run", "car", "--duration", "2", "--out", str(out)], tmp_path, domain)
    time.sleep(delay_s)
    code, _, stderr = run.signal(signal.SIGTERM)
    assert "Traceback" not in stderr, stderr
    if code == -signal.SIGTERM:  # before visnav's handler: Python's default, a silent end
        assert stderr == "", stderr
    else:
        assert code == 143, stderr
        if not out.exists():
            assert stderr.strip() == "interrupted during start-up (SIGTERM)", stderr
    assert run.left_behind() == [], stderr


def test_sigterm_is_routed_to_the_sigint_handler_in_place() -> None:
    stop = TerminateAsInterrupt()
    before = signal.getsignal(signal.SIGTERM)
    with stop.installed():
        with pytest.raises(KeyboardInterrupt):  # Python's default SIGINT handler in place
            signal.raise_signal(signal.SIGTERM)
        assert stop.terminated
        assert stop.exit_code(130) == 143
        assert stop.exit_code(0) == 143
        assert stop.exit_code(1) == 1  # an error stays an error
        interrupt = RunInterrupt()
        with interrupt.installed():  # a verb's own handler: it takes SIGTERM itself
            signal.raise_signal(signal.SIGTERM)  # a request, no exception
            assert interrupt.requested
            assert interrupt.reason == "SIGTERM"
            assert interrupt.exit_code == 143
            with pytest.raises(KeyboardInterrupt):
                signal.raise_signal(signal.SIGINT)  # the second signal: now
    assert signal.getsignal(signal.SIGTERM) is before
    ctrl_c = RunInterrupt()
    with ctrl_c.installed():
        signal.raise_signal(signal.SIGINT)
    assert (ctrl_c.reason, ctrl_c.exit_code) == ("SIGINT (Ctrl-C)", 130)


@pytest.fixture
def terminal_sigint() -> Iterator[None]:
    """Python's own SIGINT handler, as in a terminal (a background job's pytest ignores it)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.mark.usefixtures("terminal_sigint")
def test_an_interrupt_while_the_verb_loads_is_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from visnav.cli import launch as launch_verb
    from visnav.cli import main as cli_main

    def loading(argv: object) -> None:
        raise KeyboardInterrupt  # as a Ctrl-C while the verb's modules import

    with monkeypatch.context() as patch:
        patch.setattr(cli_main, "_verb_parser", loading)
        assert cli_main.main(["run", "car"]) == 130
    assert capsys.readouterr().err == "interrupted during start-up\n"

    def numpy_loading(argv: object) -> None:
        try:  # numpy's C import turns the KeyboardInterrupt into an ImportError
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            msg = 'PyCapsule_Import could not import module "datetime"'
            raise ImportError(msg) from None

    with monkeypatch.context() as patch:
        patch.setattr(cli_main, "_verb_parser", numpy_loading)
        assert cli_main.main(["run", "car"]) == 130
    assert capsys.readouterr().err == "interrupted during start-up\n"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back

    def preparing(args: object) -> None:
        raise KeyboardInterrupt  # as a Ctrl-C while `visnav launch` reads its files

    monkeypatch.setattr(launch_verb, "_prepare", preparing)
    assert cli_main.main(["launch", "car"]) == 130
    assert capsys.readouterr().err == "interrupted during start-up\n"


def test_main_in_a_thread_leaves_the_signals_alone() -> None:
    from visnav.cli.main import main

    codes: list[int] = []
    before = signal.getsignal(signal.SIGTERM)
    worker = threading.Thread(target=lambda: codes.append(main(["bag", "info", "/no/such/bag"])))
    worker.start()
    worker.join(60)
    assert codes == [1]  # the error line, not a ValueError from signal.signal
    assert signal.getsignal(signal.SIGTERM) is before
