"""PinholeCameraModel: image_geometry's tests and semantics, round trips, bad input."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.perception import CameraModelError, PinholeCameraModel

# ----------------------------------------------------------------- accessors


def test_accessors_read_p_like_image_geometry(plumb_info, upstream):
    info = plumb_info(frame_id="tf_frame", stamp=(7, 8))
    model = PinholeCameraModel.from_camera_info(info)
    assert model.initialized
    assert (model.width, model.height) == (640, 480)
    assert model.full_resolution_size == (640, 480)
    assert model.tf_frame == "tf_frame"
    assert (model.stamp.sec, model.stamp.nanosec) == (7, 8)
    assert model.stamp_ns == 7_000_000_008
    assert model.fx == upstream.PLUMB_P[0]
    assert model.fy == upstream.PLUMB_P[5]
    assert model.cx == upstream.PLUMB_P[2]
    assert model.cy == upstream.PLUMB_P[6]
    assert model.Tx == 0.0
    assert model.Ty == 0.0
    np.testing.assert_array_equal(model.K, np.reshape(upstream.PLUMB_K, (3, 3)))
    np.testing.assert_array_equal(model.P, np.reshape(upstream.PLUMB_P, (3, 4)))
    np.testing.assert_array_equal(model.D, upstream.PLUMB_D)
    assert model.distortion_model == "plumb_bob"
    assert model.has_distortion
    assert model.camera_info is info
    with pytest.raises(ValueError, match="read-only"):
        model.K[0, 0] = 1.0


def test_from_camera_info_is_a_constructor_and_an_update(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    assert isinstance(model, PinholeCameraModel)
    other = PinholeCameraModel()
    assert not other.initialized
    assert other.from_camera_info(plumb_info()) is True
    # Same calibration, new stamp: nothing to rebuild.
    assert other.from_camera_info(plumb_info(stamp=(99, 0))) is False
    assert other.stamp.sec == 99
    assert other.from_camera_info(plumb_info(d=[0.1, 0, 0, 0, 0])) is True


def test_uninitialized_model_says_what_to_do():
    model = PinholeCameraModel()
    with pytest.raises(CameraModelError, match="from_camera_info"):
        _ = model.fx
    with pytest.raises(CameraModelError, match="from_camera_info"):
        model.rectify_point((1.0, 2.0))
    assert "no camera_info" in repr(model)


# ---------------------------------------------------------------- projection


def test_project_pixel_to_3d_ray_spot_values(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    ray = model.project_pixel_to_3d_ray((100.0, 100.0))
    # image_geometry utest.cpp (ROS 2): z = 1 rays.
    np.testing.assert_allclose(ray, [-0.62787224048135637, -0.41719792045817677, 1.0], atol=1e-8)
    unit = model.project_pixel_to_3d_ray((100.0, 100.0), normalize=True)
    # image_geometry's older / Python model: unit vectors.
    np.testing.assert_allclose(
        unit, [-0.501371686835080932, -0.333142973423770972, 0.798525009563579191], atol=1e-12
    )
    centre = model.project_pixel_to_3d_ray((model.cx, model.cy))
    np.testing.assert_array_equal(centre, [0.0, 0.0, 1.0])


def test_project_and_back_project_over_the_image(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    uv = np.stack(np.meshgrid(np.arange(0, 641, 10), np.arange(0, 481, 10)), -1).reshape(-1, 2)
    back = model.project_3d_to_pixel(model.project_pixel_to_3d_ray(uv))
    np.testing.assert_allclose(back, uv, atol=1.14e-13)
    scaled = model.project_pixel_to_3d_ray(uv, normalize=True) * 3.7
    np.testing.assert_allclose(model.project_3d_to_pixel(scaled), uv, atol=1e-10)


def test_project_3d_to_pixel_uses_tx_and_gives_nan_at_z0(make_info):
    # A right stereo camera: Tx = -fx * baseline.
    p = [500.0, 0, 320, -500.0 * 0.1, 0, 500.0, 240, 0, 0, 0, 1, 0]
    model = PinholeCameraModel.from_camera_info(
        make_info(k=[500.0, 0, 320, 0, 500, 240, 0, 0, 1], p=p)
    )
    assert model.Tx == -50.0
    np.testing.assert_allclose(model.project_3d_to_pixel([0.1, 0.0, 2.0]), [320.0, 240.0])
    assert np.isnan(model.project_3d_to_pixel([1.0, 1.0, 0.0])).all()
    uv = np.array([[10.0, 20.0], [600.0, 400.0]])
    np.testing.assert_allclose(model.project_3d_to_pixel(model.project_pixel_to_3d_ray(uv)), uv)


def test_get_deltas(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    u, v, du, dv, z = 100.0, 200.0, 17.0, 23.0, 2.0
    xyz0 = model.project_pixel_to_3d_ray((u, v)) * z
    xyz1 = model.project_pixel_to_3d_ray((u + du, v + dv)) * z
    assert model.get_delta_u(xyz1[0] - xyz0[0], z) == pytest.approx(du, abs=1e-4)
    assert model.get_delta_v(xyz1[1] - xyz0[1], z) == pytest.approx(dv, abs=1e-4)
    assert model.get_delta_x(du, z) == pytest.approx(xyz1[0] - xyz0[0], abs=1e-4)
    assert model.get_delta_y(dv, z) == pytest.approx(xyz1[1] - xyz0[1], abs=1e-4)
    assert model.get_delta_u(1.0, 0.0) == float("inf")


def test_point_arguments_are_checked(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    with pytest.raises(CameraModelError, match=r"uv_raw has shape \(3,\)"):
        model.rectify_point([1.0, 2.0, 3.0])
    with pytest.raises(CameraModelError, match=r"xyz has shape \(2, 2\)"):
        model.project_3d_to_pixel([[1.0, 2.0], [3.0, 4.0]])


# ----------------------------------------------------------- rectify points


def test_rectify_point_matches_image_geometry(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    # utest.cpp's value is float32 (cv::undistortPoints on CV_32FC2).
    np.testing.assert_allclose(
        model.rectify_point((100.0, 100.0)), [142.30311584472656, 132.061065673828], atol=2e-5
    )


def test_rectify_unrectify_round_trip_plumb_bob(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    grid = np.stack(np.meshgrid(np.arange(65, 576, 5), np.arange(65, 416, 5)), -1).reshape(-1, 2)
    # image_geometry's own test only asks for one pixel with OpenCV's 5 iterations.
    default = model.unrectify_point(model.rectify_point(grid))
    assert np.abs(default - grid).max() < 1.0
    precise = model.unrectify_point(model.rectify_point(grid, iterations=50))
    np.testing.assert_allclose(precise, grid, atol=1e-9)


def test_equidistant_matches_image_geometry(equi_info, upstream):
    model = PinholeCameraModel.from_camera_info(equi_info(frame_id="tf_frame"))
    assert model.fx == upstream.EQUI_P[0]
    assert model.cy == upstream.EQUI_P[6]
    np.testing.assert_allclose(
        model.project_pixel_to_3d_ray((100.0, 100.0)),
        [-0.72136775518018115, -0.449235009214005, 1.0],
        atol=1e-8,
    )
    np.testing.assert_allclose(
        model.rectify_point((100.0, 100.0)), [135.45747375488281, 84.945091247558594], atol=2e-5
    )
    grid = np.stack(np.meshgrid(np.arange(0, 641, 5), np.arange(0, 513, 5)), -1).reshape(-1, 2)
    np.testing.assert_allclose(model.unrectify_point(model.rectify_point(grid)), grid, atol=0.01)


def test_rational_polynomial_round_trip(make_info):
    d = [0.2, -0.05, 0.001, -0.001, 0.01, 0.15, -0.04, 0.008]
    model = PinholeCameraModel.from_camera_info(
        make_info(d=d, distortion_model="rational_polynomial")
    )
    grid = np.stack(np.meshgrid(np.arange(40, 600, 20), np.arange(40, 440, 20)), -1).reshape(-1, 2)
    rect = model.rectify_point(grid, iterations=100)
    np.testing.assert_allclose(model.unrectify_point(rect), grid, atol=1e-6)
    # Same numbers as OpenCV directly.
    direct = cv2.undistortPoints(
        grid.reshape(-1, 1, 2).astype(np.float64), model.K, np.array(d), R=model.R, P=model.P
    ).reshape(-1, 2)
    np.testing.assert_allclose(model.rectify_point(grid), direct)


def test_zero_distortion_passes_points_through(make_info):
    # image_geometry: no non-zero coefficient -> rectify_point returns its input,
    # even when R and P would move it.
    tilt = [0.999, -0.0447, 0, 0.0447, 0.999, 0, 0, 0, 1]
    model = PinholeCameraModel.from_camera_info(make_info(d=[0.0] * 5, r=tilt))
    assert not model.has_distortion
    np.testing.assert_array_equal(model.rectify_point((10.5, 20.25)), [10.5, 20.25])
    np.testing.assert_array_equal(model.unrectify_point([[1.0, 2.0]]), [[1.0, 2.0]])


@settings(max_examples=40, deadline=None)
@given(
    k1=st.floats(-0.3, 0.3),
    k2=st.floats(-0.1, 0.1),
    p1=st.floats(-0.002, 0.002),
    p2=st.floats(-0.002, 0.002),
    fx=st.floats(300.0, 900.0),
    u=st.floats(120.0, 520.0),
    v=st.floats(100.0, 380.0),
)
def test_property_plumb_bob_round_trip(make_info, k1, k2, p1, p2, fx, u, v):
    model = PinholeCameraModel.from_camera_info(make_info(fx=fx, d=[k1, k2, p1, p2, 0.0]))
    if not model.has_distortion:
        return
    # OpenCV's (and image_geometry's) undistortion is a fixed-point iteration: it
    # converges where the radial term is a mild correction, not at the strongly
    # distorted image edges of a short focal length (e.g. k1 -0.25, fx 300, 200 px out).
    r2 = ((u - model.cx) / fx) ** 2 + ((v - model.cy) / fx) ** 2
    assume(abs(k1 * r2 + k2 * r2 * r2) < 0.1)
    rect = model.rectify_point((u, v), iterations=100)
    np.testing.assert_allclose(model.unrectify_point(rect), [u, v], atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(
    d=st.lists(st.floats(-0.05, 0.05), min_size=4, max_size=4),
    u=st.floats(60.0, 580.0),
    v=st.floats(60.0, 420.0),
)
def test_property_equidistant_round_trip(make_info, d, u, v):
    model = PinholeCameraModel.from_camera_info(
        make_info(fx=400.0, d=d, distortion_model="equidistant")
    )
    if not model.has_distortion:
        return
    rect = model.rectify_point((u, v), iterations=50)
    np.testing.assert_allclose(model.unrectify_point(rect), [u, v], atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(
    fx=st.floats(50.0, 2000.0),
    fy=st.floats(50.0, 2000.0),
    cx=st.floats(-100.0, 800.0),
    cy=st.floats(-100.0, 800.0),
    tx=st.floats(-100.0, 100.0),
    uv=st.tuples(st.floats(-1000.0, 2000.0), st.floats(-1000.0, 2000.0)),
)
def test_property_project_back_project(make_info, fx, fy, cx, cy, tx, uv):
    k = [fx, 0, cx, 0, fy, cy, 0, 0, 1]
    p = [fx, 0, cx, tx, 0, fy, cy, 0, 0, 0, 1, 0]
    model = PinholeCameraModel.from_camera_info(make_info(k=k, p=p))
    ray = model.project_pixel_to_3d_ray(uv)
    assert ray[2] == 1.0
    np.testing.assert_allclose(model.project_3d_to_pixel(ray), uv, atol=1e-9, rtol=1e-12)


# ----------------------------------------------------------- rectify images


def _grid_image(width: int, height: int) -> np.ndarray:
    image = np.zeros((height, width, 3), np.uint8)
    for y in range(0, height + 1, height // 10):
        cv2.line(image, (0, y), (width, y), (255, 255, 255), 7)
    for x in range(0, width + 1, width // 10):
        cv2.line(image, (x, 0), (x, height), (255, 255, 255), 7)
    return image


@pytest.mark.parametrize("camera", ["plumb_info", "equi_info"])
def test_rectify_if_calibrated(camera, request):
    # image_geometry's rectifyIfCalibrated test.
    make = request.getfixturevalue(camera)
    info = make()
    image = _grid_image(info.width, info.height)
    model = PinholeCameraModel.from_camera_info(info)
    assert np.abs(model.rectify_image(image).astype(int) - image).sum() > 10_000
    d = list(info.d)
    d[0] = 0.0
    model.from_camera_info(make(d=d))
    assert np.abs(model.rectify_image(image).astype(int) - image).sum() > 10_000
    model.from_camera_info(make(d=[0.0] * len(d)))
    np.testing.assert_array_equal(model.rectify_image(image), image)
    model.from_camera_info(make(d=[]))
    rectified = model.rectify_image(image)
    np.testing.assert_array_equal(rectified, image)
    assert rectified is not image


def _smooth(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return (128.0 + 100.0 * np.sin(u / 9.0) * np.cos(v / 11.0)).astype(np.float32)


@pytest.mark.parametrize("camera", ["plumb_info", "equi_info"])
def test_rectify_image_undoes_a_synthetic_distortion(camera, request):
    info = request.getfixturevalue(camera)()
    model = PinholeCameraModel.from_camera_info(info)
    w, h = info.width, info.height
    us, vs = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    raw_px = np.stack((us.ravel(), vs.ravel()), axis=1)
    # The raw image sees the analytic rectified scene at each raw pixel's rectified position.
    rect_px = model.rectify_point(raw_px, iterations=50)
    raw = _smooth(rect_px[:, 0], rect_px[:, 1]).reshape(h, w)
    rectified = model.rectify_image(raw)
    assert rectified.dtype == np.float32
    truth = _smooth(us, vs)
    valid = np.isfinite(rectified)
    valid[:8] = valid[-8:] = False
    valid[:, :8] = valid[:, -8:] = False
    assert valid.mean() > 0.5
    err = np.abs(rectified - truth)[valid]
    assert err.mean() < 0.3
    assert np.percentile(err, 99) < 1.5
    if camera == "plumb_info":
        # Its P sees more than the raw image: outside it float pixels are NaN
        # (image_geometry's border value).
        assert not np.isfinite(rectified).all()


def test_unrectify_image_inverts_rectify_image(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    us, vs = np.meshgrid(np.arange(640.0), np.arange(480.0))
    rect = _smooth(us, vs)
    raw = model.unrectify_image(rect)
    back = model.rectify_image(raw)
    inner = np.isfinite(back)
    inner[:40] = inner[-40:] = False
    inner[:, :40] = inner[:, -40:] = False
    assert np.abs(back - rect)[inner].mean() < 0.5


def test_maps_are_cached_per_calibration(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    maps = model.rectification_maps()
    assert maps is not None
    assert maps[0].dtype == np.int16
    assert maps[0].shape == (480, 640, 2)
    assert maps[1].dtype == np.uint16
    model.from_camera_info(plumb_info(stamp=(50, 0), frame_id="other"))
    assert model.rectification_maps() is maps
    model.from_camera_info(plumb_info(d=[-0.3, 0.1, 0.0, 0.0, 0.0]))
    new = model.rectification_maps()
    assert new is not maps
    assert not np.array_equal(new[0], maps[0])


def test_rectify_image_equals_bare_remap(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    rng = np.random.default_rng(3)
    image = rng.integers(0, 255, (480, 640, 3), dtype=np.uint8)
    map1, map2 = model.rectification_maps()
    expected = cv2.remap(image, map1, map2, cv2.INTER_LINEAR)
    np.testing.assert_array_equal(model.rectify_image(image), expected)
    nearest = cv2.remap(image, map1, map2, cv2.INTER_NEAREST)
    np.testing.assert_array_equal(
        model.rectify_image(image, interpolation=cv2.INTER_NEAREST), nearest
    )


def test_binning_and_roi_adjust_k_and_p_like_image_geometry(plumb_info, upstream):
    roi = (40, 30, 400, 300)
    model = PinholeCameraModel.from_camera_info(plumb_info(binning=(2, 2), roi=roi))
    assert model.raw_roi == roi
    assert model.raw_image_size == (200, 150)
    assert model.reduced_resolution_size == (200, 150)
    assert model.fx == pytest.approx(upstream.PLUMB_P[0] / 2)
    assert model.cx == pytest.approx((upstream.PLUMB_P[2] - 40) / 2)
    assert model.cy == pytest.approx((upstream.PLUMB_P[6] - 30) / 2)
    assert model.K[0, 2] == pytest.approx((upstream.PLUMB_K[2] - 40) / 2)
    np.testing.assert_array_equal(model.full_P, np.reshape(upstream.PLUMB_P, (3, 4)))
    full = model.to_full_resolution((10.0, 20.0))
    np.testing.assert_allclose(full, [10 * 2 + 40, 20 * 2 + 30])
    np.testing.assert_allclose(model.to_reduced_resolution(full), [10.0, 20.0])
    # Binning 0 means 1; an all-zero ROI means the full image.
    plain = PinholeCameraModel.from_camera_info(plumb_info())
    assert (plain.binning_x, plain.binning_y) == (1, 1)
    assert plain.raw_roi == (0, 0, 640, 480)


def test_roi_rectification_is_a_crop_of_the_full_one(plumb_info):
    rng = np.random.default_rng(5)
    full_raw = cv2.GaussianBlur(rng.integers(0, 255, (480, 640), dtype=np.uint8), (9, 9), 3)
    full = PinholeCameraModel.from_camera_info(plumb_info()).rectify_image(full_raw)
    x, y, w, h = 100, 80, 400, 300
    model = PinholeCameraModel.from_camera_info(plumb_info(roi=(x, y, w, h)))
    cropped = model.rectify_image(full_raw[y : y + h, x : x + w])
    assert cropped.shape == (h, w)
    m = 60  # pixels whose source lies inside the ROI
    np.testing.assert_array_equal(cropped[m:-m, m:-m], full[y + m : y + h - m, x + m : x + w - m])
    # A new ROI reuses the full-resolution maps and rebuilds only the crop.
    full_maps = model._full_maps
    model.from_camera_info(plumb_info(roi=(0, 0, 320, 240)))
    assert model.rectify_image(full_raw[:240, :320]).shape == (240, 320)
    assert model._full_maps is full_maps


def test_binned_rectification_matches_downsampled_full(plumb_info):
    us, vs = np.meshgrid(np.arange(640.0), np.arange(480.0))
    full_raw = _smooth(us / 3.0, vs / 3.0)
    full = PinholeCameraModel.from_camera_info(plumb_info()).rectify_image(full_raw)
    binned_raw = cv2.resize(full_raw, (320, 240), interpolation=cv2.INTER_AREA)
    binned = PinholeCameraModel.from_camera_info(plumb_info(binning=(2, 2))).rectify_image(
        binned_raw
    )
    reference = full[::2, ::2]
    ok = np.isfinite(binned) & np.isfinite(reference)
    ok[:20] = ok[-20:] = False
    ok[:, :20] = ok[:, -20:] = False
    assert np.abs(binned - reference)[ok].mean() < 3.0


def test_rectify_roi_of_undistorted_camera_is_identity(make_info):
    model = PinholeCameraModel.from_camera_info(make_info())
    assert model.rectify_roi((10, 20, 100, 50)) == (10, 20, 100, 50)
    assert model.unrectify_roi((10, 20, 100, 50)) == (10, 20, 100, 50)


def test_rectified_roi_with_do_rectify(plumb_info):
    model = PinholeCameraModel.from_camera_info(
        plumb_info(roi=(100, 100, 200, 200), do_rectify=True)
    )
    x, y, w, h = model.rectified_roi
    assert (x, y, w, h) == model.rectify_roi((100, 100, 200, 200))
    assert (x, y) != (100, 100)
    assert w > 0
    assert h > 0


def test_rectify_image_checks_size_and_dtype(plumb_info):
    model = PinholeCameraModel.from_camera_info(plumb_info())
    with pytest.raises(CameraModelError, match=r"shape \(240, 320\).*\(480, 640\)"):
        model.rectify_image(np.zeros((240, 320), np.uint8))
    with pytest.raises(CameraModelError, match="dtype int64"):
        model.rectify_image(np.zeros((480, 640), np.int64))


# ------------------------------------------------------------------ bad input


def test_k_all_zero_is_uncalibrated(make_info):
    with pytest.raises(CameraModelError, match=r"k is all zero.*uncalibrated") as info:
        PinholeCameraModel.from_camera_info(make_info(k=[0.0] * 9, p=[1.0] * 12))
    assert isinstance(info.value, VisnavError)
    assert isinstance(info.value, ValueError)


def test_p_all_zero_does_not_fall_back_to_k(make_info):
    k = [500.0, 0, 320, 0, 500, 240, 0, 0, 1]
    with pytest.raises(CameraModelError, match=r"p is all zero.*p = \[500, 0, 320, 0, 0, 500, 240"):
        PinholeCameraModel.from_camera_info(make_info(k=k, p=[0.0] * 12))


def test_unknown_distortion_model(make_info):
    with pytest.raises(CameraModelError, match=r"'plumbbob'.*did you mean 'plumb_bob'"):
        PinholeCameraModel.from_camera_info(
            make_info(distortion_model="plumbbob", d=[0.1, 0, 0, 0, 0])
        )
    # No coefficient to apply: accepted as distortion-free.
    model = PinholeCameraModel.from_camera_info(make_info(distortion_model="", d=[]))
    assert not model.has_distortion
    image = np.ones((480, 640), np.uint8)
    np.testing.assert_array_equal(model.rectify_image(image), image)


@pytest.mark.parametrize(
    ("model", "d", "expected"),
    [
        ("plumb_bob", [0.1, 0.01, 0.0, 0.0, 0.0, 0.0], "OpenCV takes 4"),
        ("rational_polynomial", [0.1, 0.01, 0.0], "OpenCV takes 4"),
        ("", [0.1, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0], "an empty distortion_model: OpenCV takes"),
        ("equidistant", [0.1, 0.01, 0.0, 0.0, 0.0], "expected 4"),
    ],
)
def test_d_length_must_be_one_opencv_takes(make_info, model, d, expected):
    with pytest.raises(CameraModelError, match=rf"d has {len(d)} coefficients.*{expected}"):
        PinholeCameraModel.from_camera_info(make_info(distortion_model=model, d=d))


@pytest.mark.parametrize(
    ("model", "d", "applied", "warned"),
    [
        ("plumb_bob", [0.1, 0.01, 0.001, 0.002], "plumb_bob", False),
        ("", [0.1, 0.01, 0.001, 0.002], "plumb_bob", True),
        ("", [0.1, 0.01, 0.001, 0.002, 0.003], "plumb_bob", True),
        ("rational_polynomial", [0.1, 0.01, 0.001, 0.002, 0.003], "plumb_bob", True),
        ("plumb_bob", [0.1, 0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0], "rational_polynomial", True),
        ("rational_polynomial", [0.1, 0.01] + [0.0] * 10, "rational_polynomial", False),
        ("", [0.1, 0.01] + [0.0] * 12, "rational_polynomial", True),
    ],
)
def test_d_is_read_by_length_as_opencv_does(make_info, caplog, model, d, applied, warned):
    # image_geometry hands D to OpenCV as it is: OpenCV reads 4/5 as plumb_bob (4 padded
    # with k3 = 0) and 8/12/14 as its rational model; an empty model name the same way.
    caplog.set_level("WARNING", logger="visnav.perception.camera_model")
    info = make_info(distortion_model=model, d=d)
    camera = PinholeCameraModel.from_camera_info(info)
    assert camera.distortion_model == applied
    assert camera.D.tolist() == ([*d, 0.0] if len(d) == 4 else d)
    raw = np.array([[10.0, 20.0], [600.0, 400.0]])
    k = camera.K
    want = cv2.undistortPoints(raw.reshape(-1, 1, 2), k, np.array(d), R=camera.R, P=camera.P)
    np.testing.assert_allclose(camera.rectify_point(raw), want.reshape(-1, 2), rtol=1e-12)
    camera.from_camera_info(info)  # an update with the same assumption says nothing more
    assert len(caplog.records) == int(warned)
    if warned:
        assert f"applied as {applied!r}" in caplog.records[0].getMessage()


def test_other_bad_calibrations(make_info):
    with pytest.raises(CameraModelError, match="r is all zero"):
        PinholeCameraModel.from_camera_info(make_info(r=[0.0] * 9, d=[0.1, 0, 0, 0, 0]))
    with pytest.raises(CameraModelError, match="roi"):
        PinholeCameraModel.from_camera_info(make_info(roi=(600, 0, 100, 100)))
    with pytest.raises(CameraModelError, match="width x height is 0 x 480"):
        PinholeCameraModel.from_camera_info(make_info(width=0))
    with pytest.raises(CameraModelError, match="k has 4 values"):
        PinholeCameraModel.from_camera_info(make_info(k=[1.0, 0, 0, 1.0]))
    with pytest.raises(CameraModelError, match="finite"):
        PinholeCameraModel.from_camera_info(make_info(d=[float("nan")] * 5))
    # A bad update leaves the previous calibration in place.
    model = PinholeCameraModel.from_camera_info(make_info(fx=400.0))
    with pytest.raises(CameraModelError):
        model.from_camera_info(make_info(k=[0.0] * 9))
    assert model.fx == 400.0
