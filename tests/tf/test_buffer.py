"""Tests of visnav.tf.Buffer: tf2 lookup semantics, errors, introspection, threads."""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from pytransform3d.transform_manager import TransformManager
from scipy.spatial.transform import Rotation, Slerp

from visnav.msgs import Duration, Header, Quaternion, Time, Transform, TransformStamped, Vector3
from visnav.tf import (
    Buffer,
    ConnectivityException,
    ExtrapolationException,
    InvalidArgumentException,
    LookupException,
    TransformException,
)
from visnav.tf.transforms import (
    euler_from_quaternion,
    invert,
    matrix_to_transform,
    quaternion_from_euler,
    transform_to_matrix,
    translation_quaternion_to_matrix,
)

S = 1_000_000_000


def tf(
    parent: str,
    child: str,
    stamp_ns: int = 0,
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
    q: tuple[float, float, float, float] | NDArray[np.float64] = (0.0, 0.0, 0.0, 1.0),
) -> TransformStamped:
    sec, nsec = divmod(stamp_ns, S)
    return TransformStamped(
        Header(Time(sec, nsec), parent),
        child,
        Transform(Vector3(*map(float, xyz)), Quaternion(*map(float, q))),
    )


def yaw_q(yaw: float) -> NDArray[np.float64]:
    return quaternion_from_euler(0.0, 0.0, yaw)


def matrix_of(msg: TransformStamped) -> NDArray[np.float64]:
    return transform_to_matrix(msg)


