"""A visnav action offered to ROS 1 as an actionlib server through the bridge.

In process (visnav's master, a ROS 1 peer node playing actionlib's client), and against
real rospy ``actionlib.SimpleActionClient('move_base', MoveBaseAction)`` (slow; Debian's
python3-actionlib and python3-move-base-msgs).
"""

from __future__ import annotations

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
from typing import Any

import pytest

from visnav.bridge.actionlib import (
    ABORTED,
    ACTIVE,
    PREEMPTED,
    REJECTED,
    SUCCEEDED,
    ros1_status,
)
from visnav.bridge.actionlib_types import ActionlibTypes, actionlib_types
from visnav.bridge.bridge import BridgeOptions, Ros1Bridge
from visnav.bridge.errors import BridgeError, TcprosError
from visnav.bridge.master import Ros1Master
from visnav.bridge.master_api import MasterClient
from visnav.bridge.ros1_node import Ros1Node
from visnav.graph import Context, Node
from visnav.graph.action_server import ActionServer, ServerGoalHandle
from visnav.graph.action_types import CancelResponse, GoalResponse, GoalStatus
from visnav.msgs.construct import default_message
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time

MOVE_BASE = "move_base_msgs/action/MoveBase"
SYSTEM_PYTHON = "/usr/bin/python3"
VISNAV = [sys.executable, "-m", "visnav.cli.main"]
# Debian's python3-move-base-msgs: MoveBaseActionGoal._md5sum, ...
ROS1_MD5 = {
    "goal": "660d6895a1b9a16dce51fbdd9a64a56b",
    "feedback": "7d1870ff6e0decea702b943b5af0b42e",
    "result": "1eb06eeff08fa7ea874431638cb52332",
}


def _has_rospy_actionlib() -> bool:
    if not shutil.which(SYSTEM_PYTHON):
        return False
    probe = "import actionlib, move_base_msgs.msg, rospy"
    return (
        subprocess.run([SYSTEM_PYTHON, "-c", probe], capture_output=True, check=False).returncode
        == 0
    )


def test_types_and_status_codes() -> None:
    t = actionlib_types(MOVE_BASE)
    assert (t.goal.md5sum, t.feedback.md5sum, t.result.md5sum) == (
        ROS1_MD5["goal"],
        ROS1_MD5["feedback"],
        ROS1_MD5["result"],
    )
    assert t.goal.ros1_name == "move_base_msgs/MoveBaseActionGoal"
    assert t.status.ros1_name == "actionlib_msgs/GoalStatusArray"
    assert "MSG: move_base_msgs/MoveBaseGoal" in t.goal.definition
    assert ros1_status(GoalStatus.STATUS_EXECUTING, executed=True) == ACTIVE
    assert ros1_status(GoalStatus.STATUS_SUCCEEDED, executed=True) == SUCCEEDED
    assert ros1_status(GoalStatus.STATUS_CANCELED, executed=True) == PREEMPTED
    assert ros1_status(GoalStatus.STATUS_ABORTED, executed=True) == ABORTED
    with pytest.raises(TcprosError, match="MoveBaseActionGoal"):
        t.decode_goal(b"\x01\x02")


