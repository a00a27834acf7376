"""gazebo_ros_control in the simulator: diff_drive_controller, joint_state_controller, spawner."""

from __future__ import annotations

import math
import shutil
import threading
from collections import defaultdict
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbags.typesys.stores.ros2_humble import std_msgs__msg__Bool as Bool

from visnav.description.world_yaml import world_from_dict
from visnav.graph import Context, Node
from visnav.launch import Launcher, LaunchError, RoslaunchImportError, load_launch
from visnav.launch.param_check import unknown_parameters
from visnav.msgs import (
    JointState,
    Odometry,
    TFMessage,
    Twist,
    TwistStamped,
    message_from_dict,
    msg_type_name,
)
from visnav.msgs.time import time_to_ns
from visnav.sim.ros_control import RosControlError, RosControlPlugin
from visnav.sim.ros_controllers import DiffDriveRosController, SpeedLimiter, WheelOdometry
from visnav.sim.sim_node import SimulatorNode
from visnav.sim.simulator import RobotSpawn, Simulator
from visnav.tf.transforms import yaw_from_quaternion

DATA = Path(__file__).resolve().parents[1] / "data" / "husky"

ROBOT = """<robot name="rc_bot">
  <link name="base_footprint"/>
  <joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/>
    <origin xyz="0 0 0.05"/></joint>
  <link name="base_link">
    <inertial><mass value="4"/>
      <inertia ixx="0.04" ixy="0" ixz="0" iyy="0.06" iyz="0" izz="0.08"/></inertial>
    <collision><origin xyz="-0.05 0 0.05"/><geometry><box size="0.3 0.25 0.08"/></geometry>
    </collision>
  </link>
  {wheels}
  <link name="caster">
    <inertial><mass value="0.05"/>
      <inertia ixx="0.00001" ixy="0" ixz="0" iyy="0.00001" iyz="0" izz="0.00001"/></inertial>
    <collision><geometry><sphere radius="0.025"/></geometry></collision>
  </link>
  <joint name="caster_joint" type="fixed"><parent link="base_link"/><child link="caster"/>
    <origin xyz="-0.15 0 -0.025"/></joint>
  <gazebo reference="caster"><mu1>0</mu1><mu2>0</mu2></gazebo>
  <gazebo><plugin name="gazebo_ros_control" filename="libgazebo_ros_control.so">
    <robotNamespace>/</robotNamespace>{plugin}</plugin></gazebo>
  <gazebo><plugin name="ground_truth" filename="libgazebo_ros_p3d.so">
    <robotNamespace>/</robotNamespace><bodyName>base_footprint</bodyName>
    <topicName>ground_truth</topicName><frameName>world</frameName><updateRate>50</updateRate>
  </plugin></gazebo>
</robot>"""

WHEEL = """<link name="{side}_wheel">
    <inertial><mass value="0.3"/>
      <inertia ixx="0.0003" ixy="0" ixz="0" iyy="0.0004" iyz="0" izz="0.0003"/></inertial>
    <collision><origin rpy="1.5707963 0 0"/>
      <geometry><cylinder radius="0.05" length="0.03"/></geometry></collision>
  </link>
  <joint name="{side}_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="{side}_wheel"/><origin xyz="0 {y} 0"/><axis xyz="0 1 0"/></joint>
  <transmission name="{side}_trans">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="{side}_wheel_joint"><hardwareInterface>{interface}</hardwareInterface></joint>
    <actuator name="{side}_motor"><mechanicalReduction>1</mechanicalReduction></actuator>
  </transmission>"""

WORLD = {"name": "flat", "ground": {"size": [40, 40]}, "metadata": {"spawn": [0.0, 0.0, 0.0]}}

JSC = {
    "joint_state_controller.type": "joint_state_controller/JointStateController",
    "joint_state_controller.publish_rate": 50,
}
DDC = {
    "mobile_base_controller.type": "diff_drive_controller/DiffDriveController",
    "mobile_base_controller.left_wheel": "left_wheel_joint",
    "mobile_base_controller.right_wheel": ["right_wheel_joint"],
}
BOTH = ["joint_state_controller", "mobile_base_controller"]


def robot(*, right: str = "hardware_interface/VelocityJointInterface", plugin: str = "") -> str:
    wheels = WHEEL.format(side="left", y=0.15, interface="VelocityJointInterface")
    wheels += WHEEL.format(side="right", y=-0.15, interface=right)
    return ROBOT.format(wheels=wheels, plugin=plugin)


