"""Acceptance against real ROS 1 (Debian's roscore, rostopic, rosnode, rosbag, rospy).

Each test runs its own ``roscore -p PORT`` and a private VISNAV_DOMAIN. Skipped when the ROS 1
tools are not installed (``.ci/run`` installs them with apt).
"""

from __future__ import annotations

import os
import re
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
        shutil.which("roscore") is None or shutil.which("rostopic") is None,
        reason="ROS 1 tools missing: apt install ros-core python3-rostopic python3-rosnode",
    ),
]

SYSTEM_PYTHON = "/usr/bin/python3"
VISNAV = [sys.executable, "-m", "visnav.cli.main"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Ros1Env:
    """A private roscore plus helpers to start processes against it and visnav."""

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

    def log(self, name: str) -> str:
        return (self.tmp / f"{name}.log").read_text()

    def run(self, argv: list[str], timeout_s: float = 30.0) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            argv,
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout_s,
            check=False,
            cwd=self.tmp,
        )

    def master_up(self) -> bool:
        try:
            MasterClient(self.uri, "/test", timeout_s=1.0).ping()
        except BridgeError:
            return False
        return True

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


def wait_for(
    pred: Callable[[], bool],
    timeout_s: float,
    what: str,
    *,
    logs: Callable[[], dict[str, str]] | None = None,
) -> None:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.2)
    tails = "".join(f"\n--- {n} ---\n{t}" for n, t in (logs() if logs else {}).items())
    pytest.fail(f"timed out after {timeout_s} s waiting for {what}{tails}")


@pytest.fixture
def ros1(tmp_path: Path, domain: int) -> Iterator[Ros1Env]:
    env = Ros1Env(tmp_path, domain)
    yield env
    env.close()


@pytest.fixture
def roscore(ros1: Ros1Env) -> Ros1Env:
    ros1.start(["roscore", "-p", str(ros1.port)], "roscore")
    wait_for(ros1.master_up, 30, "roscore")
    return ros1


def _topics(env: Ros1Env) -> set[str]:
    return set(env.run(["rostopic", "list"]).stdout.split())


def _hz_window(text: str) -> int:
    """The largest sample window ``rostopic hz`` has printed (0 before its first rate).

    Its window grows by the frames of one wall second per print, so a given number (50) may
    never be printed on a slow machine: compare numbers, not text.
    """
    return max((int(w) for w in re.findall(r"window: (\d+)", text)), default=0)


def _last_rate(text: str) -> float:
    rates = re.findall(r"average rate: ([0-9.]+)", text)
    assert rates, text[-500:]
    return float(rates[-1])


SIM = [*VISNAV, "sim", "--world", "office", "--robot", "car", "--realtime"]
CAMERA_RATE = 30

SIM_TOPICS = {
    "/camera/image_raw",
    "/camera/camera_info",
    "/depth_camera/points",
    "/odom",
    "/tf",
    "/tf_static",
    "/clock",
}


