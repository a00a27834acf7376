"""Services through the bridge against real ROS 1 (Debian's roscore, rosservice, rospy).

Each test runs its own ``roscore -p PORT``, a visnav service server process
(tests/graph/scripts/service_server.py) and ``visnav bridge ros1`` in a private
VISNAV_DOMAIN. Skipped when the ROS 1 tools are missing (``.ci/run`` installs them).
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from visnav.bridge.errors import BridgeError
from visnav.bridge.master_api import MasterClient

pytestmark = [
    pytest.mark.slow,
    pytest.mark.ci,
    pytest.mark.skipif(
        shutil.which("roscore") is None or shutil.which("rosservice") is None,
        reason="ROS 1 tools missing: apt install ros-core python3-rosservice python3-std-srvs",
    ),
]

SYSTEM_PYTHON = "/usr/bin/python3"
VISNAV = [sys.executable, "-m", "visnav.cli.main"]
SERVER = Path(__file__).parents[1] / "graph" / "scripts" / "service_server.py"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _Env:
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

    def start(self, argv: list[str], name: str) -> subprocess.Popen[str]:
        log = (self.tmp / f"{name}.log").open("w")
        proc = subprocess.Popen(
            argv,
            env=self.env,
            stdout=log,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,
            cwd=self.tmp,
        )
        self.procs.append(proc)
        return proc

    def logs(self) -> str:
        return "".join(
            f"\n--- {p.name} ---\n{p.read_text()[-3000:]}" for p in self.tmp.glob("*.log")
        )

    def run(self, argv: list[str], timeout_s: float = 30.0) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            argv, env=self.env, capture_output=True, text=True, timeout=timeout_s, check=False
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
            time.sleep(0.2)
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
def ros1(tmp_path: Path, domain: int) -> Iterator[_Env]:
    env = _Env(tmp_path, domain)
    env.start(["roscore", "-p", str(env.port)], "roscore")
    env.wait(env.master_up, 30, "roscore")
    yield env
    env.close()


def _services(env: _Env) -> set[str]:
    return set(env.run(["rosservice", "list"]).stdout.split())


_ROSPY_CLIENT = """
import rospy, std_srvs.srv as s
rospy.init_node("rospy_client")
rospy.wait_for_service("/srv/set_bool", timeout=20)
proxy = rospy.ServiceProxy("/srv/set_bool", s.SetBool, persistent=True)
print("set_bool", proxy(True).message, proxy(False).message)
trigger = rospy.ServiceProxy("/srv/trigger", s.Trigger)
print("trigger", trigger().message)
try:
    rospy.ServiceProxy("/srv/boom", s.Trigger)()
except rospy.ServiceException as exc:
    print("boom", exc)
import nav_msgs.srv as n
m = rospy.ServiceProxy("/srv/get_map", n.GetMap)().map
print("map", m.info.width, m.info.height, m.header.frame_id, sum(m.data[:200]))
"""

_ROSPY_SERVER = """
import rospy, std_srvs.srv as s
rospy.init_node("rospy_server")
def handle(req):
    return s.TriggerResponse(success=True, message="hello from rospy")
def fail(req):
    raise RuntimeError("rospy says no")
