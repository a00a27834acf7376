"""Camera rendering agrees with the published calibration, depth with exact ray casts."""

from __future__ import annotations

import ctypes.util
import math
import os
from collections.abc import Callable, Iterator
from dataclasses import replace

import cv2
import mujoco
import numpy as np
import pytest

from visnav.description.gazebo import (
    CameraSpec,
    GaussianNoise,
    LensDistortion,
    default_principal_point,
)
from visnav.description.rigid import R_SENSOR_MJCAM, matrix_to_quat_wxyz
from visnav.msgs.image import image_to_numpy
from visnav.msgs.pointcloud import cloud_to_structured, cloud_to_xyz
from visnav.msgs.time import time_to_ns
from visnav.sim import camera as camera_module
from visnav.sim.camera import (
    CameraSensor,
    RenderContext,
    RenderingUnavailableError,
    camera_info,
    configure_mujoco_camera,
    distort_normalized,
    render_layout,
    select_gl_backend,
    undistort_normalized,
)
from visnav.sim.errors import CameraSensorError

W, H = 64, 48


def make_spec(**kw: object) -> CameraSpec:
    width = int(kw.pop("width", W))  # type: ignore[call-overload]
    height = int(kw.pop("height", H))  # type: ignore[call-overload]
    hfov = float(kw.pop("hfov", 1.2))  # type: ignore[arg-type]
    focal = width / (2 * math.tan(hfov / 2))
    cx, cy = default_principal_point(width, height)
    base = {
        "name": "cam",
        "link": "cam_link",
        "kind": "camera",
        "width": width,
        "height": height,
        "hfov": hfov,
        "fx": focal,
        "fy": focal,
        "cx": cx,
        "cy": cy,
        "frame_id": "cam_optical",
        "image_topic": "/cam/image_raw",
        "camera_info_topic": "/cam/camera_info",
        "clip_near": 0.05,
        "clip_far": 20.0,
    }
    base.update(kw)
    return CameraSpec(**base)  # type: ignore[arg-type]