@pytest.mark.timeout(600)
def test_sim_seen_by_real_ros1_tools(roscore: Ros1Env) -> None:
    env = roscore
    env.start([*SIM, "--arg", f"camera_rate:={CAMERA_RATE}"], "sim")
    env.start([*VISNAV, "bridge", "ros1"], "bridge")
    wait_for(lambda: _topics(env) >= SIM_TOPICS, 90, f"{SIM_TOPICS} in rostopic list")
    assert "/visnav_bridge" in env.run(["rosnode", "list"]).stdout.split()
    assert env.run(["rosparam", "get", "/use_sim_time"]).stdout.strip() == "true"

    # camera_info: ROS 1's upper-case K equals the simulator's k
    ros_k = env.run(["rostopic", "echo", "-n1", "/camera/camera_info/K"], 30).stdout
    visnav_k = env.run(
        [*VISNAV, "topic", "echo", "/camera/camera_info", "--once", "--field", "k"], 60
    ).stdout
    ros_values = [float(v) for v in re.findall(r"-?[0-9.]+(?:e-?\d+)?", ros_k.split("---")[0])]
    visnav_values = [float(v) for v in re.findall(r"-?[0-9.]+(?:e-?\d+)?", visnav_k)]
    assert len(ros_values) == 9
    assert ros_values == pytest.approx(visnav_values[:9])

    # rate: /use_sim_time is set, so rostopic hz measures in ROS time = the simulator's
    # clock (bridged /clock), where the camera runs at its configured rate whatever the
    # machine's real-time factor; a frame the bridge lost would lower it.
    hz = env.start(["rostopic", "hz", "/camera/image_raw"], "rostopic_hz")
    wait_for(
        lambda: _hz_window(env.log("rostopic_hz")) >= 50 or hz.poll() is not None,
        120,
        "hz",
        logs=lambda: {n: env.log(n)[-1500:] for n in ("rostopic_hz", "bridge", "sim")},
    )
    time.sleep(2.0)
    os.killpg(hz.pid, signal.SIGINT)
    hz.wait(timeout=10)
    ros_rate = _last_rate(env.log("rostopic_hz"))
    assert ros_rate == pytest.approx(CAMERA_RATE, rel=0.05), env.log("rostopic_hz")[-300:]

    # rosbag record 5 s -> rosbag info lists the topics
    rec = env.start(
        ["rosbag", "record", "-O", "sim.bag", "--duration=5", *sorted(SIM_TOPICS)], "record"
    )
    rec.wait(timeout=60)
    info = env.run(["rosbag", "info", "sim.bag"], 60)
    assert info.returncode == 0, info.stderr
    for topic in SIM_TOPICS:
        assert re.search(rf"^\s*(topics:)?\s*{re.escape(topic)}\s+\d+ msgs?", info.stdout, re.M), (
            topic,
            info.stdout,
        )
    assert "sensor_msgs/CameraInfo" in info.stdout


_DRIVE = """
import rospy
from geometry_msgs.msg import Twist
rospy.init_node("driver")
pub = rospy.Publisher("/cmd_vel", Twist, queue_size=1)
rate = rospy.Rate(10)
while not rospy.is_shutdown():
    t = Twist(); t.linear.x = 1.0
    pub.publish(t)
    rate.sleep()
"""


def _odom_xy(env: Ros1Env) -> tuple[float, float]:
    out = env.run(["rostopic", "echo", "-n1", "/odom/pose/pose/position"], 30).stdout
    x = re.search(r"x: (\S+)", out)
    y = re.search(r"y: (\S+)", out)
    assert x is not None, out
    assert y is not None, out
    return float(x.group(1)), float(y.group(1))


@pytest.mark.timeout(300)
def test_rospy_cmd_vel_drives_the_car(roscore: Ros1Env) -> None:
    env = roscore
    env.start(SIM, "sim")
    env.start([*VISNAV, "bridge", "ros1"], "bridge")
    wait_for(lambda: "/odom" in _topics(env), 90, "/odom in ROS 1")
    x0, y0 = _odom_xy(env)
    env.start([SYSTEM_PYTHON, "-c", _DRIVE], "driver")
    moved: list[float] = []

    def far() -> bool:
        x, y = _odom_xy(env)
        moved.append(((x - x0) ** 2 + (y - y0) ** 2) ** 0.5)
        return moved[-1] > 0.3

    wait_for(far, 90, "the car to move 0.3 m")
    assert "ROS 1 -> visnav: /cmd_vel" in env.log("bridge")


_WRITE_BAG = """
import sys, rosbag, rospy
from std_msgs.msg import String
from rosgraph_msgs.msg import Clock
with rosbag.Bag(sys.argv[1], "w") as bag:
    for i in range(40):
        t = rospy.Time(100, i * 50_000_000)
        bag.write("/chatter", String(data="from ros1 %d" % i), t)
"""