@pytest.fixture
def robot() -> Buffer:
    """map -> odom (10 Hz, 0..9.9 s) -> base_link (50 Hz, 0..9.98 s) -> camera -> optical."""
    buf = Buffer()
    for i in range(100):
        buf.set_transform(
            tf("map", "odom", i * S // 10, (0.01 * i, 0, 0), yaw_q(0.001 * i)), "slam"
        )
    for i in range(500):
        buf.set_transform(
            tf("odom", "base_link", i * S // 50, (0.1 * i, 0.2, 0), yaw_q(0.01 * i)), "odom_node"
        )
    buf.set_transform_static(tf("base_link", "camera", 0, (0.1, 0, 0.5)), "rsp")
    buf.set_transform_static(
        tf("camera", "camera_optical", 0, (0, 0, 0), (-0.5, 0.5, -0.5, 0.5)), "rsp"
    )
    return buf


# ---------------------------------------------------------------- chains and branches


def test_static_chain_equals_matrix_product() -> None:
    buf = Buffer()
    links = [
        ("map", "a", (1, 2, 3), quaternion_from_euler(0.1, 0.2, 0.3)),
        ("a", "b", (-1, 0, 2), quaternion_from_euler(-0.5, 0.0, 1.0)),
        ("b", "c", (0, 4, 0), quaternion_from_euler(0.0, 1.2, -0.3)),
    ]
    expected = np.eye(4)
    for parent, child, xyz, q in links:
        assert buf.set_transform_static(tf(parent, child, 0, xyz, q), "test")
        expected = expected @ translation_quaternion_to_matrix(xyz, q)
    msg = buf.lookup_transform("map", "c")
    assert msg.header.frame_id == "map"
    assert msg.child_frame_id == "c"
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 0)  # all static: time 0
    np.testing.assert_allclose(matrix_of(msg), expected, atol=1e-12)
    np.testing.assert_allclose(buf.lookup_transform_matrix("map", "c"), expected, atol=1e-12)
    np.testing.assert_allclose(
        buf.lookup_transform_matrix("c", "map"), invert(expected), atol=1e-12
    )
    # Target is the parent of the source and vice versa.
    T_a_b = translation_quaternion_to_matrix(links[1][2], links[1][3])
    np.testing.assert_allclose(buf.lookup_transform_matrix("a", "b"), T_a_b, atol=1e-12)
    np.testing.assert_allclose(buf.lookup_transform_matrix("b", "a"), invert(T_a_b), atol=1e-12)


def test_branch_goes_through_common_ancestor() -> None:
    buf = Buffer()
    T_base_left = translation_quaternion_to_matrix([0, 0.5, 0], yaw_q(0.3))
    T_base_right = translation_quaternion_to_matrix([0, -0.5, 0], yaw_q(-0.3))
    buf.set_transform_static(tf("world", "base", 0, (5, 5, 0), yaw_q(1.0)), "t")
    buf.set_transform_static(tf("base", "left", 0, (0, 0.5, 0), yaw_q(0.3)), "t")
    buf.set_transform_static(tf("base", "right", 0, (0, -0.5, 0), yaw_q(-0.3)), "t")
    np.testing.assert_allclose(
        buf.lookup_transform_matrix("left", "right"), invert(T_base_left) @ T_base_right, atol=1e-12
    )
    # A point 1 m ahead of the right wheel, seen from the left wheel.
    p_left = buf.lookup_transform_matrix("left", "right") @ [1, 0, 0, 1]
    p_base = T_base_right @ [1, 0, 0, 1]
    np.testing.assert_allclose(T_base_left @ p_left, p_base, atol=1e-12)


def test_self_transform_is_identity() -> None:
    buf = Buffer()
    buf.set_transform(tf("odom", "base", 3 * S), "t")
    buf.set_transform(tf("odom", "base", 4 * S), "t")
    msg = buf.lookup_transform("base", "base")
    np.testing.assert_array_equal(matrix_of(msg), np.eye(4))
    assert msg.header.stamp.sec == 4  # time 0 resolves to the frame's newest stamp, as tf2
    assert buf.lookup_transform("base", "base", 7 * S).header.stamp.sec == 7
    # tf2 answers identity for a self-transform even of an unknown frame.
    np.testing.assert_array_equal(buf.lookup_transform_matrix("nowhere", "nowhere"), np.eye(4))
    assert buf.can_transform("nowhere", "nowhere")


# ---------------------------------------------------------------- time: interpolation, time 0


def test_exact_stamps_need_no_interpolation(robot: Buffer) -> None:
    msg = robot.lookup_transform("odom", "base_link", 2 * S)  # sample i = 100
    t = msg.transform.translation
    assert (t.x, t.y, t.z) == (10.0, 0.2, 0.0)
    q = msg.transform.rotation
    np.testing.assert_allclose([q.x, q.y, q.z, q.w], yaw_q(1.0), atol=1e-15)


def test_interpolation_between_samples(robot: Buffer) -> None:
    # Between i = 100 (2.00 s) and 101 (2.02 s), a quarter of the way.
    msg = robot.lookup_transform("odom", "base_link", 2 * S + 5_000_000)
    t = msg.transform.translation
    assert t.x == pytest.approx(10.025, abs=1e-12)
    assert t.y == pytest.approx(0.2, abs=1e-15)
    q = msg.transform.rotation
    assert euler_from_quaternion([q.x, q.y, q.z, q.w])[2] == pytest.approx(1.0025, abs=1e-12)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (2, 5_000_000)


def test_chain_interpolates_every_dynamic_link(robot: Buffer) -> None:
    t = 5_555_000_000
    T_map_odom = translation_quaternion_to_matrix([0.05555 * 10, 0, 0], yaw_q(0.05555))
    T_odom_base = translation_quaternion_to_matrix([0.1 * 277.75, 0.2, 0], yaw_q(2.7775))
    T_base_optical = translation_quaternion_to_matrix([0.1, 0, 0.5], [-0.5, 0.5, -0.5, 0.5])
    np.testing.assert_allclose(
        robot.lookup_transform_matrix("map", "camera_optical", t),
        T_map_odom @ T_odom_base @ T_base_optical,
        atol=1e-9,
    )


def test_time_zero_is_latest_common_time(robot: Buffer) -> None:
    # map->odom ends at 9.9 s, odom->base_link at 9.98 s, the camera links are static.
    assert robot.lookup_transform("map", "camera_optical").header.stamp == Time(9, 900_000_000)
    assert robot.lookup_transform("odom", "camera_optical").header.stamp == Time(9, 980_000_000)
    assert robot.lookup_transform("camera_optical", "odom").header.stamp == Time(9, 980_000_000)
    assert robot.lookup_transform("camera", "camera_optical").header.stamp == Time(0, 0)
    np.testing.assert_allclose(
        robot.lookup_transform_matrix("map", "camera_optical"),
        robot.lookup_transform_matrix("map", "camera_optical", 9_900_000_000),
        atol=1e-15,
    )


def test_time_zero_uses_only_links_below_common_ancestor() -> None:
    buf = Buffer()
    buf.set_transform(tf("map", "odom", 1 * S), "t")  # above the common ancestor: ignored
    buf.set_transform(tf("odom", "a", 5 * S), "t")
    buf.set_transform(tf("odom", "b", 5 * S), "t")
    buf.set_transform(tf("odom", "b", 8 * S), "t")
    buf.set_transform(tf("odom", "a", 6 * S), "t")
    assert buf.lookup_transform("a", "b").header.stamp.sec == 6


def test_time_arguments() -> None:
    buf = Buffer()
    buf.set_transform(tf("odom", "base", 1 * S, (1, 0, 0)), "t")
    buf.set_transform(tf("odom", "base", 3 * S, (3, 0, 0)), "t")
    assert buf.lookup_transform("odom", "base", Time(2, 0)).transform.translation.x == 2.0
    assert buf.lookup_transform("odom", "base", np.int64(2 * S)).transform.translation.x == 2.0

    @dataclass
    class RclpyTime:  # the shape of rclpy.time.Time
        nanoseconds: int

    assert buf.lookup_transform("odom", "base", RclpyTime(2 * S)).transform.translation.x == 2.0
    with pytest.raises(InvalidArgumentException, match="sec_to_ns"):
        buf.lookup_transform("odom", "base", 2.0)  # type: ignore[arg-type]
    with pytest.raises(InvalidArgumentException, match=">= 0"):
        buf.lookup_transform("odom", "base", -5)
    with pytest.raises(InvalidArgumentException, match="nanosec"):
        buf.lookup_transform("odom", "base", Time(1, 2 * S))


# ---------------------------------------------------------------- errors


def test_extrapolation_into_the_future(robot: Buffer) -> None:
    with pytest.raises(ExtrapolationException) as info:
        robot.lookup_transform("map", "camera_optical", 9_950_000_000)
    err = info.value
    text = str(err)
    assert "future" in text
    assert "9.950000" in text
    assert "9.900000" in text  # the latest data of the failing link (odom)
    assert "[odom]" in text
    assert "from frame [camera_optical] to frame [map]" in text
    assert (err.direction, err.frame) == ("future", "odom")
    assert (err.requested_ns, err.latest_ns, err.earliest_ns) == (9_950_000_000, 9_900_000_000, 0)


def test_extrapolation_into_the_past() -> None:
    buf = Buffer()
    buf.set_transform(tf("odom", "base", 5 * S), "t")
    buf.set_transform(tf("odom", "base", 6 * S), "t")
    with pytest.raises(ExtrapolationException, match="past") as info:
        buf.lookup_transform("base", "odom", 4 * S)
    assert "earliest data" in str(info.value)
    assert "started publishing later" in str(info.value)
    assert "4.000000" in str(info.value)
    assert "5.000000" in str(info.value)
    assert "from frame [odom] to frame [base]" in str(info.value)
    assert info.value.direction == "past"
    assert not buf.can_transform("base", "odom", 4 * S)
    ok, reason = buf.can_transform("base", "odom", 4 * S, return_debug_tuple=True)
    assert not ok
    assert "past" in reason
    assert buf.can_transform("base", "odom", 5_500_000_000, return_debug_tuple=True) == (True, "")


def test_extrapolation_with_a_single_sample() -> None:
    buf = Buffer()
    buf.set_transform(tf("odom", "base", 5 * S), "t")
    assert buf.can_transform("odom", "base", 5 * S)
    with pytest.raises(ExtrapolationException, match="one sample only") as info:
        buf.lookup_transform("odom", "base", 6 * S)
    assert info.value.direction == "single"


def test_connectivity_error_between_two_trees() -> None:
    buf = Buffer()
    buf.set_transform_static(tf("map", "odom"), "t")
    buf.set_transform_static(tf("odom", "base"), "t")
    buf.set_transform_static(tf("world", "camera"), "t")
    with pytest.raises(ConnectivityException) as info:
        buf.lookup_transform("base", "camera")
    err = info.value
    assert "'base'" in str(err)
    assert "'camera'" in str(err)
    assert "unconnected trees" in str(err)
    assert (err.target_root, err.source_root) == ("map", "world")
    assert isinstance(err, TransformException)
    with pytest.raises(ConnectivityException):
        buf.lookup_transform("base", "camera", 3 * S)  # the walk, not only time 0
    assert not buf.can_transform("base", "camera")


def test_unknown_frame_suggests_closest_names(robot: Buffer) -> None:
    with pytest.raises(LookupException) as info:
        robot.lookup_transform("map", "base_lnik")
    err = info.value
    assert isinstance(err, LookupError)
    assert err.frame == "base_lnik"
    assert err.suggestions[0] == "base_link"
    assert '"base_lnik"' in str(err)
    assert "source_frame" in str(err)
    assert '"base_link"' in str(err)
    with pytest.raises(LookupException) as info:
        robot.lookup_transform("MAP", "base_link")
    assert "map" in info.value.suggestions
    ok, reason = robot.can_transform("map", "base_lnik", return_debug_tuple=True)
    assert not ok
    assert "base_link" in reason


def test_unknown_frame_in_an_empty_buffer() -> None:
    with pytest.raises(LookupException, match="holds no frames yet"):
        Buffer().lookup_transform("map", "base_link")


def test_leading_slash_is_refused_in_lookups(robot: Buffer) -> None:
    with pytest.raises(InvalidArgumentException, match="cannot start with a '/'") as info:
        robot.lookup_transform("/map", "base_link")
    assert isinstance(info.value, ValueError)
    assert 'use "map" (a known frame)' in str(info.value)
    with pytest.raises(InvalidArgumentException, match="'/'"):
        robot.lookup_transform("/base_link", "/base_link")
    with pytest.raises(InvalidArgumentException, match="empty"):
        robot.lookup_transform("map", "")
    ok, reason = robot.can_transform("/map", "base_link", return_debug_tuple=True)
    assert not ok
    assert "'/'" in reason


def test_leading_slash_is_stripped_on_insert() -> None:
    buf = Buffer()
    assert buf.set_transform_static(tf("/map", "/odom", 0, (1, 0, 0)), "ros1_bridge")
    assert buf.get_frames() == ["odom", "map"]
    assert buf.lookup_transform("map", "odom").transform.translation.x == 1.0


# ---------------------------------------------------------------- insertion rules


def test_rejected_transforms(caplog: pytest.LogCaptureFixture) -> None:
    buf = Buffer()
    with caplog.at_level(logging.ERROR, logger="visnav.tf"):
        assert not buf.set_transform(tf("a", "b", S, (math.nan, 0, 0)), "bad_node")
        assert not buf.set_transform(tf("a", "b", S, (0, 0, 0), (0, 0, 0, 1.2)), "bad_node")
        assert not buf.set_transform(tf("a", "a", S), "bad_node")
        assert not buf.set_transform(tf("a", "", S), "bad_node")
        assert not buf.set_transform(tf("", "b", S), "bad_node")
    codes = [r.getMessage().split(":")[0] for r in caplog.records]
    assert codes == [
        "TF_NAN_INPUT",
        "TF_DENORMALIZED_QUATERNION",
        "TF_SELF_TRANSFORM",
        "TF_NO_CHILD_FRAME_ID",
        "TF_NO_FRAME_ID",
    ]
    assert "bad_node" in caplog.records[0].getMessage()
    assert buf.get_frames() == []
    with pytest.raises(InvalidArgumentException, match="TF_DENORMALIZED_QUATERNION"):
        buf.set_transform(tf("a", "b", S, (0, 0, 0), (0, 0, 0, 0)), "bad_node", strict=True)


def test_slightly_denormalised_quaternion_is_accepted_and_normalised() -> None:
    buf = Buffer()
    # squared norm 1.004: inside tf2's tolerance of 0.01
    assert buf.set_transform_static(tf("a", "b", 0, (0, 0, 0), (0, 0, 0, math.sqrt(1.004))), "t")
    q = buf.lookup_transform("a", "b").transform.rotation
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)