@pytest.mark.skipif(not _has_rospy_actionlib(), reason="python3-move-base-msgs missing")
def test_bytes_equal_genpys() -> None:
    t = actionlib_types(MOVE_BASE)
    status = t.goal_status(t.goal_id(ns_to_time(3_000_000_007), "g1"), SUCCEEDED, "done")
    ours = t.encode_result(t.header(ns_to_time(5_000_000_000), "map"), status, None)
    feedback = default_message("move_base_msgs/action/MoveBase_Feedback")
    feedback.base_position.pose.position.x = 2.5
    ours_fb = t.encode_feedback(t.header(ns_to_time(0)), status, feedback)
    script = (
        "import io, genpy, move_base_msgs.msg as m\n"
        "r = m.MoveBaseActionResult(); r.header.stamp = genpy.Time(5); r.header.frame_id = 'map'\n"
        "r.status.goal_id.stamp = genpy.Time(3, 7); r.status.goal_id.id = 'g1'\n"
        "r.status.status = 3; r.status.text = 'done'\n"
        "b = io.BytesIO(); r.serialize(b); print(b.getvalue().hex())\n"
        "f = m.MoveBaseActionFeedback(); f.status = r.status\n"
        "f.feedback.base_position.pose.position.x = 2.5\n"
        # ROS 2's Quaternion defaults to w = 1 (visnav's default message), genpy's to 0
        "f.feedback.base_position.pose.orientation.w = 1.0\n"
        "b = io.BytesIO(); f.serialize(b); print(b.getvalue().hex())\n"
        "g = m.MoveBaseActionGoal(); g.goal_id.id = 'x'\n"
        "g.goal.target_pose.header.frame_id = 'map'\n"
        "g.goal.target_pose.pose.position.y = -1.25\n"
        "b = io.BytesIO(); g.serialize(b); print(b.getvalue().hex())\n"
    )
    out = subprocess.run([SYSTEM_PYTHON, "-c", script], capture_output=True, text=True, check=True)
    result_hex, feedback_hex, goal_hex = out.stdout.split()
    assert ours == bytes.fromhex(result_hex)
    assert ours_fb == bytes.fromhex(feedback_hex)
    goal_id, goal = t.decode_goal(bytes.fromhex(goal_hex))
    assert goal_id.id == "x"
    assert goal.target_pose.header.frame_id == "map"
    assert goal.target_pose.pose.position.y == -1.25
    assert type(goal).__name__ == "move_base_msgs__action__MoveBase_Goal"


class _Graphs:
    def __init__(self) -> None:
        self.master = Ros1Master(0)
        self.master.start()
        self.ctx = Context(transport="local")
        self.ros1 = Ros1Node("visnav_bridge", master_uri=self.master.uri, host="127.0.0.1")
        self.ros1.start()
        self.peer = Ros1Node("ros1_client", master_uri=self.master.uri, host="127.0.0.1")
        self.peer.start()
        self.bridge = Ros1Bridge(
            Node("ros1_bridge", context=self.ctx), self.ros1, BridgeOptions(scan_period_s=0.05)
        )
        self.types: ActionlibTypes = actionlib_types(MOVE_BASE)
        self.got: dict[str, list[Any]] = {"status": [], "feedback": [], "result": []}
        self._seq = 0

    def connect_client(self) -> None:
        """The peer subscribes status/feedback/result and advertises goal/cancel."""
        t = self.types
        for role, rtype in (("status", t.status), ("feedback", t.feedback), ("result", t.result)):
            self.peer.subscribe(f"/move_base/{role}", rtype, self._collect(role, rtype))
        self.peer.advertise("/move_base/goal", t.goal)
        self.peer.advertise("/move_base/cancel", t.cancel)
        assert self.spin_until(
            lambda: (
                self.ros1.publisher_uris("/move_base/goal") != []
                and self.peer.subscriber_count("/move_base/cancel") > 0
                and len(self.got["status"]) > 0
            )
        )

    def _collect(self, role: str, rtype: Any) -> Callable[[bytearray], None]:
        def collect(raw: bytearray) -> None:
            self.got[role].append(self.types._from_ros1(bytes(raw), rtype))

        return collect

    def send_goal(self, goal_id: str, x: float) -> None:
        t = self.types
        cls = t.store.types[t.goal.ros2_name]
        goal = default_message("move_base_msgs/action/MoveBase_Goal")
        goal.target_pose.pose.position.x = x
        inner = t._inner(goal, "Goal")
        msg = cls(
            header=t.header(ns_to_time(0)), goal_id=t.goal_id(ns_to_time(0), goal_id), goal=inner
        )
        self._seq += 1
        self.peer.publish("/move_base/goal", t._to_ros1(msg, t.goal), seq=self._seq)

    def cancel(self, goal_id: str) -> None:
        t = self.types
        self.peer.publish(
            "/move_base/cancel", t._to_ros1(t.goal_id(ns_to_time(0), goal_id), t.cancel)
        )

    def results(self, goal_id: str) -> list[Any]:
        return [r for r in self.got["result"] if r.status.goal_id.id == goal_id]

    def spin_until(self, pred: Callable[[], bool], timeout_s: float = 10.0) -> bool:
        return self.ctx.spin_until(pred, timeout_s)

    def close(self) -> None:
        self.bridge.close()
        self.peer.close()
        self.ros1.close()
        self.ctx.shutdown()
        self.master.close()


