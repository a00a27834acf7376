"""depthimage_to_laserscan: upstream's tests, the use_point table, a flat wall, a slow reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from visnav.msgs import Header, Time
from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.perception import (
    DepthImageToLaserScan,
    DepthToScanError,
    PinholeCameraModel,
    scan_geometry,
    scan_rows,
)

F = 570.3422241210938
NAN, INF = float("nan"), float("inf")


@pytest.fixture
def openni_info(make_info):
    """The camera of upstream's test: 640 x 480, f 570.34, c (314.5, 235.5), no distortion."""
    return make_info(fx=F, cx=314.5, cy=235.5, d=[0.0] * 5, frame_id="frame")


def _depth_msg(array, encoding):
    return numpy_to_image(
        array, encoding, header=Header(stamp=Time(sec=1, nanosec=234567890), frame_id="frame")
    )


def _use_point(new, old, rmin, rmax):
    """Upstream's use_point, verbatim in Python."""
    new_finite, old_finite = math.isfinite(new), math.isfinite(old)
    if not new_finite and not old_finite:
        return not math.isnan(new)
    if not (rmin <= new <= rmax):
        return False
    if not old_finite:
        return True
    return new < old


def _reference_scan(depth, model, scan_height, range_min, range_max):
    """Upstream's convert_msg loop, pixel by pixel (slow reference)."""
    f32 = np.float32
    width = depth.shape[1]
    cy = model.cy

    def ray(u):
        return model.project_pixel_to_3d_ray(model.rectify_point((u, cy)))

    def angle(a, b):
        return math.acos(float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))))

    left, right, centre = ray(0.0), ray(width - 1.0), ray(model.cx)
    amax, amin = f32(angle(left, centre)), f32(-angle(centre, right))
    inc = f32((amax - amin) / f32(width - 1))
    mm = depth.dtype == np.uint16
    unit = f32(0.001) if mm else f32(1.0)
    center_x, constant_x = f32(model.cx), f32(float(unit) / model.fx)
    ranges = [f32(np.nan)] * width
    offset = int(cy - scan_height / 2.0)
    for v in range(offset, offset + scan_height):
        for u in range(width):
            d = depth[v, u]
            r = float(d)
            th = -math.atan2(float(f32(u) - center_x) * float(constant_x), float(unit))
            index = int((th - float(amin)) / float(inc))
            if (d != 0) if mm else math.isfinite(d):
                x = (f32(u) - center_x) * f32(d) * constant_x
                z = f32(d) * unit if mm else f32(d)
                r = math.sqrt(float(x) ** 2 + float(z) ** 2)
            r32 = f32(r)
            if 0 <= index < width and _use_point(
                float(r32), float(ranges[index]), float(f32(range_min)), float(f32(range_max))
            ):
                ranges[index] = r32
    return np.array(ranges, np.float32), (float(amin), float(amax), float(inc))


# --------------------------------------------------------------- upstream's tests


def test_setup_parameters_reach_the_message(openni_info):
    converter = DepthImageToLaserScan(
        scan_height=1,
        range_min=0.45,
        range_max=10.0,
        scan_time=1 / 30,
        output_frame_id="camera_depth_frame",
    )
    depth = np.full((480, 640), 0x0F0F, np.uint16)  # 3.855 m
    scan = converter.convert(_depth_msg(depth, "16UC1"), openni_info)
    assert scan.scan_time == np.float32(1 / 30)
    assert scan.range_min == np.float32(0.45)
    assert scan.range_max == np.float32(10.0)
    assert scan.header.frame_id == "camera_depth_frame"
    assert (scan.header.stamp.sec, scan.header.stamp.nanosec) == (1, 234567890)
    assert scan.ranges.dtype == np.float32
    assert len(scan.ranges) == 640
    assert scan.time_increment == 0.0
    assert len(scan.intensities) == 0
    # Angles of a distortion-free camera: the edge columns' bearings.
    assert scan.angle_max == pytest.approx(math.atan(314.5 / F), abs=1e-6)
    assert scan.angle_min == pytest.approx(-math.atan((639 - 314.5) / F), abs=1e-6)
    assert scan.angle_increment == pytest.approx((scan.angle_max - scan.angle_min) / 639, rel=1e-6)
    finite = scan.ranges[np.isfinite(scan.ranges)]
    assert finite.min() == pytest.approx(3.855, abs=1e-3)