def twist(lin: float, ang: float = 0.0) -> Twist:
    msg: Twist = message_from_dict(
        msg_type_name(Twist), {"linear": {"x": lin}, "angular": {"z": ang}}
    )
    return msg


def stamp(msg: Any) -> int:
    return time_to_ns(msg.header.stamp)


class Run:
    """A simulator of ``ROBOT`` whose node holds ``params``, and a recorder of its topics."""

    TOPICS: Mapping[str, type[Any]] = {
        "/mobile_base_controller/odom": Odometry,
        "/mobile_base_controller/cmd_vel_out": TwistStamped,
        "/ground_truth": Odometry,
        "/joint_states": JointState,
        "/tf": TFMessage,
    }

    def __init__(self, ctx: Context, params: Mapping[str, Any], urdf: str | None = None) -> None:
        self.node = Node("sim", context=ctx, parameter_overrides=dict(params))
        self.got: dict[str, list[Any]] = defaultdict(list)
        rec = Node("recorder", context=ctx)
        for topic, kind in self.TOPICS.items():
            rec.create_subscription(kind, topic, self.got[topic].append, 10000)
        self.cmd = rec.create_publisher(Twist, "/mobile_base_controller/cmd_vel", 10)
        self.e_stop = rec.create_publisher(Bool, "/e_stop", 10)
        world = world_from_dict(WORLD, source="flat")
        self.sim = Simulator(world, [urdf or robot()], context=ctx, node=self.node)

    def manager(self) -> RosControlPlugin:
        (plugin,) = [p for p in self.sim.robots[0].plugins if isinstance(p, RosControlPlugin)]
        return plugin

    def diff_drive(self) -> DiffDriveRosController:
        return diff_drive(self.manager(), "mobile_base_controller")


def diff_drive(manager: RosControlPlugin, name: str) -> DiffDriveRosController:
    controller = manager.controllers[name]
    assert isinstance(controller, DiffDriveRosController)
    return controller


@pytest.fixture
def ctx(mujoco_gl: str) -> Iterator[Context]:
    del mujoco_gl
    with Context(transport="local") as context:
        yield context


