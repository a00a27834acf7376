"""Sensor error models: wheel-encoder drift, depth disparity noise, their tags and the car."""

from __future__ import annotations

import contextlib
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import replace

import mujoco
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.description.gazebo import CameraSpec, default_principal_point, parse_gazebo_extensions
from visnav.description.noise_specs import DepthNoise, WheelOdometryNoise
from visnav.description.rigid import R_SENSOR_MJCAM, matrix_to_quat_wxyz
from visnav.description.robot import load_robot
from visnav.description.robots import resolve_robot
from visnav.description.urdf import parse_urdf
from visnav.errors import VisnavError
from visnav.sim.camera import CameraSensor, configure_mujoco_camera
from visnav.sim.noise_models import WheelEncoderModel, apply_depth_noise, noisy_depth_in_range
from visnav.sim.vehicles.diff_drive import EncoderOdometry

SEPARATION = 0.36
RADIUS = 0.08
KINECT = DepthNoise(disparity_stddev=0.07, disparity_step=0.125)


def _car_noise() -> WheelOdometryNoise:
    """The built-in car's wheel error model (from its Xacro, so the test follows it)."""
    return resolve_robot("car").gazebo.diff_drives[0].odometry_noise


def _scripted_drive(noise: WheelOdometryNoise | None, seed: int) -> tuple[float, float, float]:
    """Drive 60 m of straights and 90-degree turns; return (position error m, heading error
    rad, distance m) of the encoder odometry against the exact kinematics."""
    model = WheelEncoderModel(noise, seed=seed) if noise is not None else None
    odo = EncoderOdometry(SEPARATION, RADIUS, model=model)
    true = EncoderOdometry(SEPARATION, RADIUS)
    left = right = 0.0
    odo.update(left, right, 0.0)
    true.update(left, right, 0.0)
    dt = 0.02
    distance = 0.0
    segments = [(0.5, 0.0, 10.0), (0.0, 0.5, math.pi)] * 6  # 5 m straight, 90 deg turn in place
    for v, w, duration in segments:
        for _ in range(round(duration / dt)):
            left += (v - w * SEPARATION / 2) * dt / RADIUS
            right += (v + w * SEPARATION / 2) * dt / RADIUS
            odo.update(left, right, dt)
            true.update(left, right, dt)
            distance += abs(v) * dt
    heading = math.remainder(odo.theta - true.theta, 2 * math.pi)
    return math.hypot(odo.x - true.x, odo.y - true.y), heading, distance


def test_exact_encoders_do_not_drift() -> None:
    error, heading, _ = _scripted_drive(None, 0)
    assert error < 1e-9
    assert abs(heading) < 1e-9


def test_car_wheel_odometry_drifts_like_real_wheels() -> None:
    noise = _car_noise()
    assert noise.active
    runs = [_scripted_drive(noise, seed) for seed in range(20)]
    errors = np.array([r[0] / r[2] for r in runs])  # fraction of the distance driven
    headings = np.degrees(np.abs([r[1] for r in runs]))
    assert np.median(errors) >= 0.01, errors
    assert np.median(headings) >= 3.0, headings
    assert np.median(errors) < 0.2  # realistic, not absurd
    assert np.median(headings) < 45.0


def test_wheel_drift_is_seeded() -> None:
    noise = _car_noise()
    assert _scripted_drive(noise, 3) == _scripted_drive(noise, 3)
    assert _scripted_drive(noise, 3) != _scripted_drive(noise, 4)


def test_systematic_errors_are_drawn_once_with_the_configured_spread() -> None:
    noise = WheelOdometryNoise(wheel_radius_error=0.01, wheel_separation_error=0.02)
    models = [WheelEncoderModel(noise, seed=s) for s in range(400)]
    radius = np.array([m.radius_factor for m in models]).ravel() - 1.0
    separation = np.array([m.separation_factor for m in models]) - 1.0
    assert np.std(radius) == pytest.approx(0.01, rel=0.1)
    assert np.std(separation) == pytest.approx(0.02, rel=0.1)
    model = models[0]
    assert model.travel(0, 1.0, 0.1) == model.travel(0, 1.0, 0.1)  # no slip: deterministic


