"""``/gazebo/spawn_urdf_model``, ``/gazebo/spawn_sdf_model`` and ``/gazebo/delete_model``:
models added to and removed from a running simulation, in process and from another
process through ``visnav service call``."""

from __future__ import annotations

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

from visnav.description.sdf_model import sdf_model_to_urdf
from visnav.graph import Context, Node
from visnav.msgs import Odometry, Twist, Vector3
from visnav.msgs.construct import message_from_dict
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type
from visnav.sim.simulator import RobotSpawn, Simulator

SCRIPTS = Path(__file__).resolve().parent / "scripts"
SpawnModel = get_service_type("gazebo_msgs/srv/SpawnModel")
DeleteModel = get_service_type("gazebo_msgs/srv/DeleteModel")
GetModelState = get_service_type("gazebo_msgs/srv/GetModelState")

BOX_SDF = """<?xml version="1.0"?>
<sdf version="1.6">
  <model name="box">
    <link name="link">
      <inertial><mass>2.0</mass>
        <inertia><ixx>0.08</ixx><iyy>0.08</iyy><izz>0.08</izz></inertia></inertial>
      <collision name="collision"><geometry><box><size>0.5 0.5 0.5</size></box></geometry>
      </collision>
      <visual name="visual"><geometry><box><size>0.5 0.5 0.5</size></box></geometry>
        <material><diffuse>0.8 0.2 0.2 1</diffuse></material></visual>
    </link>
  </model>
</sdf>"""

ROVER_URDF = """<?xml version="1.0"?>
<robot name="rover">
  <link name="base_link">
    <inertial><origin xyz="0 0 0.1"/><mass value="4"/>
      <inertia ixx="0.05" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial>
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.4 0.3 0.1"/></geometry></collision>
  </link>
  <link name="caster">
    <inertial><mass value="0.1"/>
      <inertia ixx="0.0001" ixy="0" ixz="0" iyy="0.0001" iyz="0" izz="0.0001"/></inertial>
    <collision><geometry><sphere radius="0.05"/></geometry></collision>
  </link>
  <joint name="caster_joint" type="fixed"><parent link="base_link"/><child link="caster"/>
    <origin xyz="-0.15 0 0.05"/></joint>
  <link name="left_wheel">
    <inertial><mass value="0.3"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
    <collision><origin rpy="1.5708 0 0"/><geometry><cylinder radius="0.05" length="0.03"/>
    </geometry></collision>
  </link>
  <link name="right_wheel">
    <inertial><mass value="0.3"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
    <collision><origin rpy="1.5708 0 0"/><geometry><cylinder radius="0.05" length="0.03"/>
    </geometry></collision>
  </link>
  <joint name="left_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="left_wheel"/><origin xyz="0.05 0.18 0.05"/><axis xyz="0 1 0"/></joint>
  <joint name="right_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="right_wheel"/><origin xyz="0.05 -0.18 0.05"/><axis xyz="0 1 0"/></joint>
  <gazebo>
    <plugin name="diff_drive" filename="libgazebo_ros_diff_drive.so">
      <updateRate>50</updateRate>
      <leftJoint>left_wheel_joint</leftJoint>
      <rightJoint>right_wheel_joint</rightJoint>
      <wheelSeparation>0.36</wheelSeparation>
      <wheelDiameter>0.1</wheelDiameter>
      <wheelTorque>5</wheelTorque>
      <commandTopic>cmd_vel</commandTopic>
      <odometryTopic>odom</odometryTopic>
      <odometryFrame>odom</odometryFrame>
      <robotBaseFrame>base_link</robotBaseFrame>
      <odometrySource>world</odometrySource>
      <publishOdomTF>true</publishOdomTF>
    </plugin>
  </gazebo>
</robot>"""


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as context:
        yield context


def spawn_request(name: str, xml: str, **fields: Any) -> Any:
    return message_from_dict(
        SpawnModel.request_type_name, {"model_name": name, "model_xml": xml, **fields}
    )


def call(sim: Simulator, client: Any, request: Any) -> Any:
    future = client.call_async(request)
    for _ in range(400):
        if future.done():
            break
        sim.step(1)
    assert future.done()
    return future.result()


class Clients:
    def __init__(self, ctx: Context) -> None:
        self.node = Node("spawner", context=ctx)
        self.urdf = self.node.create_client(SpawnModel, "/gazebo/spawn_urdf_model")
        self.sdf = self.node.create_client(SpawnModel, "/gazebo/spawn_sdf_model")
        self.delete = self.node.create_client(DeleteModel, "/gazebo/delete_model")
        self.get = self.node.create_client(GetModelState, "/gazebo/get_model_state")

    def state(self, sim: Simulator, name: str, ref: str = "") -> Any:
        return call(sim, self.get, GetModelState.Request(name, ref))