def test_rosbag_play_reaches_visnav_topic_echo(roscore: Ros1Env) -> None:
    env = roscore
    bag = env.tmp / "talk.bag"
    made = env.run([SYSTEM_PYTHON, "-c", _WRITE_BAG, str(bag)])
    assert made.returncode == 0, made.stderr
    env.start([*VISNAV, "bridge", "ros1"], "bridge")
    echo = env.start(
        [*VISNAV, "topic", "echo", "/chatter", "std_msgs/msg/String", "--once", "--timeout", "60"],
        "echo",
    )
    wait_for(lambda: "ROS 1 -> visnav: /chatter" in env.log("bridge"), 60, "bridge to subscribe")
    play = env.start(["rosbag", "play", "--clock", "-l", str(bag)], "play")
    echo.wait(timeout=60)
    os.killpg(play.pid, signal.SIGINT)
    assert echo.returncode == 0, env.log("echo")
    assert "from ros1" in env.log("echo")


_TALKER = """
from visnav.graph import Context, Node
from visnav.msgs import String
with Context() as ctx:
    node = Node("talker", context=ctx)
    pub = node.create_publisher(String, "/chatter", 10)
    node.create_timer(0.1, lambda: pub.publish(String(data="hello from visnav")))
    ctx.spin(duration_s=120)
"""


def test_served_master_rosnode_and_kill(ros1: Ros1Env) -> None:
    env = ros1
    env.start([sys.executable, "-c", _TALKER], "talker")
    bridge = env.start([*VISNAV, "bridge", "ros1", "--serve-master", str(env.port)], "bridge")
    wait_for(lambda: "/chatter" in _topics(env), 60, "/chatter via the served master")
    echo = env.run(["rostopic", "echo", "-n1", "/chatter"], 30)
    assert "hello from visnav" in echo.stdout
    assert env.run(["rosparam", "set", "/answer", "42"]).returncode == 0
    assert env.run(["rosparam", "get", "/answer"]).stdout.strip() == "42"
    info = env.run(["rosnode", "info", "/visnav_bridge"]).stdout
    assert "/chatter [std_msgs/String]" in info
    assert "Pid:" in info
    assert "xmlrpc reply" in env.run(["rosnode", "ping", "-c", "1", "/visnav_bridge"]).stdout
    env.run(["rosnode", "kill", "/visnav_bridge"])
    assert bridge.wait(timeout=20) == 0


def test_no_master_one_line_error(ros1: Ros1Env) -> None:
    out = ros1.run([*VISNAV, "bridge", "ros1"], 60)
    assert out.returncode == 1
    lines = [line for line in out.stderr.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, out.stderr
    assert ros1.uri in lines[0]
    assert "roscore" in lines[0]
    assert "--serve-master" in lines[0]


def test_md5_mismatch_with_rospy_refused_bridge_keeps_running(roscore: Ros1Env) -> None:
    env = roscore
    bridge = env.start([*VISNAV, "bridge", "ros1"], "bridge")
    echo = env.start(
        [*VISNAV, "topic", "echo", "/chatter", "std_msgs/msg/String", "--timeout", "60"], "echo"
    )
    wait_for(lambda: "ROS 1 -> visnav: /chatter" in env.log("bridge"), 60, "bridge to subscribe")
    wrong = env.start(["rostopic", "pub", "-r", "5", "/chatter", "std_msgs/Int32", "7"], "wrong")
    string_md5 = "992ce8a1687cec8c8bd883ec73ca41d1"
    int32_md5 = "da5909fbe378aeaf85e547e830cc1bb7"
    wait_for(
        lambda: string_md5 in env.log("bridge") and int32_md5 in env.log("bridge"),
        60,
        "the refusal naming both md5sums",
    )
    os.killpg(wrong.pid, signal.SIGINT)
    env.start(["rostopic", "pub", "-r", "5", "/chatter", "std_msgs/String", "right"], "right")
    wait_for(lambda: "data: right" in env.log("echo"), 60, "the right type to get through")
    assert bridge.poll() is None
    os.killpg(echo.pid, signal.SIGINT)