def build_scene(
    spec: CameraSpec, add_objects: Callable[[mujoco.MjSpec], None]
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Camera link at the origin (x forward, y left, z up) plus objects; flat lighting."""
    mj = mujoco.MjSpec()
    mj.visual.headlight.ambient = [1.0, 1.0, 1.0]
    mj.visual.headlight.diffuse = [0.0, 0.0, 0.0]
    mj.visual.headlight.specular = [0.0, 0.0, 0.0]
    body = mj.worldbody.add_body(name="cam_link")
    cam = body.add_camera(name="cam")
    cam.quat = list(matrix_to_quat_wxyz(R_SENSOR_MJCAM))
    configure_mujoco_camera(cam, spec)
    add_objects(mj)
    model = mj.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def project(spec: CameraSpec, points: np.ndarray) -> np.ndarray:
    """Project link-frame points (x forward) with the published K and D (OpenCV)."""
    optical = np.stack([-points[:, 1], -points[:, 2], points[:, 0]], axis=1)
    k = np.array(spec.k()).reshape(3, 3)
    d = np.array(spec.distortion.d)
    uv, _ = cv2.projectPoints(optical.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), k, d)
    return uv.reshape(-1, 2)


@pytest.fixture
def sensors(mujoco_gl: str) -> Iterator[list[CameraSensor]]:
    del mujoco_gl
    made: list[CameraSensor] = []
    yield made
    for sensor in made:
        sensor.close()


def sphere_centroids(color: np.ndarray, count: int) -> np.ndarray:
    red = (color[..., 0] > 128) & (color[..., 1] < 100) & (color[..., 2] < 100)
    n, _, _, centroids = cv2.connectedComponentsWithStats(red.astype(np.uint8))
    assert n - 1 == count, f"expected {count} blobs, found {n - 1}"
    return centroids[1:]


SPHERES = np.array(
    [
        [3.0, 0.0, 0.0],
        [3.0, 0.9, 0.6],
        [3.0, -1.1, -0.5],
        [2.5, 0.9, -0.55],
        [2.5, -1.0, 0.6],
    ]
)


def add_spheres(mj: mujoco.MjSpec) -> None:
    for p in SPHERES:
        mj.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.06, 0, 0], pos=p.tolist(), rgba=[1, 0, 0, 1]
        )


def match(found: np.ndarray, expected: np.ndarray) -> np.ndarray:
    errors = []
    for e in expected:
        errors.append(np.min(np.linalg.norm(found - e, axis=1)))
    return np.array(errors)


# --------------------------------------------------------------------------- projection


@pytest.mark.parametrize(
    ("width", "height", "extra"),
    [
        (160, 120, {}),
        (161, 121, {}),
        (160, 120, {"cx": 70.25, "cy": 66.5}),
    ],
)
def test_projection_matches_rendering(
    sensors: list[CameraSensor], width: int, height: int, extra: dict[str, float]
) -> None:
    spec = make_spec(width=width, height=height, **extra)
    model, data = build_scene(spec, add_spheres)
    sensor = CameraSensor(model, spec, camera="cam")
    sensors.append(sensor)
    frame = sensor.render(data)
    assert frame.color is not None
    found = sphere_centroids(frame.color, len(SPHERES))
    expected = project(spec, SPHERES)
    errors = match(found, expected)
    assert errors.max() < 0.5, errors
    # The published principal point is width / 2 (issue 3) unless given explicitly.
    assert (spec.cx, spec.cy) == (
        extra.get("cx", width / 2),
        extra.get("cy", height / 2),
    )


def test_projection_with_lens_distortion(sensors: list[CameraSensor]) -> None:
    distortion = LensDistortion(k1=-0.25, k2=0.06, k3=0.0, p1=0.002, p2=-0.0015)
    spec = make_spec(width=160, height=120, distortion=distortion)
    model, data = build_scene(spec, add_spheres)
    sensor = CameraSensor(model, spec, camera="cam")
    sensors.append(sensor)
    assert sensor.layout.width > spec.width  # barrel distortion needs a wider canvas
    frame = sensor.render(data)
    assert frame.color is not None
    errors = match(sphere_centroids(frame.color, len(SPHERES)), project(spec, SPHERES))
    assert errors.max() < 0.5, errors
    assert tuple(frame.camera_info.d) == distortion.d


def test_undistort_inverts_distort() -> None:
    d = LensDistortion(k1=-0.3, k2=0.1, k3=-0.01, p1=0.003, p2=0.001)
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-0.6, 0.6, 500), rng.uniform(-0.45, 0.45, 500)
    xd, yd = distort_normalized(x, y, d)
    xu, yu, residual = undistort_normalized(xd, yd, d)
    assert residual < 1e-12
    np.testing.assert_allclose(xu, x, atol=1e-10)
    np.testing.assert_allclose(yu, y, atol=1e-10)
    pts = np.stack([x, y, np.ones_like(x)], axis=1)
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), np.eye(3), np.array(d.d))
    np.testing.assert_allclose(uv[:, 0, 0], xd, atol=1e-9)
    np.testing.assert_allclose(uv[:, 0, 1], yd, atol=1e-9)


def test_render_layout_without_distortion_is_the_image() -> None:
    spec = make_spec()
    layout = render_layout(spec)
    assert (layout.width, layout.height, layout.cx, layout.cy) == (W, H, spec.cx, spec.cy)
    assert layout.map_x is None


# --------------------------------------------------------------------------- depth


def add_depth_scene(mj: mujoco.MjSpec) -> None:
    wall = mj.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 4.0, 4.0], pos=[4.0, 0.0, 0.0]
    )
    wall.quat = list(matrix_to_quat_wxyz(cv2.Rodrigues(np.array([0.1, 0.0, 0.5]))[0]))
    mj.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.5, 0, 0], pos=[2.5, 0.3, 0.1])
    mj.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.3, 0.2, 0.25], pos=[2.0, -0.7, -0.3]
    )


def ray_depths(model: mujoco.MjModel, data: mujoco.MjData, spec: CameraSpec) -> np.ndarray:
    """Exact optical z of the first surface along each pixel's ray (NaN: no hit)."""
    k = np.array(spec.k()).reshape(3, 3)
    out = np.full((spec.height, spec.width), np.nan)
    geomid = np.zeros(1, dtype=np.int32)
    for v in range(spec.height):
        for u in range(spec.width):
            xn = (u - k[0, 2]) / k[0, 0]
            yn = (v - k[1, 2]) / k[1, 1]
            direction = np.array([1.0, -xn, -yn])
            dist = mujoco.mj_ray(model, data, np.zeros(3), direction, None, 1, -1, geomid)
            if dist >= 0:
                out[v, u] = dist  # direction has unit forward component: dist == z
    return out


def depth_spec(**kw: object) -> CameraSpec:
    base: dict[str, object] = {
        "kind": "depth",
        "depth_topic": "/cam/depth/image_raw",
        "depth_info_topic": "/cam/depth/camera_info",
        "points_topic": "/cam/points",
        "min_depth": 0.0,
    }
    base.update(kw)
    return make_spec(**base)


def test_depth_matches_ray_casts(sensors: list[CameraSensor]) -> None:
    spec = depth_spec(width=80, height=60)
    model, data = build_scene(spec, add_depth_scene)
    sensor = CameraSensor(model, spec, camera="cam", render_color=False)
    sensors.append(sensor)
    frame = sensor.render(data)
    assert frame.depth is not None
    assert frame.image is None
    truth = ray_depths(model, data, spec)
    both = np.isfinite(truth) & np.isfinite(frame.depth)
    assert both.mean() > 0.9
    err = np.abs(frame.depth[both] - truth[both])
    assert np.median(err) <= 1e-3, np.median(err)
    # Silhouette pixels may differ; the rest agree closely.
    assert np.percentile(err, 90) <= 2e-3


def test_depth_analytic_plane(sensors: list[CameraSensor]) -> None:
    spec = depth_spec()

    def plane(mj: mujoco.MjSpec) -> None:  # a wall facing the camera at x = 3.2
        mj.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 9, 9], pos=[3.3, 0, 0])

    model, data = build_scene(spec, plane)
    sensor = CameraSensor(model, spec, camera="cam", render_color=False)
    sensors.append(sensor)
    depth = sensor.render(data).depth
    assert depth is not None
    np.testing.assert_allclose(depth, 3.2, atol=1e-3)