@pytest.fixture
def graphs() -> Iterator[_Graphs]:
    g = _Graphs()
    yield g
    g.close()


def _server(ctx: Context, *, hold: threading.Event | None = None) -> tuple[Node, list[float]]:
    """A trivial MoveBase server: 3 feedbacks, then SUCCEEDED (or waits for a cancel)."""
    node = Node("move_base", context=ctx)
    targets: list[float] = []

    def execute(handle: ServerGoalHandle) -> Any:
        targets.append(handle.request.target_pose.pose.position.x)
        for i in range(3):
            feedback = default_message("move_base_msgs/action/MoveBase_Feedback")
            feedback.base_position.pose.position.x = float(i)
            handle.publish_feedback(feedback)
            time.sleep(0.02)
        if hold is not None:
            while not handle.is_cancel_requested:
                if hold.wait(0.02):
                    break
            if handle.is_cancel_requested:
                handle.canceled()
                return default_message("move_base_msgs/action/MoveBase_Result")
        handle.succeed()
        return default_message("move_base_msgs/action/MoveBase_Result")

    def on_goal(goal: Any) -> GoalResponse:
        x = goal.target_pose.pose.position.x
        return GoalResponse.REJECT if x < 0 else GoalResponse.ACCEPT

    ActionServer(
        node,
        MOVE_BASE,
        "/move_base",
        execute,
        goal_callback=on_goal,
        cancel_callback=lambda _h: CancelResponse.ACCEPT,
    )
    return node, targets


def test_goal_feedback_result_succeeded(graphs: _Graphs) -> None:
    _node, targets = _server(graphs.ctx)
    assert graphs.spin_until(lambda: graphs.bridge.actionlib.actions() == ["/move_base"])
    types = MasterClient(graphs.master.uri, "/t").topic_types()
    assert types["/move_base/goal"] == "move_base_msgs/MoveBaseActionGoal"
    assert types["/move_base/status"] == "actionlib_msgs/GoalStatusArray"
    assert "/move_base/_action/status" not in types  # ROS 2's action topics stay in visnav
    graphs.connect_client()
    graphs.send_goal("goal-1", 1.5)
    assert graphs.spin_until(lambda: graphs.results("goal-1") != [])
    (result,) = graphs.results("goal-1")
    assert result.status.status == SUCCEEDED
    assert targets == [1.5]
    feedback = [f for f in graphs.got["feedback"] if f.status.goal_id.id == "goal-1"]
    assert [f.feedback.base_position.pose.position.x for f in feedback] == [0.0, 1.0, 2.0]
    assert all(f.status.status == ACTIVE for f in feedback)
    # status lists the goal as SUCCEEDED after the result
    assert graphs.spin_until(
        lambda: any(
            s.goal_id.id == "goal-1" and s.status == SUCCEEDED
            for s in graphs.got["status"][-1].status_list
        )
    )