def test_topics_frames_tf_and_declared_parameter_names(ctx: Context) -> None:
    params = {
        "controllers": BOTH,
        **JSC,
        **DDC,
        "mobile_base_controller.publish_cmd": True,
        "mobile_base_controller.base_frame_id": "base_footprint",
        "mobile_base_controller.pose_covariance_diagonal": [1, 2, 3, 4, 5, 6],
        "mobile_base_controller.linear.x.has_velocity_limits": True,
        "mobile_base_controller.linear.x.max_velocity": 2,  # an int where a float is read
    }
    run = Run(ctx, params)
    with run.sim:
        run.sim.run(0.1)
    assert unknown_parameters(params, run.node.parameters) == []
    for name in ("mobile_base_controller.angular.z.max_jerk", "mobile_base_controller.open_loop"):
        assert name in run.node.parameters  # every parameter the controller reads is declared
    odom = run.got["/mobile_base_controller/odom"][-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_footprint")
    assert list(odom.pose.covariance[[0, 7, 14, 21, 28, 35]]) == [1, 2, 3, 4, 5, 6]
    frames = {(t.header.frame_id, t.child_frame_id) for m in run.got["/tf"] for t in m.transforms}
    assert ("odom", "base_footprint") in frames
    assert ("base_link", "left_wheel") in frames  # robot_state_publisher reads /joint_states
    joints = run.got["/joint_states"][-1]
    assert list(joints.name) == ["left_wheel_joint", "right_wheel_joint"]  # sorted by name
    assert run.got["/mobile_base_controller/cmd_vel_out"]


def test_odometry_follows_the_wheels_and_ground_truth_on_a_circle(ctx: Context) -> None:
    run = Run(
        ctx, {"controllers": BOTH, **JSC, **DDC, "mobile_base_controller.cmd_vel_timeout": 9.0}
    )
    with run.sim:
        run.sim.run(0.1)
        run.cmd.publish(twist(0.3, 0.6))
        run.sim.run(8.0)  # 4.8 rad: most of a circle of 0.5 m radius
    odoms = run.got["/mobile_base_controller/odom"]
    truth = {stamp(m): m for m in run.got["/ground_truth"]}
    g0 = run.got["/ground_truth"][0].pose.pose.position
    # the controller's own arithmetic, replayed from the published joint angles
    replay = WheelOdometry(0.3, 0.05, 0.05, window=10)
    replay.init(0)
    by_time = {stamp(m): m for m in run.got["/joint_states"]}
    for t_ns in sorted(by_time):
        left, right = by_time[t_ns].position
        replay.update(float(left), float(right), t_ns)
    last = odoms[-1]
    assert yaw_from_quaternion(last.pose.pose.orientation) == pytest.approx(
        math.remainder(replay.heading, math.tau), abs=0.02
    )
    errors = []
    for odom in odoms[::10]:
        at = stamp(odom)
        nearest = min(truth, key=lambda t: abs(t - at))
        g = truth[nearest].pose.pose
        dx = odom.pose.pose.position.x - (g.position.x - g0.x)
        dy = odom.pose.pose.position.y - (g.position.y - g0.y)
        errors.append(math.hypot(dx, dy))
        dyaw = math.remainder(
            yaw_from_quaternion(odom.pose.pose.orientation) - yaw_from_quaternion(g.orientation),
            math.tau,
        )
        assert abs(dyaw) < 0.15  # wheel sinkage into the soft ground shortens the arc a little
    assert max(errors) < 0.1  # over a 2.4 m arc
    assert last.twist.twist.linear.x == pytest.approx(0.3, abs=0.01)
    assert last.twist.twist.angular.z == pytest.approx(0.6, abs=0.02)
    assert len(run.got["/mobile_base_controller/odom"]) == pytest.approx(8.1 * 50, abs=2)


def test_speed_limiter_matches_diff_drive_controller() -> None:
    lim = SpeedLimiter(
        has_velocity_limits=True, has_acceleration_limits=True, has_jerk_limits=True,
        max_velocity=1.0, min_velocity=-0.5, max_acceleration=2.0, max_jerk=25.0,
    )  # fmt: skip
    assert lim.limit(5.0, 0.0, 0.0, 0.01) == pytest.approx(0.005)  # jerk: 25 * 2 * dt^2
    assert lim.limit(5.0, 0.9, 0.88, 0.1) == pytest.approx(1.0)  # velocity cap
    assert lim.limit(-5.0, -0.45, -0.45, 0.1) == pytest.approx(-0.5)  # min_velocity
    assert SpeedLimiter(has_acceleration_limits=True, max_acceleration=2.0).limit(
        -5.0, 0.0, 0.0, 0.1
    ) == pytest.approx(-0.2)  # min_acceleration defaults to -max_acceleration


def test_velocity_and_acceleration_limits_shape_the_command(ctx: Context) -> None:
    params = {
        "controllers": BOTH, **JSC, **DDC,
        "mobile_base_controller.publish_cmd": True,
        "mobile_base_controller.cmd_vel_timeout": 9.0,
        "mobile_base_controller.linear.x.has_velocity_limits": True,
        "mobile_base_controller.linear.x.max_velocity": 0.4,
        "mobile_base_controller.linear.x.has_acceleration_limits": True,
        "mobile_base_controller.linear.x.max_acceleration": 0.5,
        "mobile_base_controller.angular.z.has_velocity_limits": True,
        "mobile_base_controller.angular.z.max_velocity": 0.3,
    }  # fmt: skip
    run = Run(ctx, params)
    with run.sim:
        run.sim.run(0.1)
        run.cmd.publish(twist(2.0, -5.0))
        run.sim.run(2.0)
    out = run.got["/mobile_base_controller/cmd_vel_out"]
    lin = np.array([m.twist.linear.x for m in out])
    times = np.array([stamp(m) for m in out]) * 1e-9
    ramp = (times > 0.2) & (lin < 0.39)
    slope = np.polyfit(times[ramp], lin[ramp], 1)[0]
    assert slope == pytest.approx(0.5, rel=0.02)
    assert lin.max() == pytest.approx(0.4)
    assert min(m.twist.angular.z for m in out) == pytest.approx(-0.3)
    assert run.got["/mobile_base_controller/odom"][-1].twist.twist.linear.x == pytest.approx(
        0.4, abs=0.02
    )


def test_cmd_vel_timeout_and_e_stop_stop_the_wheels(ctx: Context) -> None:
    run = Run(
        ctx,
        {"controllers": BOTH, **JSC, **DDC, "mobile_base_controller.cmd_vel_timeout": 0.5},
        robot(plugin="<eStopTopic>/e_stop</eStopTopic>"),
    )
    with run.sim:
        run.sim.run(0.1)
        run.cmd.publish(twist(0.3))
        run.sim.run(0.4)
        moving = run.got["/joint_states"][-1].velocity
        run.sim.run(0.6)  # the command is 1.0 s old: older than cmd_vel_timeout
        timed_out = run.got["/joint_states"][-1].velocity
        run.cmd.publish(twist(0.3))
        run.sim.run(0.3)
        run.e_stop.publish(Bool(data=True))
        run.sim.run(0.3)
        stopped = run.got["/joint_states"][-1].velocity
        run.e_stop.publish(Bool(data=False))
        run.cmd.publish(twist(0.3))
        run.sim.run(0.3)
        released = run.got["/joint_states"][-1].velocity
    assert np.allclose(moving, 6.0, atol=0.3)  # 0.3 m/s on 0.05 m wheels
    assert np.allclose(timed_out, 0.0, atol=0.1)
    assert np.allclose(stopped, 0.0, atol=0.1)
    assert np.allclose(released, 6.0, atol=0.5)


def test_joint_state_controller_publishes_at_its_rate(ctx: Context) -> None:
    params = {"controllers": ["joint_state_controller"], **JSC}
    params["joint_state_controller.publish_rate"] = 40
    run = Run(ctx, params)
    with run.sim:
        run.sim.run(2.0)
    stamps = np.array([stamp(m) for m in run.got["/joint_states"]])
    assert stamps[0] == 0  # publishes in the first update
    step = run.sim.timestep_ns
    # due when last + 1 / rate < now, then last += 1 / rate: no drift, on physics steps
    assert np.all(np.abs(np.diff(stamps) - 25_000_000) < step)
    assert len(stamps) == 80  # 2 s at 40 Hz
    assert not run.got["/mobile_base_controller/odom"]  # a stopped / absent controller is quiet


def test_control_period_sets_the_update_rate(ctx: Context) -> None:
    params = {"controllers": BOTH, **JSC, **DDC, "mobile_base_controller.publish_cmd": True}
    run = Run(ctx, params, robot(plugin="<controlPeriod>0.01</controlPeriod>"))
    with run.sim:
        run.sim.run(0.5)
    stamps = np.array([stamp(m) for m in run.got["/mobile_base_controller/cmd_vel_out"]])
    assert np.all(np.diff(stamps) == 10_000_000)  # one controller update per control period


def test_stopped_controllers_are_loaded_but_do_not_run(ctx: Context) -> None:
    params = {
        "controllers": ["joint_state_controller"],
        "stopped_controllers": ["mobile_base_controller"],
        **JSC,
        **DDC,
    }
    run = Run(ctx, params)
    with run.sim:
        run.sim.run(0.1)
        run.cmd.publish(twist(0.3))
        run.sim.run(0.5)
        assert run.manager().loaded == ("mobile_base_controller",)
    assert not run.got["/mobile_base_controller/odom"]
    assert np.allclose(run.got["/joint_states"][-1].velocity, 0.0, atol=0.05)  # held at 0
    bad = {**params, "mobile_base_controller.type": "nope/Nope"}
    with pytest.raises(RosControlError, match="nope/Nope"):  # loading checks the configuration
        Run(ctx, bad)


def test_a_namespaced_robot_has_its_controller_manager_there(ctx: Context) -> None:
    params = {
        "controllers": ["r1/mobile_base_controller"],
        **{f"r1.{k}": v for k, v in DDC.items()},
    }
    node = Node("sim", context=ctx, parameter_overrides=params)
    got: list[Odometry] = []
    Node("rec", context=ctx).create_subscription(
        Odometry, "/r1/mobile_base_controller/odom", got.append, 100
    )
    world = world_from_dict(WORLD, source="flat")
    spawn = RobotSpawn(source=robot(), namespace="/r1", frame_prefix="r1/")
    with Simulator(world, [spawn], context=ctx, node=node) as sim:
        sim.run(0.1)
    assert got
    assert (got[-1].header.frame_id, got[-1].child_frame_id) == ("r1/odom", "r1/base_link")


def test_wheel_geometry_from_urdf_parameters_and_multipliers(ctx: Context) -> None:
    params = {
        "controllers": BOTH, **JSC, **DDC,
        "mobile_base_controller.wheel_separation_multiplier": 1.5,
        "mobile_base_controller.left_wheel_radius_multiplier": 1.1,
        "mobile_base_controller.right_wheel_radius_multiplier": 0.9,
    }  # fmt: skip
    run = Run(ctx, params)
    with run.sim:
        ddc = run.diff_drive()
    assert (ddc.separation, ddc.left_radius, ddc.right_radius) == pytest.approx(
        (0.45, 0.055, 0.045)
    )
    params["mobile_base_controller.wheel_radius_multiplier"] = 2.0  # overrides left/right
    params["mobile_base_controller.wheel_separation"] = 0.5
    run = Run(ctx, params)
    with run.sim:
        ddc = run.diff_drive()
    assert (ddc.separation, ddc.left_radius, ddc.right_radius) == pytest.approx((0.75, 0.1, 0.1))


@pytest.mark.parametrize(
    ("params", "urdf", "needle"),
    [
        (
            {"controllers": ["mobile_base_controller"], **DDC,
             "mobile_base_controller.type": "effort_controllers/JointEffortController"},
            None,
            "type 'effort_controllers/JointEffortController' is not simulated; visnav has "
            "diff_drive_controller/DiffDriveController, joint_state_controller/Joint",
        ),
        ({"controllers": ["nobody"]}, None, "/nobody/type is not set"),
        (
            {"controllers": ["mobile_base_controller"], **DDC},
            robot(right="EffortJointInterface"),
            "needs VelocityJointInterface on joint 'right_wheel_joint'",
        ),
        (
            {"controllers": ["mobile_base_controller"], **DDC,
             "mobile_base_controller.left_wheel": ["left_wheel_joint", "right_wheel_joint"]},
            None,
            "2 left wheels",
        ),
        (
            {"controllers": ["mobile_base_controller"], **DDC,
             "mobile_base_controller.cmd_vel_timeout": "soon"},
            None,
            "/mobile_base_controller/cmd_vel_timeout is 'soon': expected a number",
        ),
        (
            {"controllers": ["joint_state_controller"], **JSC,
             "joint_state_controller.publish_rate": None},
            None,
            "publish_rate is not set",
        ),
    ],
)  # fmt: skip
def test_controllers_that_cannot_load_are_one_clear_error(
    ctx: Context, params: dict[str, Any], urdf: str | None, needle: str
) -> None:
    params = {k: v for k, v in params.items() if v is not None}
    with pytest.raises(RosControlError, match=r"^controller") as info:
        Run(ctx, params, urdf)
    assert needle in str(info.value)
    assert "\n" not in str(info.value)


def test_spawned_controllers_without_ros_control_are_refused(ctx: Context, tmp_path: Path) -> None:
    urdf = tmp_path / "bot.urdf"
    urdf.write_text(robot().replace("libgazebo_ros_control.so", "libnothing.so"))
    world = tmp_path / "flat.yaml"
    world.write_text("name: flat\nground: {size: [10, 10]}\n")
    with pytest.raises(RosControlError, match=r"no robot has a libgazebo_ros_control\.so plugin"):
        SimulatorNode(
            "sim",
            context=ctx,
            parameter_overrides={
                "world": str(world), "robot": str(urdf), "realtime": False,
                "controllers": ["mobile_base_controller"], **DDC,
            },
        )  # fmt: skip


# --------------------------------------------------------------------------- roslaunch


def write_package(root: Path) -> Path:
    pkg = root / "rc_bot"
    (pkg / "launch").mkdir(parents=True)
    (pkg / "config").mkdir()
    (pkg / "package.xml").write_text("<package><name>rc_bot</name></package>\n")
    (pkg / "robot.urdf").write_text(robot())
    (pkg / "config" / "control.yaml").write_text(
        "joint_state_controller:\n"
        "  type: joint_state_controller/JointStateController\n"
        "  publish_rate: 50\n"
        "mobile_base_controller:\n"
        "  type: diff_drive_controller/DiffDriveController\n"
        "  left_wheel: left_wheel_joint\n"
        "  right_wheel: [right_wheel_joint]\n"
        "  linear: {x: {has_velocity_limits: true, max_velocity: 0.5}}\n"
        "  extra: [{a: 1}]\n"
    )
    (pkg / "launch" / "sim.launch").write_text(
        """<launch>
  <include file="$(find gazebo_ros)/launch/empty_world.launch"/>
  <param name="robot_description" textfile="$(find rc_bot)/robot.urdf"/>
  <node name="spawn" pkg="gazebo_ros" type="spawn_model"
        args="-urdf -param robot_description -model rc_bot"/>
  <rosparam command="load" file="$(find rc_bot)/config/control.yaml"/>
  <node name="spawner" pkg="controller_manager" type="spawner"
        args="joint_state_controller --shutdown-timeout 3"/>
  <node name="cm" pkg="controller_manager" type="controller_manager"
        args="spawn mobile_base_controller"/>
</launch>
"""
    )
    return pkg


def test_launch_spawners_fold_into_the_sim_node(tmp_path: Path) -> None:
    pkg = write_package(tmp_path)
    desc = load_launch(pkg / "launch" / "sim.launch", packages={"rc_bot": str(pkg)})
    (sim,) = desc.nodes
    assert sim.executable == "sim"
    p = sim.params
    assert p["controllers"] == ["joint_state_controller", "mobile_base_controller"]
    assert p["mobile_base_controller.linear.x.max_velocity"] == 0.5
    assert p["mobile_base_controller.right_wheel"] == ["right_wheel_joint"]
    assert "mobile_base_controller.extra" not in p  # a list of mappings is no parameter
    notes = "\n".join(desc.notes)
    assert "--shutdown-timeout 3 ignored" in notes
    assert "/mobile_base_controller/extra" in notes
    assert "start with the simulation" in notes


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        ("--bogus ctrl", "option '--bogus' is not mapped"),
        ("missing_ctrl", "controller 'missing_ctrl' has no /missing_ctrl/type"),
    ],
)
def test_bad_spawners_are_import_problems(tmp_path: Path, args: str, needle: str) -> None:
    pkg = write_package(tmp_path)
    launch = pkg / "launch" / "sim.launch"
    launch.write_text(
        launch.read_text().replace("joint_state_controller --shutdown-timeout 3", args)
    )
    with pytest.raises(RoslaunchImportError, match=needle):
        load_launch(launch, packages={"rc_bot": str(pkg)})


