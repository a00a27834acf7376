"""The simulator's ``/gazebo/*`` services (gazebo_ros_api_plugin's names and gazebo_msgs
types): called from a client in the same process, from another process and from the CLI."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.description.robot import RobotDescription, load_robot
from visnav.graph import Context, Node
from visnav.msgs import Odometry, TFMessage, Twist, Vector3
from visnav.msgs.construct import message_from_dict
from visnav.msgs.serde import deserialize, get_message_class, serialize, typestore
from visnav.msgs.srv import get_service_type
from visnav.sim.gazebo_services import GAZEBO_SERVICE_NAMES
from visnav.sim.simulator import RobotSpawn, Simulator

TB3 = Path(__file__).resolve().parent.parent / "data" / "turtlebot3" / "turtlebot3_description"
SCRIPTS = Path(__file__).resolve().parent / "scripts"
Empty = get_service_type("std_srvs/srv/Empty")
GetModelState = get_service_type("gazebo_msgs/srv/GetModelState")
SetModelState = get_service_type("gazebo_msgs/srv/SetModelState")
SpawnModel = get_service_type("gazebo_msgs/srv/SpawnModel")
DeleteModel = get_service_type("gazebo_msgs/srv/DeleteModel")


@pytest.fixture(scope="module")
def burger() -> RobotDescription:
    return load_robot(
        TB3 / "urdf" / "turtlebot3_burger.urdf.xacro", packages={"turtlebot3_description": TB3}
    )


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as context:
        yield context


def make_sim(
    ctx: Context, burger: RobotDescription, *spawns: tuple[str, float, float, float]
) -> Simulator:
    robots = [
        RobotSpawn(source=burger, name=name, spawn=(x, y, 0.0, yaw), namespace=f"/{name}")
        for name, x, y, yaw in (spawns or (("tb_a", 0.5, 0.0, 0.0),))
    ]
    return Simulator("empty", robots, context=ctx)


def call(sim: Simulator, client: Any, request: Any, steps: int = 1) -> Any:
    """Call in lock-step: the simulator's steps spin the context until the reply is in."""
    future = client.call_async(request)
    for _ in range(200):
        if future.done():
            break
        sim.step(steps)
    assert future.done()
    return future.result()


def set_request(**state: Any) -> Any:
    return message_from_dict(SetModelState.request_type_name, {"model_state": state})