def test_a_visnav_status_topic_of_the_same_name_stays_out(graphs: _Graphs) -> None:
    """The navigator publishes its own /move_base/status: ROS 1 must see actionlib's only."""
    nav = Node("navigator", context=graphs.ctx)
    array_cls = get_message_class("actionlib_msgs/msg/GoalStatusArray")
    own = default_message("actionlib_msgs/msg/GoalStatusArray")
    entry = default_message("actionlib_msgs/msg/GoalStatus")
    entry.goal_id.id = "visnav-own"
    own.status_list = [entry]
    pub = nav.create_publisher(array_cls, "/move_base/status", 10)
    nav.create_subscription(array_cls, "/move_base/status", lambda _m: None, 10)
    nav.create_timer(0.05, lambda: pub.publish(own))
    assert graphs.spin_until(lambda: "/move_base/status" in graphs.bridge.out_topics())
    t = graphs.types
    graphs.peer.subscribe("/move_base/status", t.status, graphs._collect("status", t.status))

    def seen_own() -> bool:
        return any(
            s.goal_id.id == "visnav-own" for m in graphs.got["status"] for s in m.status_list
        )

    assert graphs.spin_until(seen_own)  # bridged as a plain topic until the action comes
    _server(graphs.ctx)
    assert graphs.spin_until(lambda: graphs.bridge.actionlib.actions() == ["/move_base"])
    graphs.connect_client()
    graphs.send_goal("goal-2", 1.0)
    assert graphs.spin_until(lambda: graphs.results("goal-2") != [])

    def seen_goal() -> bool:
        return any(s.goal_id.id == "goal-2" for m in graphs.got["status"] for s in m.status_list)

    # actionlib's status comes at 5 Hz over the peer's new connection: wait for one with the goal
    assert graphs.spin_until(seen_goal)
    graphs.ctx.spin(duration_s=0.5)
    assert "/move_base/status" not in graphs.bridge.out_topics()
    assert "/move_base/status" not in graphs.bridge.in_topics()
    first = next(
        i
        for i, m in enumerate(graphs.got["status"])
        if any(s.goal_id.id == "goal-2" for s in m.status_list)
    )
    ids = {s.goal_id.id for m in graphs.got["status"][first:] for s in m.status_list}
    assert ids == {"goal-2"}
    pubs, _, _ = MasterClient(graphs.master.uri, "/t").system_state()
    assert dict(pubs)["/move_base/status"] == ["/visnav_bridge"]


def test_rejected_and_cancelled_goals(graphs: _Graphs) -> None:
    hold = threading.Event()
    _server(graphs.ctx, hold=hold)
    assert graphs.spin_until(lambda: graphs.bridge.actionlib.actions() == ["/move_base"])
    graphs.connect_client()
    graphs.send_goal("bad", -1.0)
    assert graphs.spin_until(lambda: graphs.results("bad") != [])
    assert graphs.results("bad")[0].status.status == REJECTED
    graphs.send_goal("long", 2.0)
    assert graphs.spin_until(
        lambda: any(f.status.goal_id.id == "long" for f in graphs.got["feedback"])
    )
    graphs.cancel("long")
    assert graphs.spin_until(lambda: graphs.results("long") != [])
    assert graphs.results("long")[0].status.status == PREEMPTED
    server = graphs.bridge.actionlib.server("/move_base")
    assert server.goals_received == 2
    assert server.bad_messages == 0


def test_broken_goal_bytes_cost_nothing_but_the_message(graphs: _Graphs) -> None:
    _server(graphs.ctx)
    assert graphs.spin_until(lambda: graphs.bridge.actionlib.actions() == ["/move_base"])
    graphs.connect_client()
    graphs.peer.publish("/move_base/goal", b"\x00\x00\x00\x00\xff\xff")
    server = graphs.bridge.actionlib.server("/move_base")
    assert graphs.spin_until(lambda: server.bad_messages == 1)
    graphs.send_goal("after", 0.5)
    assert graphs.spin_until(lambda: graphs.results("after") != [])
    assert graphs.results("after")[0].status.status == SUCCEEDED


