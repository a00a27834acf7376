"""Vehicles: the Gazebo-style differential drive, the SO(3) quadrotor, the built-in robots."""

from __future__ import annotations

import io
import math

import mujoco
import numpy as np
import pytest
import xacro
import yourdfpy
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.description.errors import QuadrotorParamsError
from visnav.description.robots import car_description_path, quadrotor_description_path
from visnav.description.vehicle_params import QuadrotorParams
from visnav.sim.vehicles.diff_drive import (
    DiffDriveConfig,
    DiffDriveController,
    DiffDriveError,
    EncoderOdometry,
)
from visnav.sim.vehicles.quadrotor import (
    PositionCommand,
    QuadrotorController,
    QuadrotorError,
    QuadrotorState,
    SO3Gains,
    add_quadrotor,
    so3_control,
)

WHEEL_RADIUS = 0.08
SEPARATION = 0.36
DT_NS = 2_000_000

# ----------------------------------------------------------------------------- diff drive


def _car(**overrides: object) -> tuple[mujoco.MjModel, mujoco.MjData, DiffDriveConfig]:
    """A diff-drive test car built directly with MjSpec (chassis, two wheels, a caster)."""
    spec = mujoco.MjSpec()
    spec.option.timestep = DT_NS * 1e-9
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[30, 30, 1])
    base = spec.worldbody.add_body(name="base_footprint")
    base.add_freejoint(name="root")
    base.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[0.21, 0.14, 0.06],
        pos=[-0.06, 0, WHEEL_RADIUS + 0.06],
        mass=5.0,
    )
    for side, y in (("left", SEPARATION / 2), ("right", -SEPARATION / 2)):
        wheel = base.add_body(name=f"{side}_wheel", pos=[0, y, WHEEL_RADIUS])
        wheel.add_joint(
            name=f"{side}_wheel_joint", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0]
        )
        wheel.add_geom(
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[WHEEL_RADIUS, 0.02, 0],
            quat=[math.sqrt(0.5), math.sqrt(0.5), 0, 0],
            mass=0.5,
        )
    # a frictionless caster: condim 1 and a priority so its (zero) friction wins
    base.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[0.04, 0, 0],
        pos=[-0.2, 0, 0.04],
        condim=1,
        priority=1,
        mass=0.1,
    )
    params: dict[str, object] = {
        "left_joints": ("left_wheel_joint",),
        "right_joints": ("right_wheel_joint",),
        "wheel_separation": (SEPARATION,),
        "wheel_diameter": (2 * WHEEL_RADIUS,),
        "max_wheel_acceleration": 1.0,
        "max_wheel_torque": 20.0,
        "update_rate": 50.0,
    }
    params.update(overrides)
    config = DiffDriveConfig(**params)  # type: ignore[arg-type]
    model = spec.compile()
    return model, mujoco.MjData(model), config