JSC_TYPE = "joint_state_controller/JointStateController"
_ARG_TOKENS = st.sampled_from(
    ["--stopped", "--namespace", "--namespace=r1", "--timeout", "5", "--no-timeout",
     "--shutdown-timeout", "--wait-for", "-h", "--bogus", "c", "d", "r1", "/abs", "spawn", "load",
     "kill", ""]
)  # fmt: skip


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.lists(_ARG_TOKENS, max_size=6), st.sampled_from(["spawner", "controller_manager"]))
def test_fuzzed_spawner_args_import_or_fail_clearly(
    tmp_path: Path, args: list[str], kind: str
) -> None:
    f = tmp_path / "fuzz.launch"
    f.write_text(
        f"""<launch>
  <include file="$(find gazebo_ros)/launch/empty_world.launch"/>
  <rosparam ns="c" command="load">{{type: {JSC_TYPE}}}</rosparam>
  <rosparam ns="r1/d" command="load">{{type: {JSC_TYPE}}}</rosparam>
  <node name="s" pkg="controller_manager" type="{kind}" args="{" ".join(args)}"/>
</launch>"""
    )
    try:
        (sim,) = load_launch(f).nodes
    except LaunchError:
        return
    for key in ("controllers", "stopped_controllers"):
        for entry in sim.params.get(key, []):
            assert f"{entry.replace('/', '.')}.type" in sim.params