def _log_passes(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, bool]]:
    """Record every render (segmentation flag) and read-back (colour, depth) of the sensor."""
    log: list[tuple[str, bool]] = []
    real_render, real_read = mujoco.mjr_render, mujoco.mjr_readPixels

    def render(rect: object, scene: mujoco.MjvScene, ctx: object) -> None:
        log.append(("render", bool(scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT])))
        real_render(rect, scene, ctx)

    def read(rgb: object, depth: object, rect: object, ctx: object) -> None:
        log.append(("read_rgb" if rgb is not None else "read_depth", depth is not None))
        real_read(rgb, depth, rect, ctx)

    monkeypatch.setattr(camera_module.mujoco, "mjr_render", render)
    monkeypatch.setattr(camera_module.mujoco, "mjr_readPixels", read)
    return log


def _depth_pass_only(
    model: mujoco.MjModel, data: mujoco.MjData, spec: CameraSpec, sensors: list[CameraSensor]
) -> np.ndarray:
    """Depth from the separate segmentation pass (a depth-only sensor of the same camera)."""
    sensor = CameraSensor(model, spec, camera="cam", render_color=False)
    sensors.append(sensor)
    depth = sensor.render(data).depth
    assert depth is not None
    assert sensor.depth_passes == 1
    return depth


def no_msaa(add: Callable[[mujoco.MjSpec], None]) -> Callable[[mujoco.MjSpec], None]:
    """``add`` in a model without multisampling (the simulator's default, msaa_samples=0)."""

    def build(mj: mujoco.MjSpec) -> None:
        mj.visual.quality.offsamples = 0
        add(mj)

    return build


