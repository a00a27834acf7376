"""depth_image_proc: point_cloud_xyz, point_cloud_xyzrgb, convert_metric."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from visnav.msgs import Header, PointField, Time
from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.msgs.pointcloud import cloud_to_structured, cloud_to_xyz, unpack_rgb
from visnav.perception import (
    CameraModelError,
    DepthImageError,
    PinholeCameraModel,
    PointCloudXyz,
    PointCloudXyzrgb,
    convert_metric,
    depth_ray_tables,
    depth_to_points,
    point_cloud_xyz,
    point_cloud_xyzrgb,
)


def _reference_points(depth, model, invalid_depth=0.0):
    """depth_image_proc's convertDepth loop, pixel by pixel in float32 (slow reference)."""
    f32 = np.float32
    unit = f32(0.001) if depth.dtype == np.uint16 else f32(1.0)
    center_x, center_y = f32(model.cx), f32(model.cy)
    constant_x = f32(float(unit) / model.fx)
    constant_y = f32(float(unit) / model.fy)
    out = np.empty((*depth.shape, 3), np.float32)
    for v in range(depth.shape[0]):
        for u in range(depth.shape[1]):
            d = depth[v, u]
            valid = d != 0 if depth.dtype == np.uint16 else np.isfinite(d)
            if not valid:
                if invalid_depth == 0.0:
                    out[v, u] = np.nan
                    continue
                d = (
                    np.uint16(int(f32(invalid_depth) * f32(1000.0) + 0.5))
                    if depth.dtype == np.uint16
                    else f32(invalid_depth)
                )
            df = f32(d)
            out[v, u, 0] = (f32(u) - center_x) * df * constant_x
            out[v, u, 1] = (f32(v) - center_y) * df * constant_y
            out[v, u, 2] = df * unit
    return out


def _header(frame="depth_optical", sec=3, nanosec=4):
    return Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame)


# ------------------------------------------------------------------ numpy layer


def test_known_points_float_metres(make_info):
    info = make_info(width=8, height=6, fx=100.0, fy=50.0, cx=3.0, cy=2.0)
    depth = np.full((6, 8), 2.0, np.float32)
    points = depth_to_points(depth, info)
    assert points.shape == (6, 8, 3)
    assert points.dtype == np.float32
    # Pixel (u=7, v=0): x = (7 - 3) * 2 / 100, y = (0 - 2) * 2 / 50.
    np.testing.assert_allclose(points[0, 7], [0.08, -0.08, 2.0], rtol=1e-6)
    np.testing.assert_array_equal(points[2, 3], [0.0, 0.0, 2.0])


def test_millimetres_and_zero_is_invalid(make_info):
    info = make_info(width=4, height=3, fx=200.0, cx=1.0, cy=1.0)
    depth = np.array([[1000, 0, 1500, 65535]] * 3, np.uint16)
    points = depth_to_points(depth, info)
    np.testing.assert_allclose(points[1, 0], [-0.005, 0.0, 1.0], rtol=1e-6)
    assert np.isnan(points[:, 1]).all()
    assert points[1, 3, 2] == pytest.approx(65.535, rel=1e-6)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_invalid_float_depth_gives_nan_points(make_info, bad):
    info = make_info(width=5, height=4)
    depth = np.full((4, 5), 1.5, np.float32)
    depth[1, 2] = bad
    points = depth_to_points(depth, info)
    assert np.isnan(points[1, 2]).all()
    assert np.isfinite(np.delete(points.reshape(-1, 3), 1 * 5 + 2, axis=0)).all()


def test_invalid_depth_parameter_replaces_missing_points(make_info):
    info = make_info(width=5, height=4, fx=100.0, cx=2.0, cy=1.0)
    depth_m = np.full((4, 5), np.nan, np.float32)
    depth_mm = np.zeros((4, 5), np.uint16)
    for depth in (depth_m, depth_mm):
        points = depth_to_points(depth, info, invalid_depth=3.0)
        np.testing.assert_allclose(points[..., 2], 3.0, rtol=1e-6)
        np.testing.assert_allclose(points[0, 4], [0.06, -0.03, 3.0], rtol=1e-5)


@settings(max_examples=25, deadline=None)
@given(
    depth=hnp.arrays(
        np.float32,
        (5, 7),
        elements=st.one_of(
            st.floats(0.125, 50.0, width=32), st.sampled_from([0.0, np.nan, np.inf, -np.inf])
        ),
    ),
    fx=st.floats(50.0, 1000.0),
    cx=st.floats(-5.0, 10.0),
)
def test_property_matches_the_reference_loop_float(make_info, depth, fx, cx):
    model = PinholeCameraModel.from_camera_info(
        make_info(width=7, height=5, fx=fx, fy=fx * 1.1, cx=cx, cy=2.5)
    )
    np.testing.assert_allclose(
        depth_to_points(depth, model), _reference_points(depth, model), rtol=2e-6, atol=1e-30
    )