def test_a_spawner_without_a_simulator_is_refused(tmp_path: Path) -> None:
    f = tmp_path / "x.launch"
    f.write_text(
        '<launch><rosparam param="/c/type">joint_state_controller/JointStateController'
        '</rosparam><node name="s" pkg="controller_manager" type="spawner" args="c"/></launch>'
    )
    with pytest.raises(RoslaunchImportError, match="exactly one simulator"):
        load_launch(f)


def test_spawner_namespace_and_stopped(tmp_path: Path) -> None:
    f = tmp_path / "x.launch"
    f.write_text(
        """<launch>
  <include file="$(find gazebo_ros)/launch/empty_world.launch"/>
  <rosparam ns="r1/c" command="load">{type: joint_state_controller/JointStateController}</rosparam>
  <rosparam ns="r2/d" command="load">{type: joint_state_controller/JointStateController}</rosparam>
  <group ns="r1"><node name="s" pkg="controller_manager" type="spawner" args="--stopped c"/></group>
  <node name="t" pkg="controller_manager" type="spawner" args="--namespace=r2 d"/>
</launch>"""
    )
    (sim,) = load_launch(f).nodes
    assert sim.params["stopped_controllers"] == ["r1/c"]
    assert sim.params["controllers"] == ["r2/d"]
    assert sim.params["r1.c.type"] == "joint_state_controller/JointStateController"