def yaw_of(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def test_service_types_are_gazebo_msgs_and_round_trip() -> None:
    for stype in (GetModelState, SetModelState, SpawnModel, DeleteModel):
        for cls in (stype.Request, stype.Response):
            msg = message_from_dict(cls.__msgtype__, {})
            assert serialize(deserialize(serialize(msg), cls.__msgtype__)) == serialize(msg)
    fields = typestore().fielddefs
    assert [f for f, _ in fields["gazebo_msgs/srv/GetModelState_Response"][1]] == [
        "header", "pose", "twist", "success", "status_message",
    ]  # fmt: skip
    assert [f for f, _ in fields["gazebo_msgs/srv/SpawnModel_Request"][1]] == [
        "model_name", "model_xml", "robot_namespace", "initial_pose", "reference_frame",
    ]  # fmt: skip
    assert get_service_type("gazebo_msgs/SetModelState") is SetModelState  # ROS 1 spelling


def test_every_service_is_served_by_the_sim_node(ctx: Context, burger: RobotDescription) -> None:
    with make_sim(ctx, burger) as sim:
        served = {s.srv_name: s.srv_type.name for s in sim.node.services}
        assert {k: served.get(k) for k in GAZEBO_SERVICE_NAMES} == GAZEBO_SERVICE_NAMES
    # closed: the names are free again for another simulator in the same context
    with make_sim(ctx, burger) as sim:
        assert "/gazebo/reset_world" in {s.srv_name for s in sim.node.services}


def test_get_model_state_in_the_world_and_relative_to_an_entity(
    ctx: Context, burger: RobotDescription
) -> None:
    client = Node("client", context=ctx).create_client(GetModelState, "/gazebo/get_model_state")
    with make_sim(ctx, burger, ("tb_a", 0.5, 0.0, 0.0), ("tb_b", 1.5, 1.0, math.pi / 2)) as sim:
        sim.step(10)
        reply = call(sim, client, GetModelState.Request("tb_b", ""))
        assert reply.success, reply.status_message
        assert (reply.pose.position.x, reply.pose.position.y) == pytest.approx((1.5, 1.0), abs=2e-3)
        assert yaw_of(reply.pose.orientation) == pytest.approx(math.pi / 2, abs=1e-2)
        assert reply.header.stamp.nanosec > 0  # the sim time of the state
        # tb_b seen from tb_a (at 0.5, 0 facing +x): 1 m ahead, 1 m to the left, turned 90 deg
        rel = call(sim, client, GetModelState.Request("tb_b", "tb_a"))
        assert rel.success
        assert rel.header.frame_id == "tb_a"
        assert (rel.pose.position.x, rel.pose.position.y) == pytest.approx((1.0, 1.0), abs=5e-3)
        assert yaw_of(rel.pose.orientation) == pytest.approx(math.pi / 2, abs=1e-2)
        # a link by its scoped name: the left wheel's axle is 8 cm beside base_footprint
        link = call(sim, client, GetModelState.Request("tb_a", "tb_a::wheel_left_link"))
        p = link.pose.position
        assert link.success
        assert math.hypot(p.x, p.y, p.z) > 0.08
        ground = call(sim, client, GetModelState.Request("ground_plane", "world"))
        assert ground.success
        assert ground.pose.position.x == 0.0
        missing = call(sim, client, GetModelState.Request("tb_z", ""))
        assert not missing.success
        assert "model [tb_z] does not exist" in missing.status_message
        assert "tb_a" in missing.status_message
        bad_ref = call(sim, client, GetModelState.Request("tb_a", "wheel_left_link"))
        assert not bad_ref.success
        assert "scope the body" in bad_ref.status_message


def test_set_model_state_moves_the_robot_and_world_odometry_and_tf_follow(
    ctx: Context, burger: RobotDescription
) -> None:
    listener = Node("listener", context=ctx)
    odoms: list[Any] = []
    tfs: list[Any] = []
    listener.create_subscription(Odometry, "/tb_a/odom", odoms.append, 1000)
    listener.create_subscription(TFMessage, "/tf", tfs.append, 1000)
    client = listener.create_client(SetModelState, "/gazebo/set_model_state")
    with make_sim(ctx, burger) as sim:
        sim.run(0.2)
        request = set_request(
            model_name="tb_a",
            pose={
                "position": {"x": 2.0, "y": -1.0},
                "orientation": {"z": 0.7071068, "w": 0.7071068},
            },
        )
        reply = call(sim, client, request)
        assert reply.success, reply.status_message
        body = sim.model.body("tb_a/base_footprint").id
        assert sim.data.xpos[body][:2] == pytest.approx([2.0, -1.0], abs=1e-3)
        odoms.clear()
        tfs.clear()
        sim.run(0.2)
        # gazebo_ros_diff_drive with odometrySource world publishes the model's world pose
        odom = odoms[-1].pose.pose
        assert (odom.position.x, odom.position.y) == pytest.approx((2.0, -1.0), abs=0.01)
        assert yaw_of(odom.orientation) == pytest.approx(math.pi / 2, abs=0.02)
        base = [
            t.transform
            for m in tfs
            for t in m.transforms
            if t.child_frame_id == "base_footprint" and t.header.frame_id == "odom"
        ]
        assert base
        assert base[-1].translation.x == pytest.approx(2.0, abs=0.01)
        # relative to another entity, with a twist (world frame)
        reply = call(
            sim,
            client,
            set_request(
                model_name="tb_a",
                reference_frame="ground_plane",
                pose={"position": {"x": -1.0}},
                twist={"linear": {"x": 0.3}},
            ),
        )
        assert reply.success
        assert sim.data.xpos[body][0] == pytest.approx(-1.0, abs=0.01)


@pytest.mark.parametrize(
    ("state", "expected"),
    [
        ({"model_name": "nobody"}, "model [nobody] does not exist"),
        ({"model_name": "ground_plane"}, "is static"),
        ({"model_name": "tb_a", "reference_frame": "nowhere"}, "[nowhere] does not exist"),
        ({"model_name": "tb_a", "pose": {"position": {"x": math.nan}}}, "not finite"),
        ({"model_name": "tb_a", "pose": {"orientation": {"w": math.inf}}}, "not finite"),
        ({"model_name": "tb_a", "twist": {"angular": {"z": -math.inf}}}, "not finite"),
        ({"model_name": "tb_a", "pose": {"position": {"y": 1e7}}}, "beyond what"),
        ({"model_name": "tb_a", "twist": {"linear": {"z": -5e3}}}, "beyond what"),
    ],
)
def test_set_model_state_refuses_with_a_status_message(
    ctx: Context, burger: RobotDescription, state: dict[str, Any], expected: str
) -> None:
    client = Node("client", context=ctx).create_client(SetModelState, "/gazebo/set_model_state")
    with make_sim(ctx, burger) as sim:
        before = np.array(sim.data.qpos)
        reply = call(sim, client, set_request(**state))
        assert not reply.success
        assert expected in reply.status_message
        assert reply.status_message.startswith("SetModelState:")
        sim.step(1)
        assert np.allclose(sim.data.qpos[:3], before[:3], atol=1e-3)


def test_reset_world_puts_robots_back_and_keeps_time_running(
    ctx: Context, burger: RobotDescription
) -> None:
    driver = Node("driver", context=ctx)
    cmd = driver.create_publisher(Twist, "/tb_a/cmd_vel", 1)
    reset = driver.create_client(Empty, "/gazebo/reset_world")
    with make_sim(ctx, burger) as sim:
        body = sim.model.body("tb_a/base_footprint").id
        start = np.array(sim.data.xpos[body])
        cmd.publish(Twist(linear=Vector3(0.2, 0.0, 0.0), angular=Vector3(0.0, 0.0, 0.5)))
        sim.run(1.0)
        assert np.linalg.norm(sim.data.xpos[body] - start) > 0.1
        before_ns = sim.now_ns
        call(sim, reset, Empty.Request())
        assert sim.gazebo_services.resets == 1
        assert sim.now_ns > before_ns  # time is not reset
        assert sim.data.xpos[body] == pytest.approx(start, abs=2e-3)
        assert np.abs(sim.data.qvel).max() < 0.05
        # the diff drive forgot its command (gazebo_ros_diff_drive's Reset): it stays put
        sim.run(0.5)
        assert sim.data.xpos[body] == pytest.approx(start, abs=5e-3)


def test_encoder_odometry_restarts_at_the_origin_from_the_current_wheel_angles() -> None:
    from visnav.sim.vehicles.diff_drive import EncoderOdometry

    enc = EncoderOdometry(0.16, 0.033)
    enc.update(0.0, 0.0, 0.0)
    enc.update(2.0, 2.0, 0.1)
    assert enc.x == pytest.approx(0.066)
    enc.restart()  # what reset_world does through DiffDriveController.reset()
    assert (enc.x, enc.y, enc.theta, enc.v) == (0.0, 0.0, 0.0, 0.0)
    enc.update(5.0, 5.0, 0.1)  # the wheels' angles now are the new zero
    assert enc.x == 0.0
    enc.update(6.0, 6.0, 0.1)
    assert enc.x == pytest.approx(0.033)


PLANAR_BOX = """<?xml version="1.0"?>
<robot name="mover">
  <link name="base_footprint"><inertial><mass value="5"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.4 0.3 0.2"/></geometry></collision>
  </link>
  <gazebo reference="base_footprint"><mu1>0</mu1><mu2>0</mu2></gazebo>
  <gazebo><plugin name="planar" filename="libgazebo_ros_planar_move.so"/></gazebo>
</robot>"""


def test_reset_world_stops_the_planar_move_plugin(ctx: Context) -> None:
    driver = Node("driver", context=ctx)
    cmd = driver.create_publisher(Twist, "/cmd_vel", 1)
    reset = driver.create_client(Empty, "/gazebo/reset_world")
    spawn = RobotSpawn(source=PLANAR_BOX, spawn=(1.0, 1.0, 0.0, 0.0))
    with Simulator("empty", [spawn], context=ctx) as sim:
        body = sim.model.body("mover/base_footprint").id
        start = np.array(sim.data.xpos[body])
        cmd.publish(Twist(linear=Vector3(0.5, 0.0, 0.0), angular=Vector3(0.0, 0.0, 0.0)))
        sim.run(0.5)
        assert sim.data.xpos[body][0] > start[0] + 0.1
        call(sim, reset, Empty.Request())
        sim.run(0.5)  # gazebo_ros_planar_move's Reset(): the command is zero
        assert sim.data.xpos[body][:2] == pytest.approx(start[:2], abs=2e-3)


def test_reset_simulation_rewinds_sim_time_to_zero_and_sensors_restart(
    ctx: Context, burger: RobotDescription
) -> None:
    client = Node("client", context=ctx).create_client(Empty, "/gazebo/reset_simulation")
    setter = Node("setter", context=ctx).create_client(SetModelState, "/gazebo/set_model_state")
    listener = Node("listener", context=ctx)
    clocks: list[int] = []
    odom: list[Odometry] = []
    listener.create_subscription(
        get_message_class("rosgraph_msgs/msg/Clock"),
        "/clock",
        lambda m: clocks.append(m.clock.sec * 10**9 + m.clock.nanosec),
        1000,
    )
    listener.create_subscription(Odometry, "/tb_a/odom", odom.append, 1000)
    with make_sim(ctx, burger) as sim:
        sim.run(1.0)
        call(sim, setter, set_request(model_name="tb_a", pose={"position": {"x": 3.0}}))
        body = sim.model.body("tb_a/base_footprint").id
        before = sim.elapsed_ns
        call(sim, client, Empty.Request())
        assert sim.data.xpos[body][0] == pytest.approx(0.5, abs=2e-3)
        assert sim.now_ns < 20_000_000  # back at 0 (plus the steps since the call)
        assert sim.elapsed_ns >= before  # run() durations and pacing never go back
        clocks.clear()
        odom.clear()
        sim.run(0.5)
        assert clocks[0] < 20_000_000  # /clock restarts from 0
        assert clocks == sorted(clocks)
        stamps = [o.header.stamp.sec * 10**9 + o.header.stamp.nanosec for o in odom]
        assert stamps  # the diff drive's schedule restarted with the clock
        assert max(stamps) < 600_000_000


def test_pause_stops_sim_time_and_clock_until_unpaused(
    ctx: Context, burger: RobotDescription
) -> None:
    from visnav.msgs.types import Clock

    node = Node("client", context=ctx)
    clocks: list[Any] = []
    node.create_subscription(Clock, "/clock", clocks.append, 10_000)
    pause = node.create_client(Empty, "/gazebo/pause_physics")
    unpause = node.create_client(Empty, "/gazebo/unpause_physics")
    with make_sim(ctx, burger) as sim:
        sim.run(0.1)
        call(sim, pause, Empty.Request())
        assert sim.paused
        paused_at = sim.now_ns
        clocks.clear()
        wall = time.monotonic()
        # run() keeps serving callbacks while paused; an unpause from another thread ends it
        threading.Timer(0.3, lambda: unpause.call(Empty.Request(), timeout_sec=5.0)).start()
        seen_while_paused: list[int] = []

        def until() -> bool:
            if sim.paused:
                seen_while_paused.append(sim.now_ns)
            return sim.now_ns >= paused_at + 100_000_000

        sim.run(5.0, until=until)
        assert time.monotonic() - wall >= 0.25
        assert not sim.paused
        assert set(seen_while_paused) == {paused_at}
        stamps = [c.clock.sec * 10**9 + c.clock.nanosec for c in clocks]
        assert stamps
        assert min(stamps) >= paused_at
        assert len(stamps) == len(set(stamps))


def test_sim_node_timer_does_not_step_while_paused(tmp_path: Path) -> None:
    from visnav.sim.sim_node import SimulatorNode

    with Context(transport="local") as ctx:
        node = SimulatorNode(
            "gazebo",  # as a roslaunch file's gazebo_ros node becomes it
            context=ctx,
            parameter_overrides={
                "world": "empty",
                "robot": str(TB3 / "urdf" / "turtlebot3_burger.urdf.xacro"),
                "packages": [f"turtlebot3_description={TB3}"],
                "realtime": False,
            },
        )
        try:
            names = {srv.srv_name for srv in node.services}
            assert set(GAZEBO_SERVICE_NAMES) <= names  # absolute: not /gazebo/gazebo/...
            assert "/gazebo/get_parameters" in names
            node.sim.pause()
            ctx.spin_once(0.05)
            ctx.spin_once(0.05)
            assert node.sim.now_ns == 0
            node.sim.unpause()
            deadline = time.monotonic() + 5.0
            while node.sim.now_ns == 0 and time.monotonic() < deadline:
                ctx.spin_once(0.05)
            assert node.sim.now_ns > 0
        finally:
            node.destroy_node()


# spawn_*_model and delete_model: tests/sim/test_gazebo_services_spawn.py


_text = st.text(max_size=40)
_float = st.floats(allow_nan=True, allow_infinity=True, width=64)
_vec = st.fixed_dictionaries({"x": _float, "y": _float, "z": _float})
_quat = st.fixed_dictionaries({"x": _float, "y": _float, "z": _float, "w": _float})
_names = st.one_of(
    _text, st.sampled_from(["tb_a", "ground_plane", "tb_a::base_footprint", "", "world"])
)


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    which=st.sampled_from(["get", "set", "spawn", "delete"]),
    name=_names,
    ref=_names,
    position=_vec,
    orientation=_quat,
    linear=_vec,
    xml=_text,
)
def test_fuzz_requests_never_kill_the_services(
    fuzz_sim: tuple[Simulator, dict[str, Any]],
    which: str,
    name: str,
    ref: str,
    position: dict[str, float],
    orientation: dict[str, float],
    linear: dict[str, float],
    xml: str,
) -> None:
    sim, clients = fuzz_sim
    sim.gazebo_services.reset_world()  # every example starts from the spawn state
    pose = {"position": position, "orientation": orientation}
    if which == "get":
        request: Any = GetModelState.Request(name, ref)
    elif which == "set":
        request = set_request(
            model_name=name, reference_frame=ref, pose=pose, twist={"linear": linear}
        )
    elif which == "spawn":
        request = message_from_dict(
            SpawnModel.request_type_name,
            {"model_name": name, "model_xml": xml, "reference_frame": ref, "initial_pose": pose},
        )
    else:  # deleting the robot works (test_gazebo_services_spawn.py); fuzz the others
        request = DeleteModel.Request(name if name != "tb_a" else "tb_a_")
    reply = call(sim, clients[which], request)
    assert isinstance(reply.success, bool)
    if not reply.success:
        assert reply.status_message  # a clear error reply, never an exception
    sim.step(25)  # 50 ms of physics from whatever state was accepted
    # the robot stays finite and the services keep answering
    assert np.all(np.isfinite(sim.data.qpos))
    ok = call(sim, clients["get"], GetModelState.Request("tb_a", ""))
    assert ok.success