def test_colour_and_depth_from_one_lit_pass(
    sensors: list[CameraSensor], monkeypatch: pytest.MonkeyPatch
) -> None:
    spec = depth_spec(width=80, height=60)
    model, data = build_scene(spec, no_msaa(add_depth_scene))
    separate = _depth_pass_only(model, data, spec, sensors)
    sensor = CameraSensor(model, spec, camera="cam")
    sensors.append(sensor)
    log = _log_passes(monkeypatch)
    frame = sensor.render(data)
    assert frame.image is not None
    assert frame.depth is not None
    # one lit render, colour and depth read back together; no segmentation pass
    assert log == [("render", False), ("read_rgb", True)]
    assert sensor.depth_passes == 0
    # the lit pass's depth is the segmentation pass's, bit for bit
    np.testing.assert_array_equal(frame.depth, separate)
    assert np.isfinite(frame.depth).mean() > 0.9
    assert not sensor._scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT]
    assert not sensor._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW]


def test_multisampling_takes_the_depth_pass(sensors: list[CameraSensor]) -> None:
    """Multisampled depth differs at silhouettes: MuJoCo's default 4 samples need the pass."""
    spec = depth_spec(width=80, height=60)
    model, data = build_scene(spec, add_depth_scene)
    assert model.vis.quality.offsamples == 4
    sensor = CameraSensor(model, spec, camera="cam")
    sensors.append(sensor)
    frame = sensor.render(data)
    assert frame.image is not None
    assert sensor.depth_passes == 1