def test_a_launched_robot_drives_lock_step(ctx: Context, tmp_path: Path) -> None:
    pkg = write_package(tmp_path)
    (spec,) = load_launch(pkg / "launch" / "sim.launch", packages={"rc_bot": str(pkg)}).nodes
    node = SimulatorNode(
        spec.name, context=ctx, parameter_overrides={**spec.params, "realtime": False}
    )
    try:
        assert unknown_parameters(spec.params, node.parameters) == []
        got: list[Odometry] = []
        rec = Node("rec", context=ctx)
        rec.create_subscription(Odometry, "/mobile_base_controller/odom", got.append, 100)
        pub = rec.create_publisher(Twist, "/mobile_base_controller/cmd_vel", 10)
        for _ in range(20):
            pub.publish(twist(2.0))
            node.run_lockstep(0.1)
        assert got[-1].twist.twist.linear.x == pytest.approx(0.5, abs=0.01)  # the YAML's limit
    finally:
        node.destroy_node()


# --------------------------------------------------------------------------- the Husky

_COLLADA = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="p"><float_array id="pa" count="12">0 0 0 0.01 0 0 0 0.01 0 0 0 0.01</float_array>
      <technique_common><accessor source="#pa" count="4" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <triangles count="4"><input semantic="VERTEX" source="#v" offset="0"/>
      <p>0 2 1 0 1 3 0 3 2 1 2 3</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"/></node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""