def test_empty_output_frame_keeps_the_depth_frame(openni_info):
    converter = DepthImageToLaserScan(output_frame_id="")
    scan = converter.convert(_depth_msg(np.ones((480, 640), np.float32), "32FC1"), openni_info)
    assert scan.header.frame_id == "frame"


def test_encodings(openni_info):
    converter = DepthImageToLaserScan()
    with pytest.raises(DepthToScanError, match=r"'rgb8'.*16UC1.*32FC1"):
        converter.convert(_depth_msg(np.zeros((480, 640, 3), np.uint8), "rgb8"), openni_info)
    converter.convert(_depth_msg(np.ones((480, 640), np.float32), "32FC1"), openni_info)
    converter.convert(_depth_msg(np.ones((480, 640), np.uint16), "16UC1"), openni_info)


def test_scan_height_takes_the_minimum_of_each_column(openni_info):
    converter = DepthImageToLaserScan()
    low, high = 500, 3000
    for scan_height in range(1, 101, 3):
        converter.scan_height = scan_height
        depth = np.full((480, 640), high, np.uint16)
        offset = int(235.5 - scan_height / 2)
        v, u = np.mgrid[0:scan_height, 0:640]
        depth[offset : offset + scan_height] = np.where(
            v % scan_height == u % scan_height, low, high
        )
        scan = converter.convert(_depth_msg(depth, "16UC1"), openni_info)
        valid = scan.ranges[(scan.ranges >= scan.range_min) & (scan.ranges <= scan.range_max)]
        assert valid.size > 300
        assert (valid < high / 1000 * 0.9).all(), scan_height


def test_random_near_depths_stay_within_limits(openni_info):
    rng = np.random.default_rng(8675309)
    depth = rng.integers(0, 500, (480, 640)).astype(np.uint16)  # 0 .. 0.5 m
    scan = DepthImageToLaserScan().convert(_depth_msg(depth, "16UC1"), openni_info)
    finite = scan.ranges[np.isfinite(scan.ranges)]
    assert finite.size > 0
    assert (finite >= scan.range_min).all()
    assert (finite <= scan.range_max).all()


def test_nan_image_gives_no_finite_range(openni_info):
    depth = np.full((480, 640), np.nan, np.float32)
    scan = DepthImageToLaserScan().convert(_depth_msg(depth, "32FC1"), openni_info)
    assert np.isnan(scan.ranges).all()


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_inf_image_keeps_inf(openni_info, sign):
    depth = np.full((480, 640), sign * np.inf, np.float32)
    scan = DepthImageToLaserScan().convert(_depth_msg(depth, "32FC1"), openni_info)
    assert not np.isfinite(scan.ranges).any()
    infs = scan.ranges[np.isinf(scan.ranges)]
    assert (np.sign(infs) == sign).all()
    assert np.isnan(scan.ranges).sum() <= 0.8 * 640


# ------------------------------------------------------------ use_point precedence