def _drive(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    controller: DiffDriveController,
    seconds: float,
    start_step: int = 0,
) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Step the car; return (time, qpos[:7], qvel[:6]) after every step."""
    out = []
    for k in range(start_step, start_step + round(seconds / (DT_NS * 1e-9))):
        controller.step(data, k * DT_NS)
        mujoco.mj_step(model, data)
        out.append(((k + 1) * DT_NS * 1e-9, data.qpos[:7].copy(), data.qvel[:6].copy()))
    return out


def _yaw(q: np.ndarray) -> float:
    w, x, y, z = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def test_diff_drive_reaches_speed_within_the_acceleration_limit() -> None:
    model, data, config = _car(max_wheel_acceleration=1.0)
    controller = DiffDriveController(model, config, base_body="base_footprint")
    controller.set_command(0.5, 0.0)
    log = _drive(model, data, controller, 2.0)
    t = np.array([row[0] for row in log])
    speed = np.array([np.hypot(*row[2][:2]) for row in log])
    # never faster than the ramp allows (one 50 Hz update of slack), and no later than it
    assert (speed <= 1.0 * t + 0.03).all()
    assert speed[t < 0.45].max() < 0.47
    settled = speed[t > 0.8]
    assert np.abs(settled - 0.5).max() < 0.015
    assert speed[np.searchsorted(t, 0.62)] > 0.48
    # the wheels' torque stays within max_wheel_torque at every step
    assert np.abs(data.qfrc_applied[6:8]).max() <= 20.0


def test_diff_drive_without_acceleration_limit_and_with_a_weak_motor() -> None:
    model, data, config = _car(max_wheel_acceleration=0.0)
    controller = DiffDriveController(model, config, base_body="base_footprint")
    controller.set_command(0.5, 0.0)
    log = _drive(model, data, controller, 0.3)
    assert np.hypot(*log[-1][2][:2]) == pytest.approx(0.5, abs=0.01)
    # a 0.05 N m limit can only push ~5.6 kg at 2 * 0.05 / 0.08 / 5.6 = 0.22 m/s^2
    model, data, config = _car(max_wheel_acceleration=0.0, max_wheel_torque=0.05)
    weak = DiffDriveController(model, config, base_body="base_footprint")
    weak.set_command(0.5, 0.0)
    peak = 0.0
    for k in range(500):
        weak.step(data, k * DT_NS)
        peak = max(peak, float(np.abs(data.qfrc_applied[6:8]).max()))
        mujoco.mj_step(model, data)
    assert peak == pytest.approx(0.05)
    assert np.hypot(*data.qvel[:2]) < 0.25


@pytest.mark.parametrize(("v", "w"), [(0.3, 0.5), (0.0, 1.0), (0.4, -0.8)])
def test_diff_drive_turning_rate(v: float, w: float) -> None:
    model, data, config = _car(max_wheel_acceleration=0.0)
    controller = DiffDriveController(model, config, base_body="base_footprint")
    controller.set_command(v, w)
    log = _drive(model, data, controller, 1.5)
    yaw_rate = np.array([row[2][5] for row in log if row[0] > 0.5])
    assert yaw_rate.mean() == pytest.approx(w, rel=0.06)
    speed = np.array([np.hypot(*row[2][:2]) for row in log if row[0] > 0.5])
    assert speed.mean() == pytest.approx(v, abs=0.02)


def test_world_odometry_is_the_ground_truth_at_update_rate() -> None:
    model, data, config = _car(odometry_source="world", update_rate=50.0)
    controller = DiffDriveController(model, config, base_body="base_footprint")
    controller.set_command(0.4, 0.3)
    samples = []
    for k in range(501):  # 0 .. 1 s
        odom = controller.step(data, k * DT_NS)
        if odom is not None:
            samples.append(odom)
            np.testing.assert_allclose(odom.position, data.qpos[:3], atol=1e-12)
            assert odom.yaw == pytest.approx(_yaw(data.qpos[3:7]), abs=1e-9)
            forward = np.array([math.cos(odom.yaw), math.sin(odom.yaw)])
            assert odom.linear[0] == pytest.approx(float(forward @ data.qvel[:2]), abs=1e-6)
            rot = np.zeros(9)
            mujoco.mju_quat2Mat(rot, data.qpos[3:7])
            world_rate = (rot.reshape(3, 3) @ data.qvel[3:6])[2]  # free joint: body-frame rates
            assert odom.angular[2] == pytest.approx(world_rate, abs=1e-9)
        mujoco.mj_step(model, data)
    assert len(samples) == 50  # one second at 50 Hz; the first at 20 ms
    assert [s.stamp_ns for s in samples[:3]] == [20_000_000, 40_000_000, 60_000_000]
    msg = samples[-1].to_msg()
    assert msg.header.frame_id == "odom"
    assert msg.child_frame_id == "base_footprint"
    assert msg.pose.covariance[0] == 1e-5
    assert msg.pose.covariance[35] == 1e-3
    assert msg.pose.covariance[14] == 1e12
    tf = samples[-1].to_transform()
    assert tf.transform.translation.x == samples[-1].position[0]


def test_encoder_odometry_tracks_ground_truth() -> None:
    model, data, config = _car(odometry_source="encoder", max_wheel_acceleration=1.0)
    controller = DiffDriveController(model, config, base_body="base_footprint")
    pairs = []
    for k in range(2000):
        controller.set_command(*((0.4, 0.3) if k < 1000 else (0.3, -0.4)))
        odom = controller.step(data, k * DT_NS)
        if odom is not None:
            pairs.append((odom, data.qpos[:7].copy(), data.qvel[:6].copy()))
        mujoco.mj_step(model, data)
    odom, qpos, qvel = pairs[-1]
    travelled = 0.4 * 2 + 0.3 * 2
    error = np.hypot(odom.position[0] - qpos[0], odom.position[1] - qpos[1])
    assert error < 0.05 * travelled  # wheel slip while turning, nothing more
    assert odom.yaw == pytest.approx(_yaw(qpos[3:7]), abs=0.08)
    assert odom.linear[0] == pytest.approx(np.hypot(*qvel[:2]), abs=0.02)
    assert odom.angular[2] == pytest.approx(qvel[5], abs=0.05)
    assert odom.frame_id == "odom"


def test_encoder_odometry_integrates_arcs_exactly() -> None:
    odo = EncoderOdometry(wheel_separation=0.5, wheel_radius=0.1)
    odo.reset(0.0, 0.0)
    # a quarter circle of radius 1 m: left rim 0.75 * pi / 2, right rim 1.25 * pi / 2
    steps = 1000
    for i in range(1, steps + 1):
        left = 0.75 * math.pi / 2 * i / steps / 0.1
        right = 1.25 * math.pi / 2 * i / steps / 0.1
        odo.update(left, right, 0.001)
    assert odo.theta == pytest.approx(math.pi / 2)
    assert odo.x == pytest.approx(1.0, abs=1e-6)
    assert odo.y == pytest.approx(1.0, abs=1e-6)
    assert odo.v == pytest.approx(math.pi / 2 / 1.0, rel=1e-6)  # 1 m radius, pi/2 in 1 s


def test_diff_drive_bad_configuration() -> None:
    model, _, config = _car()
    with pytest.raises(DiffDriveError, match="joint 'car/left_wheel_joint' is not in"):
        DiffDriveController(model, config, base_body="base_footprint", prefix="car/")
    with pytest.raises(DiffDriveError, match="base body 'nope'"):
        DiffDriveController(model, config, base_body="nope")
    bad = DiffDriveConfig(left_joints=("left_wheel_joint",), right_joints=())
    with pytest.raises(DiffDriveError, match="as many left as right"):
        DiffDriveController(model, bad, base_body="base_footprint")
    negative = DiffDriveConfig(
        left_joints=("left_wheel_joint",), right_joints=("right_wheel_joint",), wheel_diameter=(-1,)
    )
    with pytest.raises(DiffDriveError, match="wheel_diameter"):
        DiffDriveController(model, negative, base_body="base_footprint")


# ----------------------------------------------------------------------------- quadrotor


def _quad(
    params: QuadrotorParams | None = None,
    seed: int = 0,
    pos: tuple[float, float, float] = (0, 0, 1),
) -> tuple[mujoco.MjModel, mujoco.MjData, QuadrotorController]:
    spec = mujoco.MjSpec()
    spec.option.timestep = DT_NS * 1e-9
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[30, 30, 1])
    body = add_quadrotor(spec, pos=pos)
    model = spec.compile()
    return (
        model,
        mujoco.MjData(model),
        QuadrotorController(model, body=body, params=params, seed=seed),
    )


def _fly(
    model: mujoco.MjModel, data: mujoco.MjData, controller: QuadrotorController, seconds: float
) -> np.ndarray:
    out = []
    for _ in range(round(seconds / (DT_NS * 1e-9))):
        controller.step(data)
        mujoco.mj_step(model, data)
        out.append(data.qpos[:3].copy())
    return np.array(out)


def test_quadrotor_mass_and_inertia_from_the_model() -> None:
    _, _, controller = _quad()
    assert controller.mass == pytest.approx(0.98)
    np.testing.assert_allclose(np.diag(controller.inertia), [0.0025, 0.0025, 0.0043])
    # a child body shifts the centre of mass: parallel-axis theorem
    spec = mujoco.MjSpec()
    body = add_quadrotor(spec)
    child = spec.body(body).add_body(name="payload", pos=[0.2, 0, 0])
    child.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01, 0, 0], mass=0.02)
    model = spec.compile()
    heavy = QuadrotorController(model, body=body)
    assert heavy.mass == pytest.approx(1.0)
    offset_q, offset_p = 0.2 * 0.02 / 1.0, 0.2 * 0.98 / 1.0  # distances to the new COM
    point = 0.4 * 0.02 * 0.01**2
    expected_zz = 0.0043 + 0.98 * offset_q**2 + point + 0.02 * offset_p**2
    assert heavy.inertia[2, 2] == pytest.approx(expected_zz, rel=1e-6)


def test_quadrotor_hover_holds_altitude() -> None:
    model, data, controller = _quad()
    controller.set_command(PositionCommand.hold((0.0, 0.0, 1.0)))
    path = _fly(model, data, controller, 3.0)
    assert np.abs(path[:, 2] - 1.0).max() < 0.005
    assert np.abs(path[:, :2]).max() < 1e-6
    assert controller.last_output is not None
    assert controller.last_output.thrust == pytest.approx(0.98 * 9.81, rel=1e-3)


@pytest.mark.parametrize("motor_time_constant", [0.0, 0.02])
def test_quadrotor_step_settles_without_large_overshoot(motor_time_constant: float) -> None:
    model, data, controller = _quad(QuadrotorParams(motor_time_constant=motor_time_constant))
    controller.set_command(PositionCommand.hold((2.0, 0.0, 1.0)))
    path = _fly(model, data, controller, 4.0)
    overshoot = (path[:, 0].max() - 2.0) / 2.0
    assert overshoot < 0.2
    assert np.abs(path[-500:, 0] - 2.0).max() < 0.05  # settled over the last second
    assert np.abs(path[:, 2] - 1.0).max() < 0.1  # altitude held while tilting


def test_quadrotor_tracks_a_circle() -> None:
    model, data, controller = _quad(QuadrotorParams(motor_time_constant=0.02))
    radius, rate = 1.5, 1.0
    errors = []
    for k in range(2500):
        t = k * DT_NS * 1e-9
        c, s = math.cos(rate * t), math.sin(rate * t)
        command = PositionCommand(
            position=(radius * c - radius, radius * s, 1.0),
            velocity=(-radius * rate * s, radius * rate * c, 0.0),
            acceleration=(-radius * rate**2 * c, -radius * rate**2 * s, 0.0),
            yaw=rate * t,
            yaw_dot=rate,
        )
        controller.set_command(command)
        controller.step(data)
        mujoco.mj_step(model, data)
        if t > 2.0:
            errors.append(np.linalg.norm(data.qpos[:3] - np.asarray(command.position)))
            heading = _yaw(data.qpos[3:7])
            assert abs(math.remainder(heading - rate * (t + DT_NS * 1e-9), 2 * math.pi)) < 0.05
    assert max(errors) < 0.05


def test_quadrotor_is_deterministic_for_a_seed() -> None:
    params = QuadrotorParams(disturbance_std=0.5, motor_time_constant=0.02)
    runs = []
    for seed in (7, 7, 8):
        model, data, controller = _quad(params, seed=seed)
        controller.set_command(PositionCommand.hold((1.0, -1.0, 1.5), yaw=0.5))
        runs.append(_fly(model, data, controller, 1.0))
    assert np.array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])
    assert np.abs(runs[0][-1] - [1.0, -1.0, 1.5]).max() < 0.3


def test_quadrotor_limits_thrust_moments_and_tilt() -> None:
    params = QuadrotorParams(max_thrust=15.0, max_moment=(0.2, 0.2, 0.05), max_tilt=0.3)
    model, data, controller = _quad(params)
    controller.set_command(PositionCommand.hold((30.0, 0.0, 10.0), yaw=2.0))
    for _ in range(300):
        out = controller.step(data)
        assert out is not None
        assert 0.0 <= out.thrust <= 15.0
        assert (np.abs(out.moments) <= np.array([0.2, 0.2, 0.05]) + 1e-12).all()
        tilt = math.acos(out.force[2] / np.linalg.norm(out.force))
        assert tilt <= 0.3 + 1e-9
        mujoco.mj_step(model, data)


def test_quadrotor_velocity_only_command_and_gain_override() -> None:
    model, data, controller = _quad()
    nan3 = (math.nan, math.nan, math.nan)
    controller.set_command(
        PositionCommand(position=nan3, velocity=(1.0, 0.0, 0.0), acceleration=nan3)
    )
    _fly(model, data, controller, 2.5)
    np.testing.assert_allclose(data.qvel[:3], [1.0, 0.0, 0.0], atol=0.02)
    # so3_control-style force gains equal to mass x the normalised ones change nothing
    state = QuadrotorState(
        position=np.array([0.3, -0.2, 1.1]),
        velocity=np.array([0.1, 0.2, 0.0]),
        rotation=np.eye(3),
        angular_velocity=np.zeros(3),
    )
    gains = SO3Gains()
    kwargs = {"mass": 2.0, "inertia": np.diag([0.01, 0.01, 0.02]), "gains": gains}
    base = so3_control(state, PositionCommand(), params=QuadrotorParams(max_thrust=50), **kwargs)
    forced = so3_control(
        state,
        PositionCommand(kx=tuple(2.0 * k for k in gains.kx), kv=tuple(2.0 * k for k in gains.kv)),  # type: ignore[arg-type]
        params=QuadrotorParams(max_thrust=50),
        **kwargs,
    )
    np.testing.assert_allclose(forced.force, base.force)


@settings(max_examples=30, deadline=None)
@given(
    yaw=st.floats(-math.pi, math.pi),
    yaw_error=st.floats(-1.0, 1.0),
    acc=st.tuples(*[st.floats(-3.0, 3.0)] * 3),
)
def test_so3_control_on_reference_and_yaw_error_sign(
    yaw: float, yaw_error: float, acc: tuple[float, float, float]
) -> None:
    params = QuadrotorParams(max_thrust=100.0, max_moment=(10.0, 10.0, 10.0), max_tilt=1.5)
    inertia = np.diag([0.0025, 0.0025, 0.0043])
    command = PositionCommand(position=(1.0, 2.0, 3.0), acceleration=acc, yaw=yaw)
    # on the reference, with the attitude the controller wants: thrust m |a + g|, no moments
    first = so3_control(
        QuadrotorState(np.array([1.0, 2.0, 3.0]), np.zeros(3), np.eye(3), np.zeros(3)),
        command,
        mass=1.0,
        inertia=inertia,
        gains=SO3Gains(),
        params=params,
    )
    aligned = QuadrotorState(
        np.array([1.0, 2.0, 3.0]), np.zeros(3), first.desired_rotation, np.zeros(3)
    )
    out = so3_control(aligned, command, mass=1.0, inertia=inertia, gains=SO3Gains(), params=params)
    expected = np.linalg.norm(np.asarray(acc) + np.array([0.0, 0.0, 9.81]))
    assert out.thrust == pytest.approx(expected, rel=1e-9)
    np.testing.assert_allclose(out.moments, 0.0, atol=1e-9)
    # level, with the heading behind the command by yaw_error: the yaw moment turns towards it
    c, s = math.cos(yaw - yaw_error), math.sin(yaw - yaw_error)
    level = QuadrotorState(
        np.array([1.0, 2.0, 3.0]),
        np.zeros(3),
        np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]),
        np.zeros(3),
    )
    hover = PositionCommand(position=(1.0, 2.0, 3.0), yaw=yaw)
    turn = so3_control(level, hover, mass=1.0, inertia=inertia, gains=SO3Gains(), params=params)
    if abs(yaw_error) > 1e-3:
        assert math.copysign(1.0, turn.moments[2]) == math.copysign(1.0, yaw_error)


def test_quadrotor_bad_input() -> None:
    spec = mujoco.MjSpec()
    spec.worldbody.add_body(name="fixed").add_geom(size=[0.1, 0, 0])
    model = spec.compile()
    with pytest.raises(QuadrotorError, match="free joint"):
        QuadrotorController(model, body="fixed")
    with pytest.raises(QuadrotorError, match="'nope' is not in"):
        QuadrotorController(model, body="nope")
    with pytest.raises(QuadrotorParamsError, match="max_tilt"):
        QuadrotorParams(max_tilt=2.0)
    parsed = QuadrotorParams.from_plugin_params({"max_thrust": "20", "max_moment": "1 1 0.2"})
    assert parsed.max_thrust == 20.0
    assert parsed.max_moment == (1.0, 1.0, 0.2)
    with pytest.raises(QuadrotorParamsError, match="unknown parameter <thrust>"):
        QuadrotorParams.from_plugin_params({"thrust": "1"})
    with pytest.raises(QuadrotorParamsError, match="needs 3 number"):
        QuadrotorParams.from_plugin_params({"max_moment": "1"})


# ----------------------------------------------------------------------------- robot files


def _path(name: str) -> str:
    return str(car_description_path() if name.startswith("car") else quadrotor_description_path())


def _robot(name: str, **args: str) -> yourdfpy.URDF:
    xml = xacro.process_file(_path(name), mappings=args).toxml()
    return yourdfpy.URDF.load(io.StringIO(xml), load_meshes=False, build_scene_graph=True)


def _gazebo_blocks(name: str, **args: str) -> list:
    doc = xacro.process_file(_path(name), mappings=args)
    return list(doc.getElementsByTagName("gazebo"))


def _text(element: object, tag: str) -> str:
    nodes = element.getElementsByTagName(tag)  # type: ignore[attr-defined]
    return str(nodes[0].firstChild.data).strip()


OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def test_car_description() -> None:
    car = _robot("car.urdf.xacro")
    assert car.base_link == "base_footprint"
    for frame in (
        "base_link",
        "left_wheel",
        "right_wheel",
        "caster_link",
        "camera_link",
        "camera_optical_frame",
        "depth_camera_link",
        "depth_camera_optical_frame",
    ):
        assert frame in car.link_map, frame  # fmt: skip
    for optical, body in (
        ("camera_optical_frame", "camera_link"),
        ("depth_camera_optical_frame", "depth_camera_link"),
    ):
        np.testing.assert_allclose(car.get_transform(optical, body)[:3, :3], OPTICAL, atol=1e-6)
    left = car.get_transform("left_wheel", "base_footprint")[:3, 3]
    right = car.get_transform("right_wheel", "base_footprint")[:3, 3]
    assert car.joint_map["left_wheel_joint"].type == "continuous"
    wheel = car.link_map["left_wheel"].collisions[0].geometry.cylinder
    # the caster touches the ground with the wheels
    caster = car.get_transform("caster_link", "base_footprint")[2, 3]
    assert caster == pytest.approx(car.link_map["caster_link"].collisions[0].geometry.sphere.radius)
    assert left[2] == pytest.approx(wheel.radius)

    blocks = _gazebo_blocks("car.urdf.xacro")
    sensors = {s.getAttribute("name"): s for b in blocks for s in b.getElementsByTagName("sensor")}
    assert sensors["camera"].getAttribute("type") == "camera"
    assert _text(sensors["camera"], "update_rate") == "30"
    assert _text(sensors["depth_camera"], "update_rate") == "20"
    for sensor in sensors.values():
        assert (_text(sensor, "width"), _text(sensor, "height")) == ("640", "480")
    assert _text(sensors["camera"], "frame_name") == "camera_optical_frame"
    assert _text(sensors["depth_camera"], "frame_name") == "depth_camera_optical_frame"
    plugins = {
        p.getAttribute("filename"): p for b in blocks for p in b.getElementsByTagName("plugin")
    }
    p3d = plugins["libgazebo_ros_p3d.so"]
    assert _text(p3d, "remapping") == "odom:=ground_truth/odom"
    assert _text(p3d, "update_rate") == "50"
    drive = plugins["libgazebo_ros_diff_drive.so"]
    # wheel encoders use the calibrated effective track: joint separation + wheel width
    width = 0.04
    assert float(_text(drive, "wheel_separation")) == pytest.approx(
        np.linalg.norm(left - right) + width
    )
    assert float(_text(drive, "wheel_diameter")) == pytest.approx(2 * wheel.radius)
    assert _text(drive, "odometry_source") == "0"  # wheel encoders (with noise) by default
    ideal = _gazebo_blocks("car.urdf.xacro", ideal_sensors="true")
    drives = [p for b in ideal for p in b.getElementsByTagName("plugin")]
    assert any(p.getElementsByTagName("odometry_source") and _text(p, "odometry_source") == "1"
               for p in drives)  # fmt: skip
    ideal_drive = next(p for p in drives if p.getElementsByTagName("odometry_source"))
    assert float(_text(ideal_drive, "wheel_separation")) == pytest.approx(
        np.linalg.norm(left - right)
    )


def test_quadrotor_description() -> None:
    quad = _robot("quadrotor.urdf.xacro")
    assert quad.base_link == "base_link"
    mass = sum(link.inertial.mass for link in quad.link_map.values() if link.inertial is not None)
    assert mass == pytest.approx(1.0)
    np.testing.assert_allclose(
        quad.get_transform("depth_camera_optical_frame", "depth_camera_link")[:3, :3],
        OPTICAL,
        atol=1e-6,
    )
    forward = quad.get_transform("depth_camera_optical_frame", "base_link")[:3, 2]
    np.testing.assert_allclose(forward, [1.0, 0.0, 0.0], atol=1e-6)  # the camera looks ahead
    blocks = _gazebo_blocks("quadrotor.urdf.xacro")
    sensors = [s for b in blocks for s in b.getElementsByTagName("sensor")]
    assert [s.getAttribute("type") for s in sensors] == ["depth"]
    assert _text(sensors[0], "update_rate") == "20"
    plugins = {
        p.getAttribute("filename"): p for b in blocks for p in b.getElementsByTagName("plugin")
    }
    assert _text(plugins["libgazebo_ros_p3d.so"], "body_name") == "base_link"
    quad_plugin = plugins["libvisnav_quadrotor.so"]
    params = {
        child.tagName: str(child.firstChild.data)
        for child in quad_plugin.childNodes
        if child.nodeType == child.ELEMENT_NODE
    }
    assert QuadrotorParams.from_plugin_params(params).max_thrust > 2 * 9.81 * mass
