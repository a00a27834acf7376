"""RerunSink: every supported message type logs to a saved .rrd, read back and checked."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rerun")

from visnav.msgs import (
    CameraInfo,
    ColorRGBA,
    CompressedImage,
    LaserScan,
    MapMetaData,
    Marker,
    MarkerArray,
    OccupancyGrid,
    Odometry,
    Path,
    Point,
    Pose,
    PoseStamped,
    String,
    Vector3,
    make,
    numpy_to_image,
    pack_rgb,
    structured_to_cloud,
    xyz_to_cloud,
)
from visnav.perception.image_transport import compress, compress_depth
from visnav.tf import quaternion_from_euler, quaternion_to_matrix
from visnav.viz import SUPPORTED_TYPES, RerunSink, VizError

T0 = 1_000_000_000
MS = 1_000_000


def _static(vz: Any) -> Any:
    return vz.tf_msg(vz.tf("map", "odom", 0, (1.0, 0.0, 0.0)))


def test_image_encodings_log_with_the_right_archetype(session: Any, vz: Any) -> None:
    s = session(fixed_frame="cam", jpeg_quality=None)
    rgb = np.zeros((4, 6, 3), np.uint8)
    rgb[..., 0] = 200
    s.log("/cam/image_raw", numpy_to_image(rgb, "rgb8", header=vz.header("cam", T0)))
    s.log("/cam/image_mono", numpy_to_image(rgb[..., 0], "mono8", header=vz.header("cam", T0)))
    bayer = np.zeros((4, 6), np.uint8)
    s.log("/cam/image_bayer", numpy_to_image(bayer, "bayer_rggb8", header=vz.header("cam", T0)))
    depth = np.full((4, 6), 2.5, np.float32)
    s.log("/depth/image_raw", numpy_to_image(depth, "32FC1", header=vz.header("cam", T0)))
    mm = np.full((4, 6), 1500, np.uint16)
    s.log("/depth/image_mm", numpy_to_image(mm, "16UC1", header=vz.header("cam", T0)))
    yuv = np.zeros((4, 6, 2), np.uint8)
    s.log("/cam/image_yuv", numpy_to_image(yuv, "uyvy", header=vz.header("cam", T0)))
    rrd = s.finish()
    assert "Image:buffer" in rrd.columns("world/cameras/cam/image_raw")
    fmt = rrd.rows("world/cameras/cam/image_raw", "Image:format")[0][0]
    assert (fmt["width"], fmt["height"]) == (6, 4)
    assert "Image:buffer" in rrd.columns("world/cameras/cam/image_bayer")
    assert "Image:buffer" in rrd.columns("world/cameras/cam/image_yuv")  # converted to RGB
    meters = rrd.rows("world/cameras/depth/image_raw", "DepthImage:meter")
    assert meters == [[1000.0]]  # 32FC1 metres sent as 16-bit millimetres
    assert rrd.rows("world/cameras/depth/image_mm", "DepthImage:meter") == [[1000.0]]
    # The camera namespace entity is placed in the fixed frame (identity here).
    assert rrd.rows("world/cameras/cam", "Transform3D:translation")[0] == [[0.0, 0.0, 0.0]]


def test_colour_images_are_sent_as_jpeg_by_default(session: Any, vz: Any) -> None:
    import cv2

    s = session(fixed_frame="cam")
    rgb = np.zeros((48, 64, 3), np.uint8)
    rgb[..., 0] = 200  # red
    s.log("/cam/image_raw", numpy_to_image(rgb, "rgb8", header=vz.header("cam", T0)))
    s.log(
        "/cam/image_bgr", numpy_to_image(rgb[..., ::-1].copy(), "bgr8", header=vz.header("cam", T0))
    )
    depth = np.full((4, 6), 2.5, np.float32)
    depth[0, 0] = np.nan
    s.log("/depth/image_raw", numpy_to_image(depth, "32FC1", header=vz.header("cam", T0)))
    rrd = s.finish()
    for topic in ("image_raw", "image_bgr"):
        entity = f"world/cameras/cam/{topic}"
        assert rrd.rows(entity, "EncodedImage:media_type") == [["image/jpeg"]]
        blob = np.asarray(rrd.rows(entity, "EncodedImage:blob")[0], np.uint8).ravel().tobytes()
        assert len(blob) < rgb.nbytes / 10
        decoded = cv2.imdecode(np.frombuffer(blob, np.uint8), cv2.IMREAD_COLOR)
        assert abs(int(decoded[..., 2].mean()) - 200) <= 3  # red stays red (BGR order)
        assert int(decoded[..., 0].mean()) <= 3
    fmt = rrd.rows("world/cameras/depth/image_raw", "DepthImage:format")[0][0]
    assert (fmt["width"], fmt["height"]) == (6, 4)


def test_compressed_images_are_logged_encoded_and_depth_decoded(session: Any, vz: Any) -> None:
    s = session(fixed_frame="cam")
    img = numpy_to_image(np.full((8, 8, 3), 90, np.uint8), "bgr8", header=vz.header("cam", T0))
    s.log("/cam/image_raw/compressed", compress(img, format="jpeg"))
    s.log("/cam/image_png/compressed", compress(img, format="png"))
    depth = numpy_to_image(np.full((8, 8), 2.0, np.float32), "32FC1", header=vz.header("cam", T0))
    s.log("/depth/image_raw/compressedDepth", compress_depth(depth))
    bad = make(CompressedImage, header=vz.header("cam", T0), format="jpeg")
    bad.data = np.frombuffer(b"not an image", np.uint8)
    assert not s.log("/cam/broken/compressed", bad)
    rrd = s.finish()
    media = rrd.rows("world/cameras/cam/image_raw/compressed", "EncodedImage:media_type")
    assert media == [["image/jpeg"]]
    media = rrd.rows("world/cameras/cam/image_png/compressed", "EncodedImage:media_type")
    assert media == [["image/png"]]
    meter = rrd.rows("world/cameras/depth/image_raw/compressedDepth", "DepthImage:meter")
    assert meter == [[1000.0]]
    assert s.sink.errors == {"/cam/broken/compressed": 1}


def test_camera_info_becomes_a_pinhole_on_the_camera_frame(session: Any, vz: Any) -> None:
    s = session(fixed_frame="map")
    q = quaternion_from_euler(-math.pi / 2, 0.0, -math.pi / 2)  # optical frame under base
    s.log("/tf_static", vz.tf_msg(vz.tf("map", "cam_optical", 0, (0.5, 0.0, 1.0), q)))
    info = make(CameraInfo, header=vz.header("cam_optical", T0), width=640, height=480)
    info.k[:] = [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]
    s.log("/camera/camera_info", info)
    s.log("/camera/camera_info", info)  # unchanged: pinhole logged once
    img = numpy_to_image(np.zeros((480, 640, 3), np.uint8), "rgb8")
    img.header = vz.header("cam_optical", T0)
    s.log("/camera/image_raw", img)
    rrd = s.finish()
    k = rrd.rows("world/cameras/camera", "Pinhole:image_from_camera")
    assert len(k) == 1
    assert np.allclose(np.array(k[0][0]).reshape(3, 3).T, np.array(info.k).reshape(3, 3))
    assert rrd.rows("world/cameras/camera", "Pinhole:resolution") == [[[640.0, 480.0]]]
    translations = rrd.rows("world/cameras/camera", "Transform3D:translation")
    assert len(translations) == 2  # from camera_info only (the image does not re-place it)
    assert np.allclose(translations[0][0], [0.5, 0.0, 1.0])
    quat = rrd.rows("world/cameras/camera", "Transform3D:quaternion")[0][0]
    assert np.allclose(np.abs(np.dot(quat, q)), 1.0, atol=1e-6)
    assert rrd.entities >= {"world/cameras/camera/image_raw"}


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, -2.0])
def test_cloud_in_a_rotated_child_frame_lands_where_tf_puts_it(
    session: Any, vz: Any, yaw: float
) -> None:
    s = session(fixed_frame="map")
    q = quaternion_from_euler(0.3, -0.2, yaw)
    s.log("/tf_static", _static(vz))
    s.log("/tf", vz.tf_msg(vz.tf("odom", "base", T0, (2.0, -1.0, 0.5), q)))
    s.log("/tf", vz.tf_msg(vz.tf("odom", "base", T0 + 100 * MS, (3.0, -1.0, 0.5), q)))
    local = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]], np.float32)
    # Stamped halfway: TF interpolates x between 2 and 3.
    s.log("/points", xyz_to_cloud(local, header=vz.header("base", T0 + 50 * MS)))
    rrd = s.finish()
    got = np.array(rrd.rows("world/points", "Points3D:positions")[0])
    rot = quaternion_to_matrix(q)
    expected = local @ rot.T + np.array([1.0 + 2.5, -1.0, 0.5])
    assert np.allclose(got, expected, atol=1e-5)
    assert rrd.times("world/points", "Points3D:positions") == [T0 + 50 * MS]


def test_cloud_waits_for_tf_then_is_placed(session: Any, vz: Any) -> None:
    s = session(fixed_frame="odom")
    s.log("/tf", vz.tf_msg(vz.tf("odom", "base", T0, (1.0, 0.0, 0.0))))
    cloud = xyz_to_cloud(np.zeros((1, 3), np.float32), header=vz.header("base", T0 + 10 * MS))
    s.log("/points", cloud)  # newer than TF: queued (tf2 MessageFilter)
    assert s.sink.placer.pending == 1
    s.log("/tf", vz.tf_msg(vz.tf("odom", "base", T0 + 20 * MS, (2.0, 0.0, 0.0))))
    assert s.sink.placer.pending == 0
    old = xyz_to_cloud(np.zeros((1, 3), np.float32), header=vz.header("base", T0 - 10 * MS))
    s.log("/points", old)  # older than every TF sample: dropped with the reason
    rrd = s.finish()
    got = rrd.rows("world/points", "Points3D:positions")
    assert np.allclose(got, [[[1.5, 0.0, 0.0]]])
    stats = s.sink.stats()["/points"]
    assert stats["dropped"] == 1
    assert "past" in stats["reason"]
    assert "[base]" in stats["reason"]


def test_cloud_decimation_colours_and_nans(session: Any, vz: Any) -> None:
    s = session(fixed_frame="base", max_points=1000)
    n = 10_000
    xyz = np.random.default_rng(0).normal(size=(n, 3)).astype(np.float32)
    xyz[::7] = np.nan
    rgb = np.zeros((n, 3), np.uint8)
    rgb[:, 1] = 255
    dtype = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<f4")])
    arr = np.zeros(n, dtype)
    arr["x"], arr["y"], arr["z"] = xyz.T
    arr["rgb"] = pack_rgb(rgb)
    cloud = structured_to_cloud(arr, header=vz.header("base", T0))
    s.log("/cloud", cloud)
    rrd = s.finish()
    pts = np.array(rrd.rows("world/cloud", "Points3D:positions")[0])
    assert 0 < len(pts) <= 1000
    assert np.isfinite(pts).all()
    colors = rrd.rows("world/cloud", "Points3D:colors")[0]
    assert len(colors) == len(pts)
    assert {c & 0xFFFFFF00 for c in colors} == {0x00FF0000}  # packed RGBA: green


def test_laser_scan_points_in_the_scan_frame(session: Any, vz: Any) -> None:
    s = session(fixed_frame="base")
    s.log("/tf_static", vz.tf_msg(vz.tf("base", "laser", 0, (0.2, 0.0, 0.3))))
    scan = make(
        LaserScan,
        header=vz.header("laser", T0),
        angle_min=-math.pi / 2,
        angle_max=math.pi / 2,
        angle_increment=math.pi / 2,
        range_min=0.1,
        range_max=10.0,
        ranges=np.array([1.0, 2.0, math.inf], np.float32),
    )
    s.log("/scan", scan)
    rrd = s.finish()
    pts = np.array(rrd.rows("world/scan", "Points3D:positions")[0])
    assert np.allclose(pts, [[0.2, -1.0, 0.3], [2.2, 0.0, 0.3]], atol=1e-6)


def test_odometry_pose_and_path(session: Any, vz: Any) -> None:
    s = session(fixed_frame="map")
    s.log("/tf_static", _static(vz))
    for i in range(5):
        odom = make(Odometry, header=vz.header("odom", T0 + i * 100 * MS), child_frame_id="base")
        odom.pose.pose.position.x = 0.1 * i
        odom.pose.pose.orientation.w = 1.0
        s.log("/odom", odom)
    rrd = s.finish()
    origins = rrd.rows("world/odom", "Arrows3D:origins")
    assert len(origins) == 5
    assert np.allclose(origins[-1], [[1.4, 0.0, 0.0]])
    vectors = rrd.rows("world/odom", "Arrows3D:vectors")
    assert np.allclose(vectors[-1], [[0.5, 0.0, 0.0]])
    strips = rrd.rows("world/odom/path", "LineStrips3D:strips")
    assert len(strips) == 4  # from the second pose on
    assert np.allclose(strips[-1][0], [[1.0 + 0.1 * i, 0, 0] for i in range(5)])


def test_path_pose_stamped_and_occupancy_grid(session: Any, vz: Any) -> None:
    s = session(fixed_frame="map")
    s.log("/tf_static", _static(vz))
    path = make(Path, header=vz.header("odom", T0))
    for i in range(3):
        ps = make(PoseStamped, header=vz.header("odom", T0))
        ps.pose.position.x = float(i)
        ps.pose.orientation.w = 1.0
        path.poses.append(ps)
    s.log("/plan", path)
    goal = make(PoseStamped, header=vz.header("odom", T0))
    goal.pose.orientation.z, goal.pose.orientation.w = math.sin(0.5), math.cos(0.5)
    s.log("/goal", goal)
    grid = make(OccupancyGrid, header=vz.header("map", T0))
    grid.info = make(MapMetaData, resolution=0.05, width=4, height=3)
    grid.info.origin.position.x = -1.0
    grid.info.origin.orientation.w = 1.0
    grid.data = np.array([-1, 0, 100, 50] + [0] * 4 + [100] * 4, np.int8)  # rows 0, 1, 2
    s.log("/map", grid)
    rrd = s.finish()
    strip = rrd.rows("world/plan", "LineStrips3D:strips")[0][0]
    assert np.allclose(strip, [[1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    vec = rrd.rows("world/goal", "Arrows3D:vectors")[0][0]
    assert np.allclose(vec, [0.5 * math.cos(1.0), 0.5 * math.sin(1.0), 0.0], atol=1e-6)
    assert rrd.rows("world/map", "GridMap:cell_size") == [[pytest.approx(0.05)]]
    assert np.allclose(rrd.rows("world/map", "GridMap:translation")[0], [[-1.0, 0.0, 0.0]])
    data = bytes(rrd.rows("world/map", "GridMap:data")[0][0])
    # Rerun draws row 0 at the top (image order); ROS row 0 is at the origin: rows flipped.
    assert data == bytes([100] * 4 + [0] * 4 + [255, 0, 100, 50])


def _marker(kind: int, mid: int, **fields: Any) -> Marker:
    m = make(Marker, ns="test", id=mid, type=kind, action=0)
    m.header.frame_id = "odom"
    m.header.stamp.sec = 1
    m.pose.orientation.w = 1.0
    m.scale = Vector3(x=0.2, y=0.4, z=0.6)
    m.color = ColorRGBA(r=1.0, g=0.0, b=0.0, a=1.0)
    for k, v in fields.items():
        setattr(m, k, v)
    return m


def test_marker_types_and_deletion(session: Any, vz: Any) -> None:
    s = session(fixed_frame="map")
    s.log("/tf_static", _static(vz))
    pts = [Point(x=0.0, y=0.0, z=0.0), Point(x=1.0, y=0.0, z=0.0), Point(x=1.0, y=1.0, z=0.0)]
    markers = [
        _marker(0, 0),
        _marker(0, 1, points=pts[:2]),
        _marker(1, 2),
        _marker(2, 3),
        _marker(3, 4),
        _marker(4, 5, points=pts),
        _marker(5, 6, points=pts[:2]),
        _marker(6, 7, points=pts),
        _marker(7, 8, points=pts),
        _marker(8, 9, points=pts, colors=[ColorRGBA(r=0.0, g=1.0, b=0.0, a=1.0)] * 3),
        _marker(9, 10, text="hello"),
        _marker(11, 11, points=pts),
        _marker(10, 12, mesh_resource="package://robot/mesh.dae"),
    ]
    markers[2].pose.orientation = make(type(markers[2].pose.orientation))  # all-zero quaternion
    s.log("/markers", MarkerArray(markers=markers))
    expected = {
        0: "Arrows3D:vectors",
        1: "Arrows3D:vectors",
        2: "Boxes3D:half_sizes",
        3: "Ellipsoids3D:half_sizes",
        4: "Cylinders3D:lengths",
        5: "LineStrips3D:strips",
        6: "LineStrips3D:strips",
        7: "Boxes3D:centers",
        8: "Ellipsoids3D:centers",
        9: "Points3D:positions",
        10: "Points3D:labels",
        11: "Mesh3D:vertex_positions",
    }
    delete = _marker(2, 3, action=2)
    s.log("/markers", MarkerArray(markers=[delete]))
    rrd = s.finish()
    for mid, column in expected.items():
        assert column in rrd.columns(f"world/markers/test/{mid}"), (mid, column)
    assert "world/markers/test/12" not in rrd.entities  # MESH_RESOURCE: not shown
    arrow = rrd.rows("world/markers/test/0", "Arrows3D:vectors")[0]
    assert np.allclose(arrow, [[0.2, 0.0, 0.0]])  # scale.x long along the pose x axis
    origin = rrd.rows("world/markers/test/1", "Arrows3D:origins")[0]
    assert np.allclose(origin, [[1.0, 0.0, 0.0]])  # points are in odom, odom at x=1 in map
    box = rrd.rows("world/markers/test/2", "Boxes3D:half_sizes")[0]
    assert np.allclose(box, [[0.1, 0.2, 0.3]])
    assert rrd.rows("world/markers/test/10", "Points3D:labels")[0] == ["hello"]
    assert "Clear:is_recursive" in rrd.columns("world/markers/test/3")


def test_unsupported_types_and_strict_mode(session: Any, vz: Any) -> None:
    s = session()
    assert not s.log("/chatter", String(data="hi"))
    bad = xyz_to_cloud(np.zeros((2, 3), np.float32), header=vz.header("base", T0))
    bad.data = bad.data[:10]
    assert not s.log("/cloud", bad)
    stats = s.sink.stats()
    assert stats["/chatter"]["supported"] is False
    assert stats["/cloud"]["errors"] == 1
    s.finish()
    strict = session(strict=True)
    with pytest.raises(ValueError, match="PointCloud2"):
        strict.log("/cloud", bad)
    strict.finish()
    assert RerunSink.supports("sensor_msgs/msg/Image")
    assert len(SUPPORTED_TYPES) == 14  # String: robot_description only


def test_auto_fixed_frame_is_the_tf_root_and_tf_frames_are_entities(session: Any, vz: Any) -> None:
    s = session()
    s.log("/tf_static", _static(vz))
    s.log("/tf", vz.tf_msg(vz.tf("odom", "robot1/base", T0, (0.0, 2.0, 0.0))))
    cloud = xyz_to_cloud(np.zeros((1, 3), np.float32), header=vz.header("robot1/base", T0))
    s.log("/points", cloud)
    rrd = s.finish()
    assert s.sink.fixed_frame == "map"
    assert {"world/tf/map", "world/tf/odom", "world/tf/robot1\\/base"} <= rrd.entities
    base = rrd.rows("world/tf/robot1\\/base", "Transform3D:translation")
    assert np.allclose(base[-1], [[1.0, 2.0, 0.0]])
    assert "TransformAxes3D:axis_length" in rrd.columns("world/tf/odom")
    assert np.allclose(rrd.rows("world/points", "Points3D:positions")[0], [[1.0, 2.0, 0.0]])


def test_data_without_any_tf_is_shown_in_its_own_frame(session: Any, vz: Any) -> None:
    s = session(queue_size=2)
    for i in range(3):
        cloud = xyz_to_cloud(np.ones((1, 3), np.float32), header=vz.header("lidar", T0 + i))
        s.log("/points", cloud)
    rrd = s.finish()
    assert s.sink.fixed_frame == "lidar"
    assert len(rrd.rows("world/points", "Points3D:positions")) == 3


def test_sink_rejects_bad_options(session: Any) -> None:
    with pytest.raises(VizError, match="max_points"):
        session(max_points=0)
    with pytest.raises(VizError, match="leading '/'"):
        session(fixed_frame="/map")


def test_headerless_messages_use_the_given_stamp(session: Any, vz: Any) -> None:
    s = session(fixed_frame="map")
    s.log("/tf_static", vz.tf_msg(vz.tf("map", "odom", 0)), stamp_ns=5 * T0)
    rrd = s.finish()
    assert rrd.times("world/tf/odom", "Transform3D:translation") == [5 * T0]


def test_pose_quaternion_zero_is_identity(session: Any, vz: Any) -> None:
    s = session(fixed_frame="map")
    goal = make(PoseStamped, header=vz.header("map", T0), pose=make(Pose))
    s.log("/goal", goal)
    rrd = s.finish()
    assert np.allclose(rrd.rows("world/goal", "Arrows3D:vectors")[0], [[0.5, 0.0, 0.0]])


def test_cameras_never_nest(session: Any, vz: Any) -> None:
    s = session(fixed_frame="cam")
    for topic in ("/depth_camera/camera_info", "/depth_camera/depth/camera_info"):
        info = make(CameraInfo, header=vz.header("cam", T0), width=4, height=4)
        info.k[:] = [2.0, 0.0, 2.0, 0.0, 2.0, 2.0, 0.0, 0.0, 1.0]
        s.log(topic, info)
    depth = numpy_to_image(np.ones((4, 4), np.float32), "32FC1", header=vz.header("cam", T0))
    s.log("/depth_camera/depth/image_raw", depth)
    rrd = s.finish()
    assert "Pinhole:image_from_camera" in rrd.columns("world/cameras/depth_camera")
    assert "Pinhole:image_from_camera" in rrd.columns("world/cameras/depth_camera\\/depth")
    assert "DepthImage:buffer" in rrd.columns("world/cameras/depth_camera\\/depth/image_raw")