def test_cache_pruning_and_old_data(caplog: pytest.LogCaptureFixture) -> None:
    buf = Buffer(cache_time=1.0)
    for i in range(31):  # 0 .. 3.0 s at 10 Hz
        assert buf.set_transform(tf("odom", "base", i * S // 10, (0.1 * i, 0, 0)), "t")
    info = buf.frame_infos()["base"]
    assert (info.oldest_ns, info.most_recent_ns, info.num_samples) == (2 * S, 3 * S, 11)
    assert buf.lookup_transform("odom", "base", 2 * S).transform.translation.x == pytest.approx(2.0)
    with pytest.raises(ExtrapolationException, match=r"past.*larger cache_time"):
        buf.lookup_transform("odom", "base", 1_900_000_000)
    with caplog.at_level(logging.WARNING, logger="visnav.tf"):
        assert not buf.set_transform(tf("odom", "base", 1 * S), "late_node")
    assert "TF_OLD_DATA" in caplog.text
    assert "late_node" in caplog.text
    # Older than the newest but inside the window: inserted in order.
    assert buf.set_transform(tf("odom", "base", 2_050_000_000, (99, 0, 0)), "t")
    assert buf.lookup_transform("odom", "base", 2_050_000_000).transform.translation.x == 99.0
    assert buf.frame_infos()["base"].num_samples == 12
    assert Buffer(Duration(sec=2, nanosec=0)).cache_time_ns == 2 * S
    with pytest.raises(InvalidArgumentException, match="cache_time"):
        Buffer(-1.0)


def test_same_stamp_later_insertion_wins() -> None:
    buf = Buffer()
    buf.set_transform(tf("odom", "base", 1 * S, (1, 0, 0)), "t")
    buf.set_transform(tf("odom", "base", 2 * S, (2, 0, 0)), "t")
    buf.set_transform(tf("odom", "base", 1 * S, (5, 0, 0)), "t")
    assert buf.lookup_transform("odom", "base", 1 * S).transform.translation.x == 5.0
    assert buf.frame_infos()["base"].num_samples == 2


def test_static_and_dynamic_mixing() -> None:
    buf = Buffer(cache_time=1.0)
    buf.set_transform_static(tf("base", "laser", 0, (0.2, 0, 0.1)), "rsp")
    buf.set_transform(tf("odom", "base", 10 * S, (1, 0, 0)), "odom")
    buf.set_transform(tf("odom", "base", 11 * S, (2, 0, 0)), "odom")
    # The static link is valid at any time; the dynamic one bounds the chain.
    assert buf.lookup_transform("odom", "laser", 10_500_000_000).transform.translation.x == 1.7
    assert buf.lookup_transform("base", "laser", 123 * S).transform.translation.x == 0.2
    assert buf.lookup_transform("odom", "laser").header.stamp.sec == 11
    # A static transform for a child replaces its dynamic cache, and vice versa.
    buf.set_transform_static(tf("odom", "base", 0, (7, 0, 0)), "fixed")
    assert buf.lookup_transform("odom", "base", 500 * S).transform.translation.x == 7.0
    assert buf.frame_infos()["base"].is_static
    buf.set_transform(tf("odom", "base", 20 * S, (8, 0, 0)), "odom")
    assert not buf.can_transform("odom", "base", 500 * S)
    # A later static transform replaces the earlier one.
    buf.set_transform_static(tf("base", "laser", 0, (0.3, 0, 0.1)), "rsp")
    assert buf.lookup_transform("base", "laser").transform.translation.x == 0.3


def test_reparenting_is_per_sample() -> None:
    buf = Buffer()
    buf.set_transform_static(tf("world", "a", 0, (10, 0, 0)), "t")
    buf.set_transform_static(tf("world", "b", 0, (20, 0, 0)), "t")
    buf.set_transform(tf("a", "obj", 1 * S, (1, 0, 0)), "t")  # held by a
    buf.set_transform(tf("b", "obj", 3 * S, (3, 0, 0)), "t")  # handed to b
    x = lambda t: buf.lookup_transform("world", "obj", t).transform.translation.x  # noqa: E731
    assert x(1 * S) == 11.0
    assert x(2 * S) == 11.0  # parents differ across the gap: the older sample, not a blend
    assert x(3 * S) == 23.0
    assert buf.get_parent("obj", 1 * S) == "a"
    assert buf.get_parent("obj") == "b"
    assert buf.frame_infos()["obj"].parent == "b"


def test_loop_is_reported() -> None:
    buf = Buffer()
    buf.set_transform(tf("a", "b", S), "t")
    buf.set_transform(tf("b", "a", S), "t")
    buf.set_transform_static(tf("x", "y"), "t")
    with pytest.raises(LookupException, match="loop"):
        buf.lookup_transform("y", "a")
    with pytest.raises(LookupException, match="loop"):
        buf.lookup_transform("a", "y", S)


# ---------------------------------------------------------------- lookup_transform_full


def test_lookup_transform_full_where_was_the_object() -> None:
    # The robot drives along x in odom at 1 m/s, turning 90 degrees between 1 s and 2 s.
    buf = Buffer()
    buf.set_transform(tf("odom", "base_link", 0, (0, 0, 0)), "odom")
    buf.set_transform(tf("odom", "base_link", 1 * S, (1, 0, 0)), "odom")
    buf.set_transform(tf("odom", "base_link", 2 * S, (2, 0, 0), yaw_q(math.pi / 2)), "odom")
    # At t = 1 s the robot saw an object 1 m ahead (x = 2 in odom). Where is it now (t = 2 s),
    # in the robot's frame? The robot is at x = 2 facing +y: the object is under it.
    msg = buf.lookup_transform_full("base_link", 2 * S, "base_link", 1 * S, "odom")
    T = matrix_of(msg)
    np.testing.assert_allclose(T @ [1, 0, 0, 1], [0, 0, 0, 1], atol=1e-12)
    assert msg.header.stamp.sec == 2
    # Target time 0 resolves to the latest time of the target half (2 s).
    T2 = buf.lookup_transform_full_matrix("base_link", 0, "base_link", 1 * S, "odom")
    np.testing.assert_allclose(T2, T, atol=1e-12)
    # The same point relative to the robot at 0.5 s (x = 0.5, facing +x).
    T3 = buf.lookup_transform_full_matrix("base_link", S // 2, "base_link", 1 * S, "odom")
    np.testing.assert_allclose(T3 @ [1, 0, 0, 1], [1.5, 0, 0, 1], atol=1e-12)
    assert buf.can_transform_full("base_link", 2 * S, "base_link", 1 * S, "odom")
    ok, reason = buf.can_transform_full(
        "base_link", 3 * S, "base_link", 1 * S, "odom", return_debug_tuple=True
    )
    assert not ok
    assert "future" in reason
    with pytest.raises(LookupException, match="fixed_frame"):
        buf.lookup_transform_full("base_link", 0, "base_link", 0, "mapp")


# ---------------------------------------------------------------- introspection


def test_all_frames_as_yaml(robot: Buffer) -> None:
    text = robot.all_frames_as_yaml()
    data = yaml.safe_load(text)
    assert list(data) == ["odom", "base_link", "camera", "camera_optical"]
    assert data["odom"] == {
        "parent": "map",
        "broadcaster": "slam",
        "rate": pytest.approx(100 / 9.9, abs=1e-3),
        "most_recent_transform": 9.9,
        "oldest_transform": 0.0,
        "buffer_length": 9.9,
    }
    assert data["camera"]["rate"] == 10000.0  # tf2's figure for a static frame
    assert data["camera"]["broadcaster"] == "rsp"
    assert "  most_recent_transform: 9.900000\n" in text
    assert "  rate: 10.101\n" in text
    delayed = yaml.safe_load(robot.all_frames_as_yaml(current_time=10 * S))
    assert delayed["odom"]["transform_delay"] == pytest.approx(0.1)
    assert Buffer().all_frames_as_yaml() == "[]"


def test_all_frames_as_string_and_frames(robot: Buffer) -> None:
    assert robot.all_frames_as_string().splitlines() == [
        "Frame odom exists with parent map.",
        "Frame base_link exists with parent odom.",
        "Frame camera exists with parent base_link.",
        "Frame camera_optical exists with parent camera.",
    ]
    assert robot.get_frames() == ["odom", "map", "base_link", "camera", "camera_optical"]
    assert robot.has_frame("map")
    assert not robot.has_frame("mapp")
    assert robot.get_parent("map") is None
    robot.clear()  # as tf2's BufferCore::clear: dynamic data dropped, static kept
    assert robot.all_frames_as_string().splitlines() == [
        "Frame camera exists with parent base_link.",
        "Frame camera_optical exists with parent camera.",
    ]
    assert robot.can_transform("base_link", "camera_optical")
    assert not robot.can_transform("map", "base_link")
    assert robot.has_frame("map")


# ---------------------------------------------------------------- threads and timeouts


def test_timeout_waits_for_a_late_transform() -> None:
    buf = Buffer()
    buf.set_transform(tf("odom", "base", 1 * S), "t")

    def publish_late() -> None:
        time.sleep(0.05)
        buf.set_transform(tf("odom", "base", 2 * S, (2, 0, 0)), "t")

    thread = threading.Thread(target=publish_late)
    thread.start()
    msg = buf.lookup_transform("odom", "base", 2 * S, timeout=5.0)
    thread.join()
    assert msg.transform.translation.x == 2.0
    start = time.monotonic()
    assert not buf.can_transform("odom", "base", 9 * S, timeout=0.05)
    assert time.monotonic() - start >= 0.05
    with pytest.raises(ExtrapolationException):
        buf.lookup_transform("odom", "base", 9 * S, timeout=Duration(sec=0, nanosec=10_000_000))
    with pytest.raises(InvalidArgumentException, match="timeout"):
        buf.lookup_transform("odom", "base", 0, timeout=-1.0)
    # New data cannot cure a malformed frame id: no waiting.
    start = time.monotonic()
    assert not buf.can_transform("/odom", "base", timeout=5.0)
    with pytest.raises(InvalidArgumentException):
        buf.lookup_transform("odom", "/base", timeout=5.0)
    assert time.monotonic() - start < 1.0


def test_concurrent_insert_and_lookup() -> None:
    buf = Buffer(cache_time=0.5)
    buf.set_transform_static(tf("base", "cam", 0, (0, 0, 1)), "rsp")
    buf.set_transform(tf("odom", "base", 1, (0, 0, 0)), "odom")
    errors: list[BaseException] = []
    stop = threading.Event()

    def writer() -> None:
        for i in range(2, 3000):
            buf.set_transform(tf("odom", "base", i * 1_000_000, (i * 1e-3, 0, 0)), "odom")
        stop.set()

    def reader() -> None:
        try:
            while not stop.is_set():
                msg = buf.lookup_transform("odom", "cam")
                stamp = msg.header.stamp.sec * S + msg.header.stamp.nanosec
                # x equals the stamp in seconds on every sample: a torn read would break it.
                assert msg.transform.translation.x == pytest.approx(stamp / S, abs=1e-9)
                assert msg.transform.translation.z == 1.0
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)

    threads = [threading.Thread(target=writer), threading.Thread(target=reader)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert errors == []
    assert buf.frame_infos()["base"].oldest_ns >= 2_999_000_000 - 500_000_000


# ---------------------------------------------------------------- properties and cross-checks


@st.composite
def random_trees(draw: st.DrawFn) -> tuple[list[tuple[str, str]], list[NDArray[np.float64]]]:
    """A random forest-free tree: frame i > 0 hangs under a random earlier frame."""
    n = draw(st.integers(2, 12))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    edges = [(f"f{int(rng.integers(0, i))}", f"f{i}") for i in range(1, n)]
    mats = [
        translation_quaternion_to_matrix(
            rng.normal(size=3) * 3, Rotation.random(random_state=rng).as_quat()
        )
        for _ in edges
    ]
    return edges, mats


@settings(max_examples=60, deadline=None)
@given(random_trees(), st.data())
def test_random_static_trees_match_pytransform3d(
    tree: tuple[list[tuple[str, str]], list[NDArray[np.float64]]], data: st.DataObject
) -> None:
    edges, mats = tree
    buf = Buffer()
    tm = TransformManager(check=False)
    for (parent, child), T in zip(edges, mats, strict=True):
        msg = TransformStamped(Header(Time(0, 0), parent), child, _matrix_msg(T))
        assert buf.set_transform_static(msg, "test")
        tm.add_transform(child, parent, T)  # pytransform3d: child2parent maps child into parent
    frames = [f"f{i}" for i in range(len(edges) + 1)]
    a = data.draw(st.sampled_from(frames))
    b = data.draw(st.sampled_from(frames))
    T_a_b = buf.lookup_transform_matrix(a, b)
    np.testing.assert_allclose(T_a_b, tm.get_transform(b, a), atol=1e-9)
    np.testing.assert_allclose(T_a_b @ buf.lookup_transform_matrix(b, a), np.eye(4), atol=1e-9)


def _matrix_msg(mat: NDArray[np.float64]) -> Transform:
    return matrix_to_transform(mat)


def _reference_lookup(
    samples: dict[str, tuple[str, list[int], list[NDArray[np.float64]]]], frame: str, t: int
) -> NDArray[np.float64]:
    """Slow reference: T_root_frame at t with scipy Slerp per link (single-parent links)."""
    T = np.eye(4)
    while frame in samples:
        parent, stamps, mats = samples[frame]
        rots = Rotation.from_matrix(np.array([m[:3, :3] for m in mats]))
        trans = np.array([m[:3, 3] for m in mats])
        link = np.eye(4)
        link[:3, :3] = Slerp(stamps, rots)([t]).as_matrix()[0]
        link[:3, 3] = [np.interp(t, stamps, trans[:, k]) for k in range(3)]
        T = link @ T
        frame = parent
    return T


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_dynamic_tree_matches_slow_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    buf = Buffer(cache_time=100.0)
    samples: dict[str, tuple[str, list[int], list[NDArray[np.float64]]]] = {}
    for i in range(1, 7):
        parent, child = f"f{int(rng.integers(0, i))}", f"f{i}"
        stamps = sorted({int(s) for s in rng.integers(0, 10 * S, size=int(rng.integers(2, 8)))})
        stamps = [0, *stamps, 10 * S] if stamps[0] else [*stamps, 10 * S]
        mats = []
        for s in stamps:
            T = translation_quaternion_to_matrix(
                rng.normal(size=3), Rotation.random(random_state=rng).as_quat()
            )
            mats.append(T)
            msg = TransformStamped(Header(Time(*divmod(s, S)), parent), child, _matrix_msg(T))
            assert buf.set_transform(msg, "test")
        samples[child] = (parent, stamps, mats)
    for _ in range(5):
        a, b = f"f{int(rng.integers(0, 7))}", f"f{int(rng.integers(0, 7))}"
        t = int(rng.integers(1, 10 * S))
        expected = invert(_reference_lookup(samples, a, t)) @ _reference_lookup(samples, b, t)
        np.testing.assert_allclose(buf.lookup_transform_matrix(a, b, t), expected, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(
    st.tuples(*[st.floats(-50, 50, allow_nan=False)] * 3),
    st.tuples(*[st.floats(-50, 50, allow_nan=False)] * 3),
    st.floats(-math.pi, math.pi),
    st.floats(-math.pi, math.pi),
    st.integers(1, 10**9 - 1),
)
def test_interpolated_transform_lies_between_samples(
    p0: tuple[float, float, float],
    p1: tuple[float, float, float],
    yaw0: float,
    yaw1: float,
    offset: int,
) -> None:
    buf = Buffer()
    buf.set_transform(tf("odom", "base", 1 * S, p0, yaw_q(yaw0)), "t")
    buf.set_transform(tf("odom", "base", 2 * S, p1, yaw_q(yaw1)), "t")
    msg = buf.lookup_transform("odom", "base", S + offset)
    ratio = offset / S
    t = msg.transform.translation
    for k, v in enumerate((t.x, t.y, t.z)):
        lo, hi = sorted((p0[k], p1[k]))
        assert lo - 1e-9 <= v <= hi + 1e-9
        assert v == pytest.approx((1 - ratio) * p0[k] + ratio * p1[k], abs=1e-9)
    q = msg.transform.rotation
    yaw = euler_from_quaternion([q.x, q.y, q.z, q.w])[2]
    # Along the shorter arc: the angular distance to each end splits the whole.
    total = abs(math.remainder(yaw1 - yaw0, 2 * math.pi))
    d0 = abs(math.remainder(yaw - yaw0, 2 * math.pi))
    d1 = abs(math.remainder(yaw1 - yaw, 2 * math.pi))
    assert d0 + d1 == pytest.approx(total, abs=1e-9)
    assert d0 == pytest.approx(ratio * total, abs=1e-9)