def rover_sim(ctx: Context) -> Simulator:
    spawn = RobotSpawn(
        source=ROVER_URDF, name="first", spawn=(0.0, 0.0, 0.0, 0.0), namespace="/first"
    )
    return Simulator("empty", [spawn], context=ctx)


def test_sdf_model_to_urdf_keeps_links_joints_inertials_and_plugins() -> None:
    sdf = """<sdf version="1.6"><model name="arm">
      <static>false</static>
      <link name="base"><pose>0 0 0.5 0 0 0</pose><inertial><mass>3</mass></inertial>
        <collision name="c"><geometry><cylinder><radius>0.1</radius><length>1</length>
        </cylinder></geometry></collision>
        <sensor name="cam" type="camera"><update_rate>10</update_rate></sensor></link>
      <link name="tip"><pose>0 0 1.2 0 0 0</pose><inertial><mass>1</mass></inertial></link>
      <joint name="hinge" type="revolute"><parent>base</parent><child>tip</child>
        <axis><xyz>0 1 0</xyz><limit><lower>-1</lower><upper>1</upper></limit></axis></joint>
      <plugin name="p" filename="libgazebo_ros_p3d.so"><bodyName>tip</bodyName></plugin>
    </model></sdf>"""
    urdf = sdf_model_to_urdf(sdf)
    assert '<joint name="hinge" type="revolute">' in urdf
    assert 'xyz="0 0 0.7"' in urdf  # the tip 0.7 m above the base, in the base frame
    assert '<limit effort="100" velocity="100" lower="-1" upper="1" />' in urdf
    assert '<gazebo reference="base"><sensor name="cam"' in urdf
    assert 'filename="libgazebo_ros_p3d.so"' in urdf


def test_spawned_sdf_box_falls_collides_and_is_in_model_states(ctx: Context) -> None:
    clients = Clients(ctx)
    states: list[Any] = []
    clients.node.create_subscription(
        get_message_class("gazebo_msgs/msg/ModelStates"), "/gazebo/model_states", states.append, 5
    )
    with rover_sim(ctx) as sim:
        sim.step(200)
        before = clients.state(sim, "first").pose.position
        now = sim.now_ns
        reply = call(
            sim,
            clients.sdf,
            spawn_request("box", BOX_SDF, initial_pose={"position": {"x": 2.0, "z": 1.0}}),
        )
        assert reply.success, reply.status_message
        assert "Successfully spawned" in reply.status_message
        assert sim.now_ns >= now  # sim time runs on, never back
        after = clients.state(sim, "first").pose.position
        assert after.x == pytest.approx(before.x, abs=1e-4)  # the rover kept its state
        sim.step(600)  # 1.2 s: the box falls 0.75 m and rests on the ground
        box = clients.state(sim, "box")
        assert box.success
        assert box.pose.position.x == pytest.approx(2.0, abs=0.01)
        assert box.pose.position.z == pytest.approx(0.25, abs=0.01)
        relative = clients.state(sim, "box", "first")
        assert relative.pose.position.x == pytest.approx(2.0 - after.x, abs=0.02)
        assert states
        assert "box" in states[-1].name
        reply = call(sim, clients.delete, DeleteModel.Request("box"))
        assert reply.success, reply.status_message
        sim.step(5)
        assert not clients.state(sim, "box").success
        assert [r.name for r in sim.robots] == ["first"]
        states.clear()
        sim.step(5)
        assert states
        assert "box" not in states[-1].name


def test_spawned_robot_drives_on_cmd_vel_and_survives_deleting_the_robot_before_it(
    ctx: Context,
) -> None:
    clients = Clients(ctx)
    odom: list[Odometry] = []
    clients.node.create_subscription(Odometry, "/second/odom", odom.append, 100)
    cmd = clients.node.create_publisher(Twist, "/second/cmd_vel", 10)
    with rover_sim(ctx) as sim:
        sim.step(100)
        reply = call(
            sim,
            clients.urdf,
            spawn_request(
                "second",
                ROVER_URDF,
                robot_namespace="/second",
                initial_pose={"position": {"y": 2.0}, "orientation": {"z": 1.0, "w": 0.0}},
            ),
        )
        assert reply.success, reply.status_message
        sim.step(250)
        assert odom  # its diff drive plugin publishes under the namespace
        start = clients.state(sim, "second").pose
        assert start.position.y == pytest.approx(2.0, abs=0.02)
        assert abs(start.orientation.z) == pytest.approx(1.0, abs=0.01)  # facing -x
        cmd.publish(Twist(linear=Vector3(0.3, 0.0, 0.0), angular=Vector3(0.0, 0.0, 0.0)))
        sim.step(500)
        moved = clients.state(sim, "second").pose.position
        assert moved.x < start.position.x - 0.15  # drove forward, i.e. towards -x
        # deleting the robot built before it shifts every MuJoCo id of this one
        reply = call(sim, clients.delete, DeleteModel.Request("first"))
        assert reply.success, reply.status_message
        sim.step(5)
        count = len(odom)
        sim.step(500)
        assert len(odom) > count
        later = clients.state(sim, "second").pose.position
        assert later.x < moved.x - 0.15  # still driving, its plugins rebound