def test_slip_variance_grows_with_distance_not_with_update_rate() -> None:
    noise = WheelOdometryNoise(wheel_slip=0.01)
    finals = {}
    for steps in (10, 1000):
        totals = []
        for seed in range(300):
            model = WheelEncoderModel(noise, seed=seed)
            totals.append(sum(model.travel(0, 4.0 / steps / 0.1, 0.1) for _ in range(steps)))
        finals[steps] = np.std(np.array(totals) - 4.0)
    # 4 m rolled: std = 0.01 * sqrt(4) = 2 cm, whatever the number of updates
    assert finals[10] == pytest.approx(0.02, rel=0.15)
    assert finals[1000] == pytest.approx(0.02, rel=0.15)


def test_encoder_quantises_angles_to_ticks() -> None:
    model = WheelEncoderModel(WheelOdometryNoise(encoder_resolution=4), seed=0)
    assert model.read(0.1) == 0.0
    assert model.read(math.pi / 2 + 0.01) == pytest.approx(math.pi / 2)
    assert model.read(-0.1) == pytest.approx(-math.pi / 2)


# --------------------------------------------------------------------------- depth


def test_depth_noise_std_grows_with_the_square_of_range() -> None:
    rng = np.random.default_rng(1)
    for z in (1.0, 2.0, 3.0, 5.0):
        depth = np.full((200, 200), z, dtype=np.float32)
        apply_depth_noise(depth, KINECT, rng)
        sigma = float(KINECT.sigma(z))
        assert np.std(depth) == pytest.approx(sigma, rel=0.1), z
        assert abs(float(np.mean(depth)) - z) < 0.2 * sigma + 1e-4
    # Khoshelham & Elberink (2012): about 1.5 mm at 1 m and 4 cm at 5 m for the Kinect v1
    assert float(KINECT.sigma(1.0)) == pytest.approx(0.0018, abs=0.0006)
    assert float(KINECT.sigma(5.0)) == pytest.approx(0.045, abs=0.01)


def test_depth_quantisation_steps_follow_disparity() -> None:
    step_only = DepthNoise(disparity_step=0.125)
    depth = np.linspace(2.9, 3.1, 1000, dtype=np.float32)
    apply_depth_noise(depth, step_only, np.random.default_rng(0))
    levels = np.unique(depth)
    fb = 580 * 0.075
    expected_step = 3.0**2 / fb * 0.125  # about 2.6 cm at 3 m
    assert np.median(np.diff(levels)) == pytest.approx(expected_step, rel=0.1)


def test_depth_noise_keeps_invalid_pixels_and_is_seeded() -> None:
    base = np.array([[1.0, np.nan], [0.0, 4.0]], dtype=np.float32)
    a, b, c = base.copy(), base.copy(), base.copy()
    apply_depth_noise(a, KINECT, np.random.default_rng(5))
    apply_depth_noise(b, KINECT, np.random.default_rng(5))
    apply_depth_noise(c, KINECT, np.random.default_rng(6))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.isnan(a[0, 1])
    assert a[1, 0] == 0.0
    off = DepthNoise()
    d = base.copy()
    apply_depth_noise(d, off, np.random.default_rng(5))
    np.testing.assert_array_equal(d, base)


@pytest.fixture
def sensors(mujoco_gl: str) -> Iterator[list[CameraSensor]]:
    del mujoco_gl
    made: list[CameraSensor] = []
    yield made
    for sensor in made:
        sensor.close()