@pytest.fixture(scope="module")
def fuzz_sim(burger: RobotDescription) -> Iterator[tuple[Simulator, dict[str, Any]]]:
    with Context(transport="local") as ctx, make_sim(ctx, burger) as sim:
        node = Node("fuzzer", context=ctx)
        clients = {
            "get": node.create_client(GetModelState, "/gazebo/get_model_state"),
            "set": node.create_client(SetModelState, "/gazebo/set_model_state"),
            "spawn": node.create_client(SpawnModel, "/gazebo/spawn_urdf_model"),
            "delete": node.create_client(DeleteModel, "/gazebo/delete_model"),
        }
        yield sim, clients


# ---------------------------------------------------------------------- other processes


@pytest.fixture
def sim_process(start_script: Callable[..., subprocess.Popen[str]]) -> subprocess.Popen[str]:
    return start_script(SCRIPTS / "gazebo_sim.py", "120")


def _wait(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


@pytest.mark.slow
@pytest.mark.ci
def test_reset_world_from_another_process(sim_process: subprocess.Popen[str], domain: int) -> None:
    del sim_process, domain
    with Context() as ctx:
        node = Node("remote_client", context=ctx)
        get = node.create_client(GetModelState, "/gazebo/get_model_state")
        set_ = node.create_client(SetModelState, "/gazebo/set_model_state")
        reset = node.create_client(Empty, "/gazebo/reset_world")
        assert reset.wait_for_service(10.0)
        assert set_.wait_for_service(10.0)
        assert get.wait_for_service(10.0)
        moved = set_.call(
            set_request(model_name="tb3", pose={"position": {"x": 2.5}}), timeout_sec=5
        )
        assert moved.success
        assert _wait(
            lambda: get.call(GetModelState.Request("tb3", ""), timeout_sec=5).pose.position.x > 2.4,
            5.0,
        )
        reset.call(Empty.Request(), timeout_sec=5.0)
        assert _wait(
            lambda: (
                abs(get.call(GetModelState.Request("tb3", ""), timeout_sec=5).pose.position.x - 0.5)
                < 0.01
            ),
            5.0,
        )


@pytest.mark.slow
def test_cli_set_model_state_moves_the_robot_and_tf_follows(
    sim_process: subprocess.Popen[str], domain: int
) -> None:
    del sim_process
    with Context() as ctx:
        node = Node("tf_listener", context=ctx)
        tfs: list[Any] = []
        lock = threading.Lock()

        def on_tf(msg: Any) -> None:
            with lock:
                tfs.extend(
                    t.transform.translation.x
                    for t in msg.transforms
                    if t.child_frame_id == "base_footprint"
                )

        node.create_subscription(TFMessage, "/tf", on_tf, 1000)
        stop = threading.Event()
        spinner = threading.Thread(target=lambda: ctx.spin_until(stop.is_set, 60.0), daemon=True)
        spinner.start()
        try:
            assert _wait(lambda: bool(tfs), 10.0)
            assert tfs[-1] == pytest.approx(0.5, abs=0.02)
            out = subprocess.run(
                [
                    sys.executable, "-m", "visnav.cli.main", "service", "call",
                    "/gazebo/set_model_state", "gazebo_msgs/srv/SetModelState",
                    "{model_state: {model_name: tb3, pose: {position: {x: 1.0}}}}",
                ],
                capture_output=True, text=True, timeout=60, check=False,
                env={**os.environ, "VISNAV_DOMAIN": str(domain)},
            )  # fmt: skip
            assert out.returncode == 0, out.stderr
            assert "success=True" in out.stdout
            with lock:
                tfs.clear()
            # odom -> base_footprint (world odometry) jumps to the new pose on /tf
            assert _wait(lambda: bool(tfs) and abs(tfs[-1] - 1.0) < 0.02, 10.0), tfs[-5:]
        finally:
            stop.set()
            spinner.join(5.0)


@pytest.mark.slow
@pytest.mark.ci
def test_reset_simulation_from_another_process_rewinds_clock_and_tf_recovers(
    sim_process: subprocess.Popen[str], domain: int
) -> None:
    """As rospy / tf2_ros: /clock goes back, the listener clears its buffer, lookups work."""
    del sim_process, domain
    from visnav.tf.buffer import Buffer
    from visnav.tf.ros import TransformListener

    with Context() as ctx:
        node = Node("tf_consumer", context=ctx, use_sim_time=True)
        buffer = Buffer()
        TransformListener(buffer, node)
        clocks: list[int] = []
        lock = threading.Lock()

        def on_clock(msg: Any) -> None:
            with lock:
                clocks.append(msg.clock.sec * 10**9 + msg.clock.nanosec)

        node.create_subscription(
            get_message_class("rosgraph_msgs/msg/Clock"), "/clock", on_clock, 100
        )
        reset = node.create_client(Empty, "/gazebo/reset_simulation")
        stop = threading.Event()
        spinner = threading.Thread(target=lambda: ctx.spin_until(stop.is_set, 120.0), daemon=True)
        spinner.start()

        def stamp() -> int:
            t = buffer.lookup_transform("odom", "base_footprint", 0).header.stamp
            return int(t.sec) * 10**9 + int(t.nanosec)

        def works() -> bool:
            try:
                return stamp() > 0
            except Exception:  # noqa: BLE001  (not there yet)
                return False

        try:
            assert reset.wait_for_service(10.0)
            assert _wait(lambda: works() and node.get_clock().now_ns() > 2_000_000_000, 30.0)
            before = stamp()
            assert reset.call(Empty.Request(), timeout_sec=10.0) is not None
            # /clock restarts from about 0 and the node's sim time follows it back
            assert _wait(lambda: node.get_clock().now_ns() < 1_000_000_000, 10.0)
            with lock:
                assert any(c < 1_000_000_000 for c in clocks)
            # the listener cleared the old (future) transforms; new ones are looked up
            assert _wait(lambda: works() and stamp() < before, 10.0)
            assert _wait(lambda: works() and stamp() > 500_000_000, 10.0)
        finally:
            stop.set()
            spinner.join(5.0)