@pytest.mark.parametrize(
    ("first", "second", "expected"),
    [
        (NAN, NAN, NAN),  # nothing
        (NAN, INF, INF),  # inf beats NaN
        (INF, NAN, INF),  # NaN never replaces
        (INF, -INF, -INF),  # among infs the last one wins
        (-INF, INF, INF),
        (2.0, INF, 2.0),  # finite in range beats inf
        (INF, 2.0, 2.0),
        (NAN, 2.0, 2.0),
        (2.0, NAN, 2.0),
        (3.0, 2.0, 2.0),  # shorter beats longer
        (2.0, 3.0, 2.0),
        (0.1, NAN, NAN),  # below range_min: dropped
        (0.1, INF, INF),
        (20.0, 2.0, 2.0),  # above range_max: dropped
        (20.0, NAN, NAN),
        (0.45, 10.0, 0.45),  # the limits are inclusive
    ],
)
def test_use_point_precedence(make_info, first, second, expected):
    # Two rows, one column at the principal point (x = 0, so range = depth).
    info = make_info(width=41, height=10, fx=50.0, cx=20.0, cy=5.0)
    depth = np.full((10, 41), np.nan, np.float32)
    depth[4, 20], depth[5, 20] = first, second
    converter = DepthImageToLaserScan(scan_height=2)
    scan = converter.convert(_depth_msg(depth, "32FC1"), info)
    index = converter.geometry(info, 41, np.dtype(np.float32)).index[20]
    got = scan.ranges[index]
    if math.isnan(expected):
        assert math.isnan(got)
    else:
        assert got == np.float32(expected)


def test_zero_millimetres_never_become_a_range(make_info):
    info = make_info(width=41, height=10, fx=50.0, cx=20.0, cy=5.0)
    depth = np.zeros((10, 41), np.uint16)
    scan = DepthImageToLaserScan(range_min=0.45).convert(_depth_msg(depth, "16UC1"), info)
    assert np.isnan(scan.ranges).all()


# ------------------------------------------------------------------- a flat wall


@pytest.mark.parametrize("encoding", ["32FC1", "16UC1"])
def test_flat_wall_gives_the_analytic_scan(openni_info, encoding):
    wall = 2.5  # metres along the optical axis
    depth = np.full((480, 640), wall, np.float32)
    if encoding == "16UC1":
        depth = np.full((480, 640), 2500, np.uint16)
    scan = DepthImageToLaserScan(scan_height=10).convert(_depth_msg(depth, encoding), openni_info)
    angles = scan.angle_min + np.arange(640) * scan.angle_increment
    analytic = wall / np.cos(angles)
    finite = np.isfinite(scan.ranges)
    assert finite.mean() > 0.9
    # A range comes from a column whose bearing lies in [angle_i, angle_i + increment).
    slack = wall * np.abs(np.tan(angles) / np.cos(angles)) * scan.angle_increment + 1e-5
    err = np.abs(scan.ranges - analytic)
    assert (err[finite] <= slack[finite]).all()
    # The closest point of the wall is straight ahead.
    assert np.nanmin(scan.ranges) == pytest.approx(wall, abs=1e-5)
    # Index 0 is the image's right edge (negative angle: ROS scans turn left); the
    # edge columns share it and the nearest of them (the most central) is kept.
    edge_bin = (
        wall / math.cos(scan.angle_min + scan.angle_increment),
        wall / math.cos(scan.angle_min),
    )
    assert edge_bin[0] - 1e-5 <= scan.ranges[0] <= edge_bin[1] + 1e-5
    assert scan.ranges[0] < edge_bin[1] - 1e-3  # several columns merged: not the edge one


def test_wall_seen_through_a_distorted_camera(plumb_info):
    model_info = plumb_info()
    model = PinholeCameraModel.from_camera_info(model_info)
    scan = DepthImageToLaserScan().convert(
        _depth_msg(np.full((480, 640), 3.0, np.float32), "32FC1"), model_info
    )
    # angle_max / angle_min come from the rectified rays through (0, cy) and (W - 1, cy).
    left = model.project_pixel_to_3d_ray(model.rectify_point((0.0, model.cy)))
    centre = model.project_pixel_to_3d_ray(model.rectify_point((model.cx, model.cy)))
    cos = np.dot(left, centre) / np.linalg.norm(left) / np.linalg.norm(centre)
    assert scan.angle_max == pytest.approx(math.acos(cos), abs=1e-6)
    assert np.isfinite(scan.ranges).sum() > 300


# --------------------------------------------------------- the slow reference