def test_transparent_geom_takes_the_depth_pass(
    sensors: list[CameraSensor], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A half-transparent pane is drawn without depth in the lit pass: depth needs its pass."""
    spec = depth_spec(width=80, height=60)

    def pane(mj: mujoco.MjSpec) -> None:
        add_depth_scene(mj)
        mj.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.01, 0.4, 0.4], pos=[1.0, 0, 0],
            rgba=[0.2, 0.2, 0.9, 0.5],
        )  # fmt: skip

    model, data = build_scene(spec, no_msaa(pane))
    separate = _depth_pass_only(model, data, spec, sensors)
    sensor = CameraSensor(model, spec, camera="cam")
    sensors.append(sensor)
    log = _log_passes(monkeypatch)
    depth = sensor.render(data).depth
    assert depth is not None
    np.testing.assert_allclose(depth[30, 40], 0.99, atol=2e-3)  # the pane, not the sphere
    np.testing.assert_array_equal(depth, separate)
    assert log == [("render", False), ("read_rgb", False), ("render", True), ("read_depth", True)]
    assert sensor.depth_passes == 1


def test_skybox_takes_the_depth_pass(sensors: list[CameraSensor]) -> None:
    """The lit pass draws the skybox with depth (0.7 of the far clip): sky must stay invalid."""
    spec = depth_spec(width=80, height=60, clip_far=5.0)

    def sky(mj: mujoco.MjSpec) -> None:
        mj.add_texture(
            name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
            builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=32, height=32,
            rgb1=[0.4, 0.6, 0.8], rgb2=[0, 0, 0],
        )  # fmt: skip
        mj.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.5, 0.5], pos=[2.1, 0, 0])

    model, data = build_scene(spec, no_msaa(sky))
    sensor = CameraSensor(model, spec, camera="cam")
    sensors.append(sensor)
    frame = sensor.render(data)
    assert frame.depth is not None
    assert np.isnan(frame.depth[0:5, 0:5]).all()  # sky: no depth
    np.testing.assert_allclose(frame.depth[30, 40], 2.0, atol=2e-3)
    assert sensor.depth_passes == 1


def clip_scene(mj: mujoco.MjSpec) -> None:
    # Left half: a box 0.3 m away. Lower right: a wall 8 m away with a box 2 m away in
    # front of part of it. Upper right: nothing.
    mj.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.01, 1, 1], pos=[0.31, 1.0, 0])
    mj.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 9, 2], pos=[8.1, -9.0, -2])
    mj.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.3, 0.3], pos=[2.1, -0.6, -0.6]
    )


@pytest.mark.parametrize("encoding", ["32FC1", "16UC1"])
def test_depth_outside_clip_is_invalid(sensors: list[CameraSensor], encoding: str) -> None:
    spec = depth_spec(min_depth=0.5, clip_far=5.0, depth_encoding=encoding)
    model, data = build_scene(spec, clip_scene)
    sensor = CameraSensor(model, spec, camera="cam", render_color=False)
    sensors.append(sensor)
    frame = sensor.render(data, stamp_ns=42)
    assert frame.depth_image is not None
    assert frame.depth is not None
    raw = image_to_numpy(frame.depth_image)
    assert frame.depth_image.encoding == encoding
    left_near = (slice(10, 20), slice(2, 10))  # box at 0.3 m < min_depth 0.5
    right_low_far = (slice(30, 46), slice(56, 63))  # wall at 8 m > clip far 5
    right_low_mid = (slice(34, 43), slice(42, 50))  # box at 2 m: valid
    top_sky = (slice(0, 3), slice(40, 60))  # nothing: invalid
    invalid = 0 if encoding == "16UC1" else np.nan
    for region in (left_near, top_sky):
        np.testing.assert_array_equal(raw[region], invalid)
    assert np.isnan(frame.depth[left_near]).all()
    valid_mid = frame.depth[right_low_mid]
    np.testing.assert_allclose(valid_mid, 2.0, atol=2e-3)
    if encoding == "16UC1":
        assert raw.dtype == np.uint16
        np.testing.assert_array_equal(raw[right_low_mid], np.rint(valid_mid * 1000))
    far = raw[right_low_far]
    assert (far == 0).all() if encoding == "16UC1" else np.isnan(far).all()


def wide_clip_scene(mj: mujoco.MjSpec) -> None:
    # clip_scene in a world as large as a building (the far plane's depth is scaled by
    # the model's extent, and rounds below clip far in such a world)
    clip_scene(mj)
    mj.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.1], pos=[-30, 20, 0])


@pytest.mark.parametrize("far", [0.3, 0.45, 1.7])
@pytest.mark.parametrize("noisy", [False, True])
def test_a_far_clip_nearer_than_the_scene_gives_no_depth(
    sensors: list[CameraSensor], far: float, noisy: bool
) -> None:
    # every surface of clip_scene but the 0.31 m box is beyond these far clips: the
    # far plane is "no return" (NaN), never a depth of clip far, with or without noise
    from visnav.description.noise_specs import DepthNoise

    spec = depth_spec(clip_far=far, max_depth=far)
    if noisy:
        spec = replace(spec, depth_noise=DepthNoise(disparity_stddev=0.07, disparity_step=0.125))
    model, data = build_scene(spec, wide_clip_scene)
    sensor = CameraSensor(model, spec, camera="cam", render_color=False, seed=1)
    sensors.append(sensor)
    depth = sensor.render(data).depth
    assert depth is not None
    beyond = (slice(0, 3), slice(40, 60)), (slice(30, 46), slice(56, 63))  # sky, far wall
    for region in beyond:
        assert np.isnan(depth[region]).all(), np.unique(depth[region])[:5]
    if far > 0.31:  # the near box is within range
        assert np.isfinite(depth[10:20, 2:10]).mean() > 0.9


# --------------------------------------------------------------------------- messages


def test_messages_share_stamp_and_frame(sensors: list[CameraSensor]) -> None:
    spec = depth_spec(hack_baseline=0.07)
    model, data = build_scene(spec, add_depth_scene)
    sensor = CameraSensor(model, spec, camera="cam")
    sensors.append(sensor)
    frame = sensor.render(data, stamp_ns=1_500_000_007)
    msgs = [
        frame.image,
        frame.camera_info,
        frame.depth_image,
        frame.depth_camera_info,
        frame.points,
    ]
    for msg in msgs:
        assert msg is not None
        assert msg.header.frame_id == "cam_optical"
        assert time_to_ns(msg.header.stamp) == 1_500_000_007
    info = frame.camera_info
    focal = W / (2 * math.tan(1.2 / 2))
    np.testing.assert_allclose(info.k, [focal, 0, 32.0, 0, focal, 24.0, 0, 0, 1])
    np.testing.assert_allclose(
        info.p, [focal, 0, 32.0, -focal * 0.07, 0, focal, 24.0, 0, 0, 0, 1, 0]
    )
    np.testing.assert_allclose(info.r, np.eye(3).ravel())
    assert info.distortion_model == "plumb_bob"
    assert list(info.d) == [0.0] * 5
    assert (info.width, info.height) == (W, H)
    assert frame.image is not None
    assert frame.image.step == 3 * W
    assert frame.image.encoding == "rgb8"


def test_camera_info_function_matches_spec() -> None:
    spec = make_spec(distortion=LensDistortion(k1=0.1, k2=0.2, k3=0.3, p1=0.4, p2=0.5))
    info = camera_info(
        spec, header=camera_module.Header(stamp=camera_module.ns_to_time(0), frame_id="f")
    )
    assert list(info.d) == [0.1, 0.2, 0.4, 0.5, 0.3]  # k1 k2 p1 p2 k3


def test_encodings_and_point_cloud(sensors: list[CameraSensor]) -> None:
    base = depth_spec()
    model, data = build_scene(base, add_depth_scene)
    frames = {}
    for encoding, fmt in (("rgb8", "R8G8B8"), ("bgr8", "B8G8R8"), ("mono8", "L8")):
        spec = replace(base, encoding=encoding, image_format=fmt)
        sensor = CameraSensor(model, spec, camera="cam")
        sensors.append(sensor)
        frames[encoding] = sensor.render(data)
    rgb = image_to_numpy(frames["rgb8"].image)  # type: ignore[arg-type]
    bgr = image_to_numpy(frames["bgr8"].image)  # type: ignore[arg-type]
    mono = image_to_numpy(frames["mono8"].image)  # type: ignore[arg-type]
    np.testing.assert_array_equal(bgr, rgb[..., ::-1])
    assert mono.shape == (H, W)
    np.testing.assert_array_equal(mono, cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
    # The organized cloud is depth back-projected with K in the optical frame.
    frame = frames["rgb8"]
    cloud = frame.points
    assert cloud is not None
    assert (cloud.height, cloud.width) == (H, W)
    structured = cloud_to_structured(cloud).reshape(H, W)
    assert "rgb" in structured.dtype.names
    depth = frame.depth
    assert depth is not None
    v, u = 30, 20
    z = depth[v, u]
    assert np.isfinite(z)
    assert structured["z"][v, u] == pytest.approx(z)
    assert structured["x"][v, u] == pytest.approx((u - base.cx) / base.fx * z, rel=1e-5)
    assert structured["y"][v, u] == pytest.approx((v - base.cy) / base.fy * z, rel=1e-5)
    packed = structured["rgb"][v, u].view(np.uint32)
    assert [(packed >> 16) & 255, (packed >> 8) & 255, packed & 255] == rgb[v, u].tolist()
    xyz = cloud_to_xyz(cloud)
    assert xyz.shape[0] == int(np.isfinite(depth).sum())
    assert not cloud.is_dense or np.isfinite(depth).all()


def test_pointcloud_false_publishes_no_cloud(sensors: list[CameraSensor]) -> None:
    spec = depth_spec(pointcloud=False, points_topic=None)
    model, data = build_scene(spec, add_depth_scene)
    sensor = CameraSensor(model, spec, camera="cam", render_color=False)
    sensors.append(sensor)
    frame = sensor.render(data)
    assert frame.points is None
    assert frame.depth_image is not None


def test_noise_is_seeded(sensors: list[CameraSensor]) -> None:
    spec = make_spec(noise=GaussianNoise(stddev=0.02))
    model, data = build_scene(spec, add_depth_scene)
    images = []
    for seed in (7, 7, 8):
        sensor = CameraSensor(model, spec, camera="cam", seed=seed)
        sensors.append(sensor)
        images.append(sensor.render(data).color)
    clean = CameraSensor(model, replace(spec, noise=GaussianNoise()), camera="cam")
    sensors.append(clean)
    reference = clean.render(data).color
    assert reference is not None
    np.testing.assert_array_equal(images[0], images[1])
    assert not np.array_equal(images[0], images[2])
    diff = images[0].astype(float) - reference.astype(float)  # type: ignore[union-attr]
    mid = (reference > 20) & (reference < 235)
    assert np.std(diff[mid]) == pytest.approx(0.02 * 255, rel=0.15)


def test_depth_noise_does_not_depend_on_whether_colour_is_made(
    sensors: list[CameraSensor],
) -> None:
    # which outputs a camera makes follows its subscribers; the depth noise must not
    from visnav.description.noise_specs import DepthNoise

    spec = replace(
        depth_spec(width=80, height=60),
        noise=GaussianNoise(stddev=0.02),
        depth_noise=DepthNoise(disparity_stddev=0.5, disparity_step=0.125),
    )
    model, data = build_scene(spec, add_depth_scene)
    both = CameraSensor(model, spec, camera="cam", seed=3)
    depth_only = CameraSensor(model, spec, camera="cam", seed=3)
    sensors += [both, depth_only]
    for _ in range(3):
        a = both.render(data, image=True, depth=True, points=False)
        b = depth_only.render(data, image=False, depth=True, points=False)
        assert a.image is not None
        assert b.image is None
        assert a.depth is not None
        assert b.depth is not None
        np.testing.assert_array_equal(a.depth, b.depth)


# --------------------------------------------------------------------------- end to end


def test_sensor_rejects_unconfigured_camera(mujoco_gl: str) -> None:
    del mujoco_gl
    mj = mujoco.MjSpec()
    mj.worldbody.add_camera(name="plain", fovy=45)
    model = mj.compile()
    with pytest.raises(CameraSensorError, match="configure_mujoco_camera"):
        CameraSensor(model, make_spec(), camera="plain")
    with pytest.raises(CameraSensorError, match="does not exist"):
        CameraSensor(model, make_spec(), camera="nope")


def test_shared_context_must_be_large_enough(mujoco_gl: str) -> None:
    del mujoco_gl
    spec = make_spec()
    model, _ = build_scene(spec, add_spheres)
    with RenderContext(model, max_width=16, max_height=16) as small:
        # The model's default offscreen buffer (640x480) is kept: it is larger.
        assert small.max_width >= W
        CameraSensor(model, spec, camera="cam", context=small)


# --------------------------------------------------------------------------- OpenGL backend


@pytest.fixture
def gl_env(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    """Record MUJOCO_GL / PYOPENGL_PLATFORM so what select_gl_backend sets is undone."""
    for name in ("MUJOCO_GL", "PYOPENGL_PLATFORM"):
        monkeypatch.setenv(name, os.environ.get(name, ""))
    return monkeypatch


def test_select_gl_backend_prefers_requested(gl_env: pytest.MonkeyPatch) -> None:
    monkeypatch = gl_env
    monkeypatch.setenv("MUJOCO_GL", "egl")
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: f"lib{name}.so")
    assert select_gl_backend() == "egl"


def test_select_gl_backend_falls_back_to_osmesa(gl_env: pytest.MonkeyPatch) -> None:
    monkeypatch = gl_env
    monkeypatch.delenv("MUJOCO_GL")
    monkeypatch.delenv("PYOPENGL_PLATFORM")
    monkeypatch.setattr(
        ctypes.util, "find_library", lambda name: None if name == "EGL" else "libOSMesa.so.8"
    )
    assert select_gl_backend() == "osmesa"


def test_no_gl_backend_is_one_clear_error(gl_env: pytest.MonkeyPatch) -> None:
    monkeypatch = gl_env
    monkeypatch.delenv("MUJOCO_GL")
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    with pytest.raises(RenderingUnavailableError) as info:
        select_gl_backend()
    text = str(info.value)
    assert "libEGL" in text
    assert "libegl1" in text
    assert "libosmesa6" in text
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    with pytest.raises(RenderingUnavailableError, match=r"MUJOCO_GL=osmesa.*libosmesa6"):
        select_gl_backend()