# packages husky_description's accessory Xacros include at the top level (their macros are
# only expanded when an accessory is enabled, which the default Husky does not)
_INCLUDED = {
    "fath_pivot_mount_description": "urdf/lockmount.urdf.xacro",
    "flir_camera_description": "urdf/flir_blackflys.urdf.xacro",
    "lms1xx": "urdf/sick_lms1xx.urdf.xacro",
    "velodyne_description": "urdf/VLP-16.urdf.xacro",
}


def husky_packages(root: Path) -> dict[str, str]:
    """The vendored Husky packages, with stand-ins for the large meshes left out (SOURCE.md)."""
    out = {}
    for pkg in ("husky_description", "husky_control", "husky_gazebo"):
        shutil.copytree(DATA / pkg, root / pkg)
        out[pkg] = str(root / pkg)
    for mesh in ("wheel.dae", "top_chassis.dae", "user_rail.dae"):
        (root / "husky_description" / "meshes" / mesh).write_text(_COLLADA)
    for pkg, rel in _INCLUDED.items():
        path = root / pkg / rel
        path.parent.mkdir(parents=True)
        path.write_text('<robot xmlns:xacro="http://ros.org/wiki/xacro"/>\n')
        (root / pkg / "package.xml").write_text(f"<package><name>{pkg}</name></package>\n")
        out[pkg] = str(root / pkg)
    return out