@settings(max_examples=30, deadline=None)
@given(
    depth=hnp.arrays(
        np.float32,
        (9, 24),
        elements=st.one_of(
            st.floats(0.0, 12.0, width=32),
            st.sampled_from([np.nan, np.inf, -np.inf, -1.5]),
        ),
    ),
    scan_height=st.integers(1, 8),
    fx=st.floats(8.0, 60.0),
    cx=st.floats(5.0, 18.0),
)
def test_property_matches_the_reference_float(make_info, depth, scan_height, fx, cx):
    info = make_info(width=24, height=9, fx=fx, cx=cx, cy=4.5)
    model = PinholeCameraModel.from_camera_info(info)
    expected, (amin, amax, inc) = _reference_scan(depth, model, scan_height, 0.45, 10.0)
    scan = DepthImageToLaserScan(scan_height=scan_height).convert(_depth_msg(depth, "32FC1"), info)
    assert (scan.angle_min, scan.angle_max, scan.angle_increment) == (amin, amax, inc)
    np.testing.assert_array_equal(scan.ranges, expected)


@settings(max_examples=30, deadline=None)
@given(
    depth=hnp.arrays(np.uint16, (9, 24), elements=st.integers(0, 12000)),
    scan_height=st.integers(1, 8),
    k1=st.floats(-0.2, 0.2),
)
def test_property_matches_the_reference_uint16(make_info, depth, scan_height, k1):
    info = make_info(width=24, height=9, fx=20.0, cx=11.5, cy=4.5, d=[k1, 0, 0, 0, 0])
    model = PinholeCameraModel.from_camera_info(info)
    expected, _ = _reference_scan(depth, model, scan_height, 0.45, 10.0)
    scan = DepthImageToLaserScan(scan_height=scan_height).convert(_depth_msg(depth, "16UC1"), info)
    np.testing.assert_array_equal(scan.ranges, expected)


# ----------------------------------------------------------------- bad input


def test_scan_height_must_fit_the_image(openni_info):
    converter = DepthImageToLaserScan(scan_height=481)
    with pytest.raises(DepthToScanError, match="scan_height is 481 pixels: too large"):
        converter.convert(_depth_msg(np.ones((480, 640), np.float32), "32FC1"), openni_info)
    assert scan_rows(235.5, 480, 470) == (0, 470)
    with pytest.raises(DepthToScanError):
        scan_rows(235.5, 480, 474)


def test_bad_parameters():
    with pytest.raises(DepthToScanError, match="scan_height is 0"):
        DepthImageToLaserScan(scan_height=0)
    with pytest.raises(DepthToScanError, match=r"range_min, range_max are 5.0, 1.0"):
        DepthImageToLaserScan(range_min=5.0, range_max=1.0)


def test_size_mismatch_and_narrow_images(make_info):
    converter = DepthImageToLaserScan()
    with pytest.raises(DepthToScanError, match=r"320 x 240.*640 x 480"):
        converter.convert(_depth_msg(np.ones((240, 320), np.float32), "32FC1"), make_info())
    model = PinholeCameraModel.from_camera_info(make_info(width=1, height=4, cx=0.0))
    with pytest.raises(DepthToScanError, match="at least 2 columns"):
        scan_geometry(model, 1)


def test_debug_image_marks_the_rows(openni_info):
    converter = DepthImageToLaserScan(scan_height=6)
    image = converter.debug_image(
        _depth_msg(np.full((480, 640), 2.0, np.float32), "32FC1"), openni_info
    )
    assert image.encoding == "bgr8"
    pixels = image_to_numpy(image)
    start, stop = scan_rows(235.5, 480, 6)
    assert (pixels[start:stop, :, 2] >= 160).all()
    assert (pixels[start:stop, :, 0] < pixels[start:stop, :, 2]).all()
    grey = np.delete(pixels, np.s_[start:stop], axis=0)
    assert (grey[..., 0] == grey[..., 2]).all()