def test_server_gone_withdraws_the_topics(graphs: _Graphs) -> None:
    node, _ = _server(graphs.ctx)
    assert graphs.spin_until(lambda: graphs.bridge.actionlib.actions() == ["/move_base"])
    node.destroy_node()
    assert graphs.spin_until(lambda: graphs.bridge.actionlib.actions() == [])
    pubs, subs, _ = MasterClient(graphs.master.uri, "/t").system_state()
    assert not any(t.startswith("/move_base/") for t, _ in pubs + subs)


# ---------------------------------------------------------------------------- real rospy
_SERVER = """
import sys, time
from visnav.graph import Context, Node
from visnav.graph.action_server import ActionServer
from visnav.graph.action_types import CancelResponse
from visnav.msgs.construct import default_message
from visnav.msgs.serde import get_message_class

def execute(handle):
    for i in range(5):
        fb = default_message("move_base_msgs/action/MoveBase_Feedback")
        fb.base_position.header.frame_id = "map"
        fb.base_position.pose.position.x = handle.request.target_pose.pose.position.x * (i + 1) / 5
        handle.publish_feedback(fb)
        time.sleep(0.1)
    handle.succeed()
    return default_message("move_base_msgs/action/MoveBase_Result")

with Context() as ctx:
    node = Node("move_base", context=ctx)
    ActionServer(node, "move_base_msgs/action/MoveBase", "move_base", execute,
                 cancel_callback=lambda h: CancelResponse.ACCEPT)
    ctx.flush_tokens()
    print("ready", flush=True)
    ctx.spin(duration_s=float(sys.argv[1]))
"""