rospy.Service("/ros1/trigger", s.Trigger, handle)
rospy.Service("/ros1/fail", s.Trigger, fail)
print("ready", flush=True)
rospy.spin()
"""


@pytest.mark.timeout(300)
def test_rosservice_and_rospy_reach_visnav_services(ros1: _Env) -> None:
    ros1.start([sys.executable, str(SERVER), "120"], "server")
    ros1.start([*VISNAV, "bridge", "ros1"], "bridge")
    ros1.wait(lambda: "/srv/set_bool" in _services(ros1), 60, "/srv/set_bool in rosservice list")
    names = _services(ros1)
    assert {"/srv/trigger", "/srv/get_map", "/srv/set_map", "/srv/boom"} <= names
    assert not any("parameters" in n for n in names)  # rcl_interfaces stays in visnav
    assert ros1.run(["rosservice", "type", "/srv/set_bool"]).stdout.strip() == "std_srvs/SetBool"
    info = ros1.run(["rosservice", "info", "/srv/set_bool"]).stdout
    assert "Node: /visnav_bridge" in info
    assert "Args: data" in info

    out = ros1.run(["rosservice", "call", "/srv/set_bool", "data: true"])
    assert out.returncode == 0, out.stderr
    assert "success: True" in out.stdout
    assert 'message: "on"' in out.stdout
    out = ros1.run(["rosservice", "call", "/srv/boom"])
    assert out.returncode != 0
    assert "the arm is not homed" in out.stderr + out.stdout

    client = ros1.run([SYSTEM_PYTHON, "-c", _ROSPY_CLIENT], timeout_s=60)
    assert client.returncode == 0, client.stderr
    lines = dict(line.split(" ", 1) for line in client.stdout.splitlines() if " " in line)
    assert lines["set_bool"] == "on off"
    assert lines["trigger"].startswith("call ")
    assert "ValueError: the arm is not homed" in lines["boom"]
    assert lines["map"] == f"1000 1000 map {sum(i % 100 for i in range(200))}"


@pytest.mark.timeout(300)
def test_visnav_client_reaches_rospy_service(ros1: _Env) -> None:
    ros1.start([SYSTEM_PYTHON, "-c", _ROSPY_SERVER], "rospy_server")
    ros1.wait(lambda: "/ros1/trigger" in _services(ros1), 30, "the rospy service")
    ros1.start([*VISNAV, "bridge", "ros1"], "bridge")
    time.sleep(1.0)
    out = ros1.run([*VISNAV, "service", "call", "/ros1/trigger", "std_srvs/srv/Trigger", "{}"], 60)
    assert out.returncode == 0, out.stdout + out.stderr + ros1.logs()
    assert "hello from rospy" in out.stdout
    out = ros1.run([*VISNAV, "service", "call", "/ros1/fail", "std_srvs/srv/Trigger", "{}"], 60)
    assert out.returncode != 0
    assert "rospy says no" in out.stdout + out.stderr
    # the bridge's proxy is not handed back to ROS 1 as a second provider
    _, _, srvs = MasterClient(ros1.uri, "/t").system_state()
    providers = dict(srvs)
    assert providers["/ros1/trigger"] == ["/rospy_server"]


@pytest.mark.timeout(400)
def test_rosservice_reset_world_resets_the_sim(ros1: _Env) -> None:
    """``rosservice call /gazebo/reset_world`` through the bridge puts the car back."""
    ros1.start([*VISNAV, "sim", "--world", "office", "--robot", "car", "--realtime"], "sim")
    ros1.start([*VISNAV, "bridge", "ros1"], "bridge")
    ros1.wait(lambda: "/odom" in ros1.run(["rostopic", "list"]).stdout, 120, "the sim's /odom")
    time.sleep(3.0)
    if "/gazebo/reset_world" not in _services(ros1):
        pytest.skip("this visnav sim does not serve /gazebo/reset_world yet")
    drive = ros1.start(
        ["rostopic", "pub", "-r", "20", "/cmd_vel", "geometry_msgs/Twist", "linear: {x: 0.8}"],
        "drive",
    )
    time.sleep(4.0)
    os.killpg(drive.pid, signal.SIGINT)
    drive.wait(timeout=10)
    moved = _odom_x(ros1)
    assert moved > 0.3, moved
    out = ros1.run(["rosservice", "call", "/gazebo/reset_world"])
    assert out.returncode == 0, out.stderr
    time.sleep(1.0)
    assert abs(_odom_x(ros1)) < 0.1


def _odom_x(env: _Env) -> float:
    out = env.run(["rostopic", "echo", "-n", "1", "/odom/pose/pose/position/x"], 60).stdout
    return float(out.split()[0])