def _wall(spec: CameraSpec) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The camera at the origin facing a wall 3 m ahead."""
    mj = mujoco.MjSpec()
    body = mj.worldbody.add_body(name="cam_link")
    cam = body.add_camera(name="cam")
    cam.quat = list(matrix_to_quat_wxyz(R_SENSOR_MJCAM))
    configure_mujoco_camera(cam, spec)
    mj.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 9, 9], pos=[3.1, 0, 0])
    model = mj.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def test_depth_camera_applies_the_model_seeded(sensors: list[CameraSensor]) -> None:
    width, height, hfov = 64, 48, 1.2
    focal = width / (2 * math.tan(hfov / 2))
    cx, cy = default_principal_point(width, height)
    spec = CameraSpec(
        name="cam", link="cam_link", kind="depth", width=width, height=height, hfov=hfov,
        fx=focal, fy=focal, cx=cx, cy=cy, frame_id="cam_optical", clip_near=0.05,
        clip_far=20.0, depth_topic="/d", depth_info_topic="/i", points_topic="/p",
        depth_noise=replace(KINECT, disparity_step=0.0),
    )  # fmt: skip
    model, data = _wall(spec)
    frames = []
    for seed in (11, 11, 12):
        sensor = CameraSensor(model, spec, camera="cam", seed=seed, render_color=False)
        sensors.append(sensor)
        frame = sensor.render(data)
        assert frame.depth is not None
        frames.append(frame.depth)
    np.testing.assert_array_equal(frames[0], frames[1])
    assert not np.array_equal(frames[0], frames[2])
    sigma = float(KINECT.sigma(3.0) * 0.07 / math.hypot(0.07, 0.125 / math.sqrt(12)))
    assert np.nanstd(frames[0]) == pytest.approx(sigma, rel=0.15)
    assert np.nanmean(frames[0]) == pytest.approx(3.0, abs=0.005)


# --------------------------------------------------------------------------- tags


def test_car_description_carries_the_noise_and_ideal_sensors_removes_it() -> None:
    noisy = resolve_robot("car").gazebo
    drive = noisy.diff_drives[0]
    assert drive.odometry_source == "encoder"
    assert drive.odometry_noise == WheelOdometryNoise(
        wheel_radius_error=0.003, wheel_separation_error=0.01, wheel_slip=0.005,
        encoder_resolution=4096,
    )  # fmt: skip
    cameras = {c.name: c for c in noisy.cameras}
    assert cameras["camera"].noise.stddev == 0.007
    assert cameras["camera"].noise.mean == 0.0
    assert cameras["depth_camera"].depth_noise == KINECT
    ideal = resolve_robot("car", args={"ideal_sensors": "true"}).gazebo
    assert ideal.diff_drives[0].odometry_source == "world"
    assert not ideal.diff_drives[0].odometry_noise.active
    assert not any(c.noise.active or c.depth_noise.active for c in ideal.cameras)


_ROBOT = """<robot name="r">
  <link name="base"/>
  <link name="l"/><link name="rw"/>
  <joint name="lj" type="continuous"><parent link="base"/><child link="l"/></joint>
  <joint name="rj" type="continuous"><parent link="base"/><child link="rw"/></joint>
  <gazebo><plugin name="dd" filename="libgazebo_ros_diff_drive.so">
    <left_joint>lj</left_joint><right_joint>rj</right_joint>
    <publish_odom>true</publish_odom>{drive}
  </plugin></gazebo>
  <gazebo reference="base"><sensor type="depth" name="d"><camera>
    <horizontal_fov>1.0</horizontal_fov><image><width>8</width><height>6</height></image>
  </camera><plugin name="dc" filename="libgazebo_ros_camera.so">{depth}</plugin></sensor></gazebo>
