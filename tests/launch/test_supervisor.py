"""Running launch files: shared and own processes on one graph, respawn, Ctrl-C, no orphans."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from visnav.graph import Context, Node
from visnav.launch import Launcher, load_launch
from visnav.msgs import String
from visnav.node_registry import UnknownNodeError


def write(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return path


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie still answers kill(0); it is dead for our purpose
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


class Running:
    """A Launcher on a background thread (as the CLI runs it on the main thread)."""

    def __init__(self, launcher: Launcher) -> None:
        self.launcher = launcher
        self.stop = threading.Event()
        self.code: int | None = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            self.code = self.launcher.run(self.stop)
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            self.error = exc

    def finish(self, timeout: float = 10.0) -> int | None:
        self.stop.set()
        self.thread.join(timeout)
        assert not self.thread.is_alive()
        if self.error is not None:
            raise self.error
        return self.code


@pytest.fixture
def running() -> Iterator[list[Running]]:
    started: list[Running] = []
    yield started
    for r in started:
        r.stop.set()
        r.thread.join(10)


GRAPH = """
launch:
  - arg: {name: robot, default: r1}
  - group:
      namespace: $(arg robot)
      children:
        - node: {exec: launch_test_nodes:Talker, name: front, params: {text: shared}}
        - group:
            namespace: cam
            children:
              - node:
                  exec: launch_test_nodes:Talker
                  name: back
                  process: own
                  params: {text: own, rate: 50}
        - node: {exec: launch_test_nodes:Listener, name: listener, remap: {chatter: cam/chatter}}