def test_spawn_and_delete_failures_answer_as_gazebo_ros(ctx: Context) -> None:
    clients = Clients(ctx)
    with rover_sim(ctx) as sim:
        taken = call(sim, clients.urdf, spawn_request("first", ROVER_URDF))
        assert not taken.success
        assert taken.status_message == "SpawnModel: Failure - model name first already exists."
        for xml in ("<robot name='x'><link", "not xml at all", "<sdf><world name='w'/></sdf>", ""):
            bad = call(sim, clients.sdf, spawn_request("bad", xml))
            assert not bad.success
            assert bad.status_message.startswith("SpawnModel: Failure")
        xacro = ROVER_URDF.replace('<robot name="rover">', '<robot name="x" xmlns:xacro="x">')
        refused = call(sim, clients.urdf, spawn_request("x", xacro))
        assert not refused.success
        assert "Xacro" in refused.status_message
        frame = call(sim, clients.urdf, spawn_request("x", ROVER_URDF, reference_frame="ghost"))
        assert not frame.success
        assert "reference frame [ghost] not found" in frame.status_message
        gone = call(sim, clients.delete, DeleteModel.Request("ghost"))
        assert not gone.success
        assert "does not exist" in gone.status_message
        assert [r.name for r in sim.robots] == ["first"]
        sim.step(50)
        assert clients.state(sim, "first").success


_floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
_number = st.one_of(_floats.map(repr), st.sampled_from(["0", "1", "-1", "1e9", "x", ""]))
_xml = st.one_of(
    st.text(max_size=60),
    st.builds(
        lambda size, mass, name: (
            f"<sdf version='1.6'><model name='{name}'><link name='l'><inertial><mass>{mass}"
            f"</mass></inertial><collision name='c'><geometry><box><size>{size}</size></box>"
            "</geometry></collision></link></model></sdf>"
        ),
        st.lists(_number, max_size=4).map(" ".join),
        _number,
        st.text(alphabet="ab_/<> &", max_size=8),
    ),
    st.builds(
        lambda mass, joint: (
            f"<robot name='r'><link name='a'><inertial><mass value='{mass}'/><inertia ixx='1' "
            "ixy='0' ixz='0' iyy='1' iyz='0' izz='1'/></inertial></link><link name='b'/>"
            f"<joint name='j' type='{joint}'><parent link='a'/><child link='b'/></joint></robot>"
        ),
        _number,
        st.sampled_from(["fixed", "revolute", "continuous", "floating", "bogus", ""]),
    ),
)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    name=st.one_of(st.text(max_size=12), st.sampled_from(["first", "", "ground_plane"])),
    xml=_xml,
    position=st.fixed_dictionaries({"x": _floats, "y": _floats, "z": _floats}),
    namespace=st.text(max_size=10),
)
def test_fuzz_spawn_requests_answer_and_the_sim_survives(
    fuzz_sim: tuple[Simulator, Clients],
    name: str,
    xml: str,
    position: dict[str, float],
    namespace: str,
) -> None:
    sim, clients = fuzz_sim
    request = spawn_request(
        name, xml, robot_namespace=namespace, initial_pose={"position": position}
    )
    reply = call(sim, clients.sdf, request)
    assert isinstance(reply.success, bool)
    if not reply.success:
        assert reply.status_message.startswith("SpawnModel: Failure")
    else:
        spawned = reply.status_message.split("[")[-1].rstrip("]")
        sim.step(10)
        assert np.all(np.isfinite(sim.data.qpos))
        gone = call(sim, clients.delete, DeleteModel.Request(spawned))
        assert gone.success, gone.status_message
    sim.step(10)
    assert [r.name for r in sim.robots] == ["first"]
    assert clients.state(sim, "first").success


@pytest.fixture(scope="module")
def fuzz_sim() -> Iterator[tuple[Simulator, Clients]]:
    with Context(transport="local") as ctx, rover_sim(ctx) as sim:
        yield sim, Clients(ctx)


# ---------------------------------------------------------------------- other processes