@pytest.fixture
def husky(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    packages = husky_packages(tmp_path)
    return Path(packages["husky_gazebo"]) / "launch" / "empty_world.launch", packages


def test_husky_launch_files_spawn_its_controllers(husky: tuple[Path, dict[str, str]]) -> None:
    launch, packages = husky
    desc = load_launch(launch, packages=packages, skip_unmapped=True)
    (sim,) = desc.nodes
    p = sim.params
    assert p["controllers"] == ["husky_joint_publisher", "husky_velocity_controller"]
    assert p["husky_velocity_controller.left_wheel"] == ["front_left_wheel", "rear_left_wheel"]
    assert p["husky_velocity_controller.wheel_separation_multiplier"] == 1.875
    assert p["husky_velocity_controller.linear.x.max_acceleration"] == 3.0
    assert p["husky_velocity_controller.wheel_radius_multiplier"] == 1.0  # the subst_value one
    skipped = [n for n in desc.notes if n.startswith("skipped")]
    assert len(skipped) == 5  # ekf, marker_server, twist_mux, joy_node, teleop_twist_joy


def test_husky_drives_on_its_velocity_controller(
    ctx: Context, husky: tuple[Path, dict[str, str]]
) -> None:
    launch, packages = husky
    (spec,) = load_launch(launch, packages=packages, skip_unmapped=True).nodes
    node = SimulatorNode(
        spec.name, context=ctx, parameter_overrides={**spec.params, "realtime": False}
    )
    try:
        assert unknown_parameters(spec.params, node.parameters) == []
        got: dict[str, list[Any]] = defaultdict(list)
        rec = Node("rec", context=ctx)
        for topic, kind in (
            ("/husky_velocity_controller/odom", Odometry),
            ("/husky_velocity_controller/cmd_vel_out", TwistStamped),
            ("/joint_states", JointState),
            ("/tf", TFMessage),
        ):
            rec.create_subscription(kind, topic, got[topic].append, 1000)
        pub = rec.create_publisher(Twist, "/husky_velocity_controller/cmd_vel", 10)
        ddc = next(p for p in node.sim.robots[0].plugins if isinstance(p, RosControlPlugin))
        wheels = diff_drive(ddc, "husky_velocity_controller")
        assert wheels.separation == pytest.approx(0.5708 * 1.875)  # the URDF's track
        assert wheels.left_radius == pytest.approx(0.1651)  # the wheel's collision cylinder
        data, body = node.sim.data, node.sim.model.body("husky/base_link").id

        def truth() -> tuple[float, float, float]:
            w, x, y, z = (float(v) for v in data.xquat[body])
            return (
                float(data.xpos[body][0]),
                float(data.xpos[body][1]),
                yaw_from_quaternion((x, y, z, w)),
            )

        node.run_lockstep(1.5)  # spawned at -z 0 with its wheels in the ground: it pops out
        odom0 = got["/husky_velocity_controller/odom"][-1].pose.pose
        x0, y0, _ = truth()
        for _ in range(20):
            pub.publish(twist(2.0))
            node.run_lockstep(0.1)
        odom = got["/husky_velocity_controller/odom"][-1]
        assert odom.twist.twist.linear.x == pytest.approx(1.0, abs=0.02)  # max_velocity 1.0
        x1, y1, yaw1 = truth()
        travelled = odom.pose.pose.position.x - odom0.position.x
        assert travelled > 1.2  # ramped at 3 m/s^2 to 1 m/s, 2 s
        assert math.hypot(x1 - x0, y1 - y0) == pytest.approx(travelled, rel=0.05)
        start_yaw = yaw_from_quaternion(odom.pose.pose.orientation)
        for _ in range(10):
            pub.publish(twist(0.0, 0.5))
            node.run_lockstep(0.1)
        yaw = yaw_from_quaternion(got["/husky_velocity_controller/odom"][-1].pose.pose.orientation)
        assert yaw - start_yaw == pytest.approx(0.5, abs=0.1)  # the odometry's (ws x 1.875)
        # the body turns left too, slower: skid steering in MuJoCo's friction cone slips more
        # than in Gazebo's ODE friction pyramid, which the 1.875 multiplier is tuned for
        assert 0.05 < truth()[2] - yaw1 < 0.5
    finally:
        node.destroy_node()
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
    assert got["/husky_velocity_controller/cmd_vel_out"]
    frames = {(t.header.frame_id, t.child_frame_id) for m in got["/tf"] for t in m.transforms}
    assert ("odom", "base_link") not in frames  # enable_odom_tf: false (robot_localization's)
    assert ("base_link", "front_left_wheel_link") in frames
    assert list(got["/joint_states"][-1].name) == sorted(
        ["front_left_wheel", "front_right_wheel", "rear_left_wheel", "rear_right_wheel"]
    )


@pytest.mark.slow
@pytest.mark.ci
def test_husky_launch_runs(domain: int, husky: tuple[Path, dict[str, str]]) -> None:
    launch, packages = husky
    launcher = Launcher(load_launch(launch, packages=packages, skip_unmapped=True), domain=domain)
    stop = threading.Event()
    thread = threading.Thread(target=launcher.run, args=(stop,), daemon=True)
    thread.start()
    try:
        with Context(domain) as ctx:
            got: list[Odometry] = []
            node = Node("driver", context=ctx)
            node.create_subscription(Odometry, "/husky_velocity_controller/odom", got.append, 100)
            pub = node.create_publisher(Twist, "/husky_velocity_controller/cmd_vel", 10)

            def moving() -> bool:
                return bool(got) and got[-1].pose.pose.position.x > 0.3

            node.create_timer(0.05, lambda: pub.publish(twist(0.5)))
            assert ctx.spin_until(moving, 60.0)
    finally:
        stop.set()
        thread.join(20)