"""


def test_shared_and_own_nodes_talk_over_the_graph(
    domain: int, test_nodes_path: Path, tmp_path: Path, running: list[Running]
) -> None:
    del test_nodes_path
    description = load_launch(write(tmp_path / "graph.yaml", GRAPH))
    launcher = Launcher(description, domain=domain, sigterm_timeout=2.0)
    running.append(Running(launcher))
    got: dict[str, list[str]] = {"/r1/chatter": [], "/r1/cam/chatter": []}
    with Context(domain) as ctx:
        node = Node("probe", context=ctx)
        for topic, out in got.items():
            node.create_subscription(String, topic, lambda m, out=out: out.append(m.data), 10)
        assert ctx.spin_until(lambda: all(got.values()), 8.0), got
    own_pid = launcher.pids["/r1/cam/back"]
    assert own_pid != os.getpid()
    assert got["/r1/chatter"][0] == f"shared {os.getpid()}"  # the launch process itself
    assert got["/r1/cam/chatter"][0] == f"own {own_pid}"  # the child process
    # a shared node in the launch process hears the own node across processes
    listener = next(n for n in launcher.shared_nodes if n.get_name() == "listener")
    deadline = time.monotonic() + 5.0
    while not listener.received and time.monotonic() < deadline:
        time.sleep(0.02)
    assert listener.received[0] == f"own {own_pid}"
    assert running[0].finish() == 0
    assert not alive(own_pid)
    kinds = [(e.name, e.kind) for e in launcher.events]
    assert kinds == [("/r1/cam/back", "started"), ("/r1/cam/back", "stopped")]


def test_respawn_reports_exit_codes_and_restarts_n_times(
    test_nodes_path: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    del test_nodes_path
    f = write(
        tmp_path / "crash.yaml",
        """
        launch:
          - node:
              exec: launch_test_nodes:Crasher
              respawn: true
              respawn_delay: 0.05
              respawn_max_retries: 2
              params: {code: 7}
        """,
    )
    launcher = Launcher(load_launch(f))
    caplog.set_level("INFO", logger="visnav.launch")
    code = launcher.run()  # returns when the last restart has exited
    assert code == 1
    exits = [e for e in launcher.events if e.kind == "exited"]
    starts = [e for e in launcher.events if e.kind == "started"]
    # each restart waits respawn_delay after the exit it follows (no wall-clock upper bound:
    # the loaded machine decides how long a Python process takes to start and crash)
    assert len(starts) == 3
    assert all(s.time - e.time >= 0.05 for e, s in zip(exits, starts[1:], strict=False))
    assert [e.returncode for e in exits] == [7, 7, 7]
    assert [e.restarts for e in exits] == [0, 1, 2]
    assert len({e.pid for e in exits}) == 3
    assert [e.kind for e in launcher.events][-1] == "gave_up"
    assert sum("exited with code 7" in r.getMessage() for r in caplog.records) == 3
    assert any(
        "restarting /crasher in 0.05 s (restart 2 of 2)" in r.getMessage() for r in caplog.records
    )
    assert any("respawn_max_retries (2) reached" in r.getMessage() for r in caplog.records)
    assert not any(alive(e.pid) for e in exits)


def test_required_node_stops_the_launch(test_nodes_path: Path, tmp_path: Path) -> None:
    del test_nodes_path
    f = write(
        tmp_path / "req.yaml",
        """
        launch:
          - node: {exec: launch_test_nodes:Crasher, process: own, required: true, params: {code: 4}}
          - node: {exec: launch_test_nodes:Talker, process: own, params: {rate: 5}}
        """,
    )
    launcher = Launcher(load_launch(f), sigterm_timeout=2.0)
    assert launcher.run() == 1
    talker = [e for e in launcher.events if e.name == "/talker"]
    assert [e.kind for e in talker] == ["started", "stopped"]
    assert not alive(talker[0].pid)


def test_a_crashing_shared_node_with_on_error_shutdown_stops_the_children(
    test_nodes_path: Path, tmp_path: Path
) -> None:
    del test_nodes_path
    f = write(
        tmp_path / "bomb.yaml",
        """
        launch:
          - node: {exec: launch_test_nodes:Talker, process: own, params: {rate: 5}}
          - node: {exec: launch_test_nodes:Bomb, on_error: shutdown, params: {delay: 0.5}}
        """,
    )
    launcher = Launcher(load_launch(f), sigterm_timeout=2.0)
    assert launcher.run() == 1
    assert launcher.exit_code == 1
    (talker,) = {e.pid for e in launcher.events}
    assert [e.kind for e in launcher.events] == ["started", "stopped"]
    assert not alive(talker)


def test_spawn_model_is_no_node_a_launch_file_can_start(tmp_path: Path) -> None:
    f = write(
        tmp_path / "p.yaml",
        """
        launch:
          - node: {exec: image_proc, process: own}
          - node: {exec: spawn_model}
        """,
    )
    with pytest.raises(UnknownNodeError, match=r"p.yaml:3: unknown node 'spawn_model'"):
        load_launch(f)


def _launch_cli(domain: int, tmp: Path, *args: str) -> subprocess.Popen[str]:
    # TMPDIR: the spec files of a launcher killed with SIGKILL stay in the test's tmp_path
    env = {**os.environ, "VISNAV_DOMAIN": str(domain), "TMPDIR": str(tmp)}
    return subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", "launch", *args],
        env=env,
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
    )


def _started_pids(proc: subprocess.Popen[str], count: int, timeout: float = 10.0) -> list[int]:
    assert proc.stderr is not None
    pids: list[int] = []
    deadline = time.monotonic() + timeout
    while len(pids) < count and time.monotonic() < deadline:
        line = proc.stderr.readline()
        if not line:
            break
        m = re.search(r"started /\S+ \[.*\] \(pid (\d+)\)", line)
        if m:
            pids.append(int(m.group(1)))
    assert len(pids) == count
    return pids


TWO_OWN = """
launch:
  - node: {exec: launch_test_nodes:Talker, name: a, process: own}
  - node: {exec: launch_test_nodes:Talker, name: b, process: own}
  - node: {exec: launch_test_nodes:Talker, name: c}
"""


def test_ctrl_c_stops_every_child(domain: int, test_nodes_path: Path, tmp_path: Path) -> None:
    del test_nodes_path
    f = write(tmp_path / "two.yaml", TWO_OWN)
    proc = _launch_cli(domain, tmp_path, str(f))
    try:
        pids = _started_pids(proc, 2)
        with Context(domain) as ctx:  # wait until both children publish: fully up
            node = Node("probe", context=ctx)
            seen: set[str] = set()
            node.create_subscription(String, "/chatter", lambda m: seen.add(m.data.split()[1]), 10)
            assert ctx.spin_until(lambda: {str(p) for p in pids} <= seen, 10.0)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 130
        assert not [p for p in pids if alive(p)]
        assert proc.stderr is not None
        assert "Traceback" not in proc.stderr.read()
    finally:  # a failure before the signal must not leave the launch and its children
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


@pytest.mark.ci
@pytest.mark.slow  # ~1.5-3 s: three interpreters start
def test_children_die_with_a_killed_launcher(
    domain: int, test_nodes_path: Path, tmp_path: Path
) -> None:
    del test_nodes_path
    f = write(tmp_path / "two.yaml", TWO_OWN)
    proc = _launch_cli(domain, tmp_path, str(f))
    pids = _started_pids(proc, 2)
    time.sleep(0.5)
    proc.kill()  # SIGKILL: no chance to stop the children itself
    proc.wait(timeout=5)
    deadline = time.monotonic() + 8.0
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [p for p in pids if alive(p)]