def _wait(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


def _cli(domain: int, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", *args],
        capture_output=True, text=True, timeout=120, check=False,
        env={**os.environ, "VISNAV_DOMAIN": str(domain)},
    )  # fmt: skip


@pytest.mark.slow
def test_spawn_drive_and_delete_from_other_processes(
    start_script: Callable[..., subprocess.Popen[str]], domain: int
) -> None:
    start_script(SCRIPTS / "gazebo_sim.py", "300")
    box = _cli(
        domain, "service", "call", "/gazebo/spawn_sdf_model", "gazebo_msgs/srv/SpawnModel",
        f"{{model_name: box, model_xml: '{BOX_SDF}', "
        "initial_pose: {position: {x: 2.0, z: 0.5}}}",
    )  # fmt: skip
    assert box.returncode == 0, box.stderr
    assert "success=True" in box.stdout, box.stdout
    with Context() as ctx:
        node = Node("remote", context=ctx)
        spawn = node.create_client(SpawnModel, "/gazebo/spawn_urdf_model")
        delete = node.create_client(DeleteModel, "/gazebo/delete_model")
        get = node.create_client(GetModelState, "/gazebo/get_model_state")
        assert spawn.wait_for_service(10.0)
        reply = spawn.call(
            spawn_request(
                "rover", ROVER_URDF, robot_namespace="/rover",
                initial_pose={"position": {"x": -1.0}},
            ),
            timeout_sec=60.0,
        )  # fmt: skip
        assert reply.success, reply.status_message
        odom: list[Odometry] = []
        driver = Node("driver", context=ctx)  # destroyed before the delete: its topics go
        driver.create_subscription(Odometry, "/rover/odom", odom.append, 100)
        cmd = driver.create_publisher(Twist, "/rover/cmd_vel", 10)
        stop = threading.Event()
        spinner = threading.Thread(target=lambda: ctx.spin_until(stop.is_set, 120.0), daemon=True)
        spinner.start()
        try:
            assert _wait(lambda: bool(odom), 20.0)
            x0 = get.call(GetModelState.Request("rover", ""), timeout_sec=5.0).pose.position.x

            def driven() -> bool:
                cmd.publish(Twist(linear=Vector3(0.3, 0.0, 0.0), angular=Vector3(0.0, 0.0, 0.0)))
                state = get.call(GetModelState.Request("rover", ""), timeout_sec=5.0)
                return bool(state.pose.position.x > x0 + 0.2)

            assert _wait(driven, 30.0)
        finally:
            stop.set()
            spinner.join(5.0)
        resting = get.call(GetModelState.Request("box", ""), timeout_sec=5.0)
        assert resting.success
        assert resting.pose.position.z == pytest.approx(0.25, abs=0.02)
        topics = _cli(domain, "topic", "list")
        assert "/rover/odom" in topics.stdout, topics.stdout
        driver.destroy_node()
        gone = delete.call(DeleteModel.Request("rover"), timeout_sec=30.0)
        assert gone.success, gone.status_message
        assert not get.call(GetModelState.Request("rover", ""), timeout_sec=5.0).success
        assert _wait(lambda: "/rover/odom" not in _cli(domain, "topic", "list").stdout, 20.0)
        tb3 = get.call(GetModelState.Request("tb3", ""), timeout_sec=5.0)
        assert tb3.success  # the rest continues


@pytest.mark.slow
def test_spawned_camera_renders_and_sees_models_spawned_and_deleted_later(
    mujoco_gl: str,
) -> None:
    """A camera spawned into a sim without one gets a renderer; later models appear in it."""
    del mujoco_gl
    from visnav.description.robots import resolve_robot
    from visnav.msgs import Image
    from visnav.msgs.image import image_to_numpy

    with Context(transport="local") as ctx, rover_sim(ctx) as sim:
        clients = Clients(ctx)
        images: list[Image] = []
        clients.node.create_subscription(Image, "/cam/camera/image_raw", images.append, 10)
        car = resolve_robot("car").xml
        reply = call(
            sim,
            clients.urdf,
            spawn_request(
                "car2", car, robot_namespace="/cam", initial_pose={"position": {"x": -1.0}}
            ),
        )
        assert reply.success, reply.status_message
        sim.run(0.3)
        assert images

        def red_pixels() -> int:
            rgb = image_to_numpy(images[-1]).astype(np.int64)
            return int(np.count_nonzero((rgb[..., 0] - rgb[..., 1] > 80) & (rgb[..., 0] > 120)))

        assert red_pixels() < 100
        reply = call(
            sim,
            clients.sdf,
            spawn_request("box", BOX_SDF, initial_pose={"position": {"x": 1.0, "z": 0.25}}),
        )
        assert reply.success, reply.status_message
        images.clear()
        sim.run(0.3)
        assert images
        assert red_pixels() > 5000  # the red box, 2 m ahead, fills part of the view
        assert call(sim, clients.delete, DeleteModel.Request("box")).success
        images.clear()
        sim.run(0.3)
        assert images
        assert red_pixels() < 100