@settings(max_examples=25, deadline=None)
@given(
    depth=hnp.arrays(np.uint16, (4, 6)),
    invalid=st.sampled_from([0.0, 0.25, 4.0]),
)
def test_property_matches_the_reference_loop_uint16(make_info, depth, invalid):
    model = PinholeCameraModel.from_camera_info(make_info(width=6, height=4, fx=300.0))
    np.testing.assert_allclose(
        depth_to_points(depth, model, invalid_depth=invalid),
        _reference_points(depth, model, invalid),
        rtol=2e-6,
    )


@settings(max_examples=40, deadline=None)
@given(
    fx=st.floats(100.0, 1000.0),
    fy=st.floats(100.0, 1000.0),
    cx=st.floats(0.0, 30.0),
    cy=st.floats(0.0, 20.0),
    z=st.floats(0.125, 100.0, width=32),
)
def test_property_points_project_back_to_their_pixels(make_info, fx, fy, cx, cy, z):
    model = PinholeCameraModel.from_camera_info(
        make_info(width=24, height=16, fx=fx, fy=fy, cx=cx, cy=cy)
    )
    points = depth_to_points(np.full((16, 24), z, np.float32), model)
    uv = model.project_3d_to_pixel(points.reshape(-1, 3).astype(np.float64))
    us, vs = np.meshgrid(np.arange(24.0), np.arange(16.0))
    np.testing.assert_allclose(uv, np.stack((us.ravel(), vs.ravel()), 1), atol=1e-3)


def test_ray_tables(make_info):
    model = PinholeCameraModel.from_camera_info(
        make_info(width=4, height=2, fx=2.0, cx=1.0, cy=0.5)
    )
    rx, ry = depth_ray_tables(model)
    np.testing.assert_allclose(rx, [-0.5, 0.0, 0.5, 1.0])
    np.testing.assert_allclose(ry, [-0.25, 0.25])
    rx_mm, _ = depth_ray_tables(model, unit=0.001)
    np.testing.assert_allclose(rx_mm, rx * 0.001, rtol=1e-6)


def test_depth_errors(make_info):
    info = make_info(width=8, height=6)
    with pytest.raises(DepthImageError, match=r"4 x 3 .* describes 8 x 6"):
        depth_to_points(np.ones((3, 4), np.float32), info)
    with pytest.raises(DepthImageError, match="dtype float64"):
        depth_to_points(np.ones((6, 8)), info)
    with pytest.raises(CameraModelError):
        depth_to_points(np.ones((6, 8), np.float32), make_info(width=8, height=6, k=[0.0] * 9))


# --------------------------------------------------------------- message layer


def test_point_cloud_xyz_message(make_info):
    info = make_info(width=8, height=6, fx=100.0)
    depth = np.full((6, 8), 1.25, np.float32)
    depth[0, 0] = np.nan
    msg = numpy_to_image(depth, "32FC1", header=_header())
    cloud = point_cloud_xyz(msg, info)
    assert (cloud.height, cloud.width) == (6, 8)
    assert cloud.point_step == 16
    assert cloud.row_step == 16 * 8
    assert not cloud.is_dense
    assert cloud.header.frame_id == "depth_optical"
    assert (cloud.header.stamp.sec, cloud.header.stamp.nanosec) == (3, 4)
    assert [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields] == [
        ("x", 0, PointField.FLOAT32, 1),
        ("y", 4, PointField.FLOAT32, 1),
        ("z", 8, PointField.FLOAT32, 1),
    ]
    xyz = cloud_to_xyz(cloud, skip_nans=False)
    np.testing.assert_array_equal(xyz, depth_to_points(depth, info).reshape(-1, 3))
    assert cloud_to_xyz(cloud).shape == (47, 3)


def test_point_cloud_xyz_16uc1_and_caching(make_info):
    converter = PointCloudXyz()
    depth = np.full((6, 8), 2000, np.uint16)
    msg = numpy_to_image(depth, "16UC1", header=_header())
    cloud = converter.convert(msg, make_info(width=8, height=6))
    np.testing.assert_allclose(cloud_to_xyz(cloud)[:, 2], 2.0)
    tables = converter._tables_for(np.dtype(np.uint16))
    converter.convert(msg, make_info(width=8, height=6, stamp=(99, 0)))
    assert converter._tables_for(np.dtype(np.uint16)) is tables
    converter.convert(msg, make_info(width=8, height=6, fx=300.0))
    assert converter._tables_for(np.dtype(np.uint16)) is not tables
    assert converter.model.fx == 300.0
    points = converter.points(depth, make_info(width=8, height=6, fx=300.0))
    np.testing.assert_array_equal(points, depth_to_points(depth, converter.model))