_CLIENT = """
import actionlib, rospy
from actionlib_msgs.msg import GoalStatus
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
rospy.init_node("simple_client")
client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
assert client.wait_for_server(rospy.Duration(30)), "no move_base server"
goal = MoveBaseGoal()
goal.target_pose.header.frame_id = "map"
goal.target_pose.pose.position.x = 2.0
goal.target_pose.pose.orientation.w = 1.0
feedback = []
client.send_goal(goal, feedback_cb=lambda fb: feedback.append(fb.base_position.pose.position.x))
assert client.wait_for_result(rospy.Duration(30)), "no result"
print("state", client.get_state(), GoalStatus.SUCCEEDED)
print("feedback", len(feedback), feedback[-1] if feedback else None)
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _Processes:
    """Processes of one test against one ROS 1 master, killed (by group) at the end."""

    def __init__(self, tmp: Path, domain: int, *, ros_ip: bool = True) -> None:
        self.tmp = tmp
        self.port = _free_port()
        self.uri = f"http://127.0.0.1:{self.port}/"
        self.env = {
            **os.environ,
            "ROS_MASTER_URI": self.uri,
            "ROS_HOME": str(tmp / "ros_home"),
            "ROS_LOG_DIR": str(tmp / "ros_log"),
            "VISNAV_DOMAIN": str(domain),
            "PYTHONUNBUFFERED": "1",
        }
        self.env.pop("ROS_IP", None)
        self.env.pop("ROS_HOSTNAME", None)
        if ros_ip:
            self.env["ROS_IP"] = "127.0.0.1"
        self.procs: list[subprocess.Popen[str]] = []

    def start(self, argv: list[str], name: str) -> None:
        log = (self.tmp / f"{name}.log").open("w")
        self.procs.append(
            subprocess.Popen(
                argv, env=self.env, stdout=log, stderr=subprocess.STDOUT, text=True,
                start_new_session=True, cwd=self.tmp,
            )
        )  # fmt: skip

    def logs(self) -> str:
        return "".join(f"\n--- {p.name}\n{p.read_text()[-3000:]}" for p in self.tmp.glob("*.log"))

    def wait_master(self) -> None:
        end = time.monotonic() + 30
        while True:
            try:
                MasterClient(self.uri, "/t", timeout_s=1.0).ping()
                return
            except BridgeError:
                if time.monotonic() > end:
                    pytest.fail(f"no ROS 1 master{self.logs()}")
                time.sleep(0.2)

    def client(self, script: str, timeout_s: float) -> dict[str, str]:
        """Run a system-python rospy script; its ``key value`` output lines."""
        out = subprocess.run(
            [SYSTEM_PYTHON, "-c", script], env=self.env, capture_output=True, text=True,
            timeout=timeout_s, check=False,
        )  # fmt: skip
        assert out.returncode == 0, out.stdout + out.stderr + self.logs()
        return dict(line.split(" ", 1) for line in out.stdout.splitlines() if " " in line)

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


_NEEDS_ROSPY = pytest.mark.skipif(
    shutil.which("roscore") is None or not _has_rospy_actionlib(),
    reason="ROS 1 missing: apt install ros-core python3-actionlib python3-move-base-msgs",
)


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(300)
@_NEEDS_ROSPY
def test_rospy_simple_action_client_through_the_bridge(tmp_path: Path, domain: int) -> None:
    procs = _Processes(tmp_path, domain)
    try:
        procs.start(["roscore", "-p", str(procs.port)], "roscore")
        procs.wait_master()
        procs.start([sys.executable, "-c", _SERVER, "120"], "server")
        procs.start([*VISNAV, "bridge", "ros1"], "bridge")
        lines = procs.client(_CLIENT, 90)
        assert lines["state"] == "3 3"  # SUCCEEDED
        count, last = lines["feedback"].split()
        assert int(count) >= 1
        assert float(last) > 0.0
    finally:
        procs.close()


_CAR_CLIENT = """
import math, actionlib, rospy
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import Odometry
rospy.init_node("car_client")
odom = rospy.wait_for_message("/odom", Odometry, timeout=120)
p = odom.pose.pose
yaw = 2 * math.atan2(p.orientation.z, p.orientation.w)
client = actionlib.SimpleActionClient("move_base", MoveBaseAction)
assert client.wait_for_server(rospy.Duration(60)), "no move_base server"
goal = MoveBaseGoal()
goal.target_pose.header.frame_id = odom.header.frame_id
goal.target_pose.pose.position.x = p.position.x + 1.5 * math.cos(yaw)
goal.target_pose.pose.position.y = p.position.y + 1.5 * math.sin(yaw)
goal.target_pose.pose.orientation = p.orientation
feedback = []
client.send_goal(goal, feedback_cb=lambda f: feedback.append(f))
assert client.wait_for_result(rospy.Duration(150)), "no result"
end = rospy.wait_for_message("/odom", Odometry, timeout=30).pose.pose.position
print("state", client.get_state())
print("feedback", len(feedback))
print("moved", math.hypot(end.x - p.position.x, end.y - p.position.y))
"""


@pytest.mark.slow
@pytest.mark.timeout(400)
@_NEEDS_ROSPY
def test_rospy_simple_action_client_drives_the_car(tmp_path: Path, domain: int) -> None:
    """issue 31's acceptance: rospy's SimpleActionClient('move_base') gets the car to a goal.

    The car scenario without its own mission, the bridge serving the master, no ROS_IP (so
    the bridge listens on loopback, the default).
    """
    procs = _Processes(tmp_path, domain, ros_ip=False)
    try:
        car = ("mission:=false", "slam:=false", "ideal_sensors:=true", "realtime:=true")
        procs.start([*VISNAV, "launch", "car", *car, "duration:=400"], "car")
        procs.start([*VISNAV, "bridge", "ros1", "--serve-master", str(procs.port)], "bridge")
        procs.wait_master()
        lines = procs.client(_CAR_CLIENT, 300)
        assert lines["state"] == "3", procs.logs()  # SUCCEEDED
        assert int(lines["feedback"]) >= 3
        assert float(lines["moved"]) > 1.0
    finally:
        procs.close()