</robot>"""


def _parse(drive: str = "", depth: str = "") -> tuple[object, object]:
    urdf = parse_urdf(_ROBOT.format(drive=drive, depth=depth))
    gz = parse_gazebo_extensions(urdf)
    return gz.diff_drives[0], gz.cameras[0]


def test_wheel_and_depth_tags_are_parsed() -> None:
    drive, camera = _parse(
        "<odometry_source>0</odometry_source><wheel_slip>0.01</wheel_slip>"
        "<encoder_resolution>1024</encoder_resolution>",
        "<depth_noise><type>disparity</type><baseline>0.05</baseline>"
        "<disparity_stddev>0.1</disparity_stddev></depth_noise>",
    )
    assert drive.odometry_noise == WheelOdometryNoise(wheel_slip=0.01, encoder_resolution=1024)  # type: ignore[attr-defined]
    assert camera.depth_noise == DepthNoise(baseline=0.05, disparity_stddev=0.1)  # type: ignore[attr-defined]


def test_wheel_noise_on_world_odometry_is_ignored_with_a_warning() -> None:
    urdf = parse_urdf(_ROBOT.format(drive="<wheel_slip>0.01</wheel_slip>", depth=""))
    gz = parse_gazebo_extensions(urdf)
    assert not gz.diff_drives[0].odometry_noise.active


@pytest.mark.parametrize(
    ("drive", "depth", "match"),
    [
        ("<wheel_slip>-1</wheel_slip>", "", r"<wheel_slip> = -1 is out of range"),
        ("<encoder_resolution>10.5</encoder_resolution>", "", "not a whole number of ticks"),
        ("<wheel_radius_error>x</wheel_radius_error>", "", "is not a finite number"),
        ("", "<depth_noise><type>tof</type></depth_noise>", "'tof' is not a depth noise model"),
        ("", "<depth_noise><baseline>0</baseline></depth_noise>", r"<baseline> = 0 is out"),
    ],
)
def test_bad_noise_tags_are_one_line_errors(drive: str, depth: str, match: str) -> None:
    with pytest.raises(VisnavError, match=match) as info:
        _parse(drive, depth)
    assert "\n" not in str(info.value)


_TAGS = ("wheel_radius_error", "wheel_separation_error", "wheel_slip", "encoder_resolution")
_DEPTH_TAGS = ("type", "baseline", "focal_length", "disparity_stddev", "disparity_step")
_TEXT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(str),
    st.integers(-(10**6), 10**6).map(str),
    st.text(alphabet=st.characters(blacklist_categories=("Cs", "Cc")), max_size=12),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.dictionaries(st.sampled_from(_TAGS), _TEXT, max_size=4),
    st.dictionaries(st.sampled_from(_DEPTH_TAGS), _TEXT, max_size=5),
)
def test_fuzz_noise_tags_raise_only_visnav_errors(
    drive: dict[str, str], depth: dict[str, str]
) -> None:
    def xml(tags: dict[str, str]) -> str:
        parts = []
        for tag, text in tags.items():
            element = ET.Element(tag)
            element.text = text
            parts.append(ET.tostring(element, encoding="unicode"))
        return "".join(parts)

    with contextlib.suppress(VisnavError):
        _parse(
            "<odometry_source>0</odometry_source>" + xml(drive),
            f"<depth_noise>{xml(depth)}</depth_noise>",
        )


def test_load_robot_with_noise_tags() -> None:
    desc = load_robot(
        _ROBOT.format(
            drive="<odometry_source>0</odometry_source><wheel_slip>0.02</wheel_slip>", depth=""
        )
    )
    assert desc.gazebo.diff_drives[0].odometry_noise.wheel_slip == 0.02


def _reference_noisy_depth(
    depth: np.ndarray, noise: DepthNoise, seed: int, lo: float, hi: float
) -> np.ndarray:
    """The numpy steps the camera used: range marked on the true depth, noise, NaN."""
    out = depth.copy()
    invalid = (out <= lo) | (out >= hi)
    apply_depth_noise(out, noise, np.random.default_rng(seed))
    out[invalid] = np.nan
    return out


@pytest.mark.parametrize(
    "noise",
    [
        KINECT,
        DepthNoise(disparity_stddev=0.3),
        DepthNoise(disparity_step=0.125),
        DepthNoise(baseline=0.05, focal_length=400.0, disparity_stddev=0.5, disparity_step=0.25),
        DepthNoise(),  # inactive: the range check only
    ],
)
def test_fused_depth_noise_is_the_numpy_steps_bit_for_bit(noise: DepthNoise) -> None:
    rng = np.random.default_rng(11)
    depth = rng.uniform(-1.0, 14.0, (48, 64)).astype(np.float32)
    specials = [np.nan, np.inf, -np.inf, 0.0, 0.1, 10.0, 1e-30, 500.0]
    depth.reshape(-1)[: len(specials)] = specials
    lo, hi = 0.1, 10.0
    want = _reference_noisy_depth(depth, noise, 5, lo, hi)
    got = depth.copy()
    noisy_depth_in_range(got, noise, np.random.default_rng(5), (lo, hi))
    np.testing.assert_array_equal(got, want)  # NaN where NaN, every other float equal
    assert np.isnan(got).any()
    changed = np.isfinite(depth) & (depth > lo) & (depth < hi) & (got != depth)
    assert changed.any() == noise.active


@settings(max_examples=30, deadline=None)
@given(
    values=st.lists(st.floats(width=32, allow_nan=True, allow_infinity=True), min_size=1),
    seed=st.integers(0, 2**32 - 1),
)
def test_fused_depth_noise_matches_on_any_floats(values: list[float], seed: int) -> None:
    depth = np.asarray(values, dtype=np.float32)
    want = _reference_noisy_depth(depth, KINECT, seed, 0.1, 10.0)
    got = depth.copy()
    noisy_depth_in_range(got, KINECT, np.random.default_rng(seed), (0.1, 10.0))
    np.testing.assert_array_equal(got, want)