def test_point_cloud_xyz_rejects_colour_on_depth_topic(make_info):
    msg = numpy_to_image(np.zeros((6, 8, 3), np.uint8), "rgb8")
    with pytest.raises(DepthImageError, match=r"'rgb8'.*16UC1.*32FC1"):
        point_cloud_xyz(msg, make_info(width=8, height=6))


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "rgba8", "bgra8", "mono8"])
def test_point_cloud_xyzrgb_colours(make_info, encoding):
    h, w = 4, 5
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    if encoding == "mono8":
        pixels = rgb[..., 0]
        expected = np.repeat(rgb[..., :1], 3, axis=2)
    else:
        pixels = rgb if encoding.startswith("rgb") else rgb[..., ::-1]
        expected = rgb
        if encoding.endswith("a8"):
            pixels = np.concatenate((pixels, np.full((h, w, 1), 7, np.uint8)), axis=2)
    colour = numpy_to_image(np.ascontiguousarray(pixels), encoding, header=_header())
    depth = numpy_to_image(np.full((h, w), 1.0, np.float32), "32FC1", header=_header())
    cloud = point_cloud_xyzrgb(depth, colour, make_info(width=w, height=h))
    assert cloud.point_step == 32
    assert [(f.name, f.offset) for f in cloud.fields] == [("x", 0), ("y", 4), ("z", 8), ("rgb", 16)]
    points = cloud_to_structured(cloud).reshape(h, w)
    np.testing.assert_array_equal(unpack_rgb(points["rgb"]), expected)
    np.testing.assert_allclose(points["z"], 1.0)


def test_point_cloud_xyzrgb_resizes_a_larger_colour_image(make_info):
    # Colour 16 x 12 with its camera; depth registered at half resolution (8 x 6).
    info = make_info(width=16, height=12, fx=40.0, cx=7.5, cy=5.5)
    colour = np.zeros((12, 16, 3), np.uint8)
    colour[:, 8:] = (255, 0, 0)
    depth = numpy_to_image(np.full((6, 8), 2.0, np.float32), "32FC1", header=_header())
    cloud = PointCloudXyzrgb().convert(
        depth, numpy_to_image(colour, "rgb8", header=_header()), info
    )
    assert (cloud.height, cloud.width) == (6, 8)
    points = cloud_to_structured(cloud).reshape(6, 8)
    rgb = unpack_rgb(points["rgb"])
    assert (rgb[:, 5:, 0] == 255).all()
    assert (rgb[:, :3, 0] == 0).all()
    # K and P scaled by 8 / 16: fx 20, cx 3.75.
    np.testing.assert_allclose(points["x"][0, 0], (0 - 3.75) * 2.0 / 20.0, rtol=1e-6)


def test_point_cloud_xyzrgb_errors_and_warning(make_info, caplog):
    info = make_info(width=8, height=6)
    depth = numpy_to_image(np.ones((6, 8), np.float32), "32FC1", header=_header("a"))
    with pytest.raises(DepthImageError, match="incompatible aspect"):
        point_cloud_xyzrgb(
            depth, numpy_to_image(np.zeros((2, 16, 3), np.uint8), "rgb8", header=_header("a")), info
        )
    with pytest.raises(DepthImageError, match="'mono16'"):
        point_cloud_xyzrgb(
            depth, numpy_to_image(np.zeros((6, 8), np.uint16), "mono16", header=_header("a")), info
        )
    with caplog.at_level(logging.WARNING, logger="visnav.perception.depth_image_proc"):
        point_cloud_xyzrgb(
            depth, numpy_to_image(np.zeros((6, 8, 3), np.uint8), "rgb8", header=_header("b")), info
        )
    assert "does not match" in caplog.text


# ------------------------------------------------------------------ convert_metric


def test_convert_metric_mm_to_m_and_back():
    mm = np.array([[0, 1, 1234, 65535]], np.uint16)
    metres = convert_metric(mm)
    assert metres.dtype == np.float32
    assert np.isnan(metres[0, 0])
    np.testing.assert_allclose(metres[0, 1:], [0.001, 1.234, 65.535], rtol=1e-6)
    metres = np.array([[np.nan, 1.2345, 0.0, -1.0, np.inf, 70.0, 65.5349]], np.float32)
    back = convert_metric(metres)
    assert back.dtype == np.uint16
    # NaN -> 0; truncation; values that do not fit uint16 -> 0.
    np.testing.assert_array_equal(back, [[0, 1234, 0, 0, 0, 0, 65534]])


@given(hnp.arrays(np.uint16, st.integers(1, 50)))
def test_property_convert_metric_round_trip_within_a_millimetre(mm):
    back = convert_metric(convert_metric(mm)).astype(int)
    # Truncation after float32 scaling loses at most one millimetre (as upstream).
    assert (np.abs(back - mm.astype(int)) <= 1).all()
    assert ((back == 0) == (mm == 0)).all()


def test_convert_metric_images_keep_the_header():
    msg = numpy_to_image(np.array([[1000, 0]], np.uint16), "16UC1", header=_header("d", 5, 6))
    out = convert_metric(msg)
    assert out.encoding == "32FC1"
    assert out.header.frame_id == "d"
    assert out.header.stamp.sec == 5
    values = image_to_numpy(out)
    assert values[0, 0] == pytest.approx(1.0)
    assert np.isnan(values[0, 1])
    assert convert_metric(out).encoding == "16UC1"
    with pytest.raises(DepthImageError, match="'mono8'"):
        convert_metric(numpy_to_image(np.zeros((2, 2), np.uint8), "mono8"))
    with pytest.raises(DepthImageError, match="dtype int32"):
        convert_metric(np.zeros((2, 2), np.int32))
