"""A slow ROS 1 service does not stall the bridge (real roscore and rospy).

A rospy process serves ``/ros1/slow`` (sleeps 3 s) and ``/ros1/fast`` and subscribes to
``/visnav_tick``, which this test publishes from visnav at 20 Hz through ``visnav bridge
ros1``. While a visnav client's call of the slow service is in the ROS 1 handler, the
fast service answers and the ticks keep reaching rospy: the bridge makes the ROS 1 call
on a worker thread, not in its executor. Skipped when ROS 1 is not installed.
"""

from __future__ import annotations

import itertools
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from visnav.bridge.errors import BridgeError
from visnav.bridge.master_api import MasterClient
from visnav.graph import Context, Node
from visnav.msgs import String
from visnav.msgs.srv import get_service_type

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        shutil.which("roscore") is None or not Path("/usr/bin/python3").exists(),
        reason="ROS 1 tools missing: apt install ros-core python3-rospy python3-std-srvs",
    ),
]

SYSTEM_PYTHON = "/usr/bin/python3"
VISNAV = [sys.executable, "-m", "visnav.cli.main"]
SLOW_S = 3.0

_ROSPY = f"""
import time, rospy, std_msgs.msg as m, std_srvs.srv as s
rospy.init_node("rospy_slow")
def on_tick(msg):
    print("tick %.3f" % time.time(), flush=True)
def slow(req):
    print("slow-start %.3f" % time.time(), flush=True)
    time.sleep({SLOW_S})
    print("slow-end %.3f" % time.time(), flush=True)
    return s.TriggerResponse(success=True, message="slow done")
def fast(req):
    print("fast %.3f" % time.time(), flush=True)
    return s.TriggerResponse(success=True, message="fast done")
rospy.Subscriber("/visnav_tick", m.String, on_tick)
rospy.Service("/ros1/slow", s.Trigger, slow)
rospy.Service("/ros1/fast", s.Trigger, fast)
print("ready", flush=True)
rospy.spin()
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _Ros1:
    def __init__(self, tmp: Path, domain: int) -> None:
        self.port = _free_port()
        self.uri = f"http://127.0.0.1:{self.port}/"
        self.env = {
            **os.environ,
            "ROS_MASTER_URI": self.uri,
            "ROS_IP": "127.0.0.1",
            "ROS_HOME": str(tmp / "ros_home"),
            "ROS_LOG_DIR": str(tmp / "ros_log"),
            "VISNAV_DOMAIN": str(domain),
            "PYTHONUNBUFFERED": "1",
        }
        self.tmp = tmp
        self.procs: list[subprocess.Popen[str]] = []

    def start(self, argv: list[str], name: str) -> Path:
        log = self.tmp / f"{name}.log"
        env = {**self.env, "PYTHONPATH": ""} if argv[0] == SYSTEM_PYTHON else self.env
        with log.open("w") as out:
            self.procs.append(
                subprocess.Popen(
                    argv,
                    env=env,
                    stdout=out,
                    stderr=subprocess.STDOUT,
                    text=True,
                    start_new_session=True,
                    cwd=self.tmp,
                )
            )
        return log

    def logs(self) -> str:
        return "".join(
            f"\n--- {p.name} ---\n{p.read_text()[-3000:]}" for p in self.tmp.glob("*.log")
        )

    def master_up(self) -> bool:
        try:
            MasterClient(self.uri, "/test", timeout_s=1.0).ping()
        except BridgeError:
            return False
        return True

    def wait(self, pred: Callable[[], bool], timeout_s: float, what: str) -> None:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if pred():
                return
            time.sleep(0.1)
        pytest.fail(f"timed out after {timeout_s} s waiting for {what}{self.logs()}")

    def close(self) -> None:
        for proc in reversed(self.procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGINT)
        for proc in reversed(self.procs):
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=10)


@pytest.fixture
def ros1(tmp_path: Path, domain: int) -> Iterator[_Ros1]:
    env = _Ros1(tmp_path, domain)
    env.start(["roscore", "-p", str(env.port)], "roscore")
    env.wait(env.master_up, 30, "roscore")
    yield env
    env.close()


def _events(log: Path, kind: str) -> list[float]:
    return [
        float(line.split()[1])
        for line in log.read_text().splitlines()
        if line.startswith(kind + " ")
    ]


@pytest.mark.timeout(300)
def test_slow_ros1_service_does_not_block_the_bridge(ros1: _Ros1) -> None:
    rospy_log = ros1.start([SYSTEM_PYTHON, "-c", _ROSPY], "rospy")
    ros1.wait(lambda: "ready" in rospy_log.read_text(), 30, "the rospy services")
    ros1.start([*VISNAV, "bridge", "ros1", "--services", "/ros1/*"], "bridge")
    trigger = get_service_type("std_srvs/srv/Trigger")
    with Context() as ctx:
        node = Node("slow_service_test", context=ctx)
        pub = node.create_publisher(String, "/visnav_tick", 10)
        node.create_timer(0.05, lambda: pub.publish(String(data="tick")))
        slow = node.create_client(trigger, "/ros1/slow")
        fast = node.create_client(trigger, "/ros1/fast")
        spinner = threading.Thread(target=ctx.spin, daemon=True)
        spinner.start()
        try:
            assert slow.wait_for_service(60.0), ros1.logs()
            assert fast.wait_for_service(60.0), ros1.logs()
            ros1.wait(lambda: len(_events(rospy_log, "tick")) >= 5, 60, "ticks through the bridge")

            future = slow.call_async(trigger.Request(), timeout_sec=30.0)
            ros1.wait(lambda: _events(rospy_log, "slow-start") != [], 20, "the slow call")
            start = time.monotonic()
            reply = fast.call(trigger.Request(), timeout_sec=SLOW_S - 0.5)
            assert reply.message == "fast done"
            assert time.monotonic() - start < SLOW_S - 0.5
            assert not future.done(), "the fast call should answer while the slow one runs"

            assert future.wait(30.0), ros1.logs()
            assert future.result().message == "slow done"  # type: ignore[union-attr]
        finally:
            ctx.shutdown()
            spinner.join(5.0)
    (began,) = _events(rospy_log, "slow-start")
    (ended,) = _events(rospy_log, "slow-end")
    (fast_at,) = _events(rospy_log, "fast")
    assert began < fast_at < ended
    during = [t for t in _events(rospy_log, "tick") if began + 0.5 < t < ended - 0.5]
    # 20 Hz for 2 s: ~40 ticks; a blocked executor forwards none until the slow call returns
    assert len(during) >= 15, (len(during), ros1.logs())
    gaps = [b - a for a, b in itertools.pairwise(during)]
    assert max(gaps) < 1.0, gaps
