"""Viewer geometry and TF placement (no Rerun needed)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.msgs import ColorRGBA, LaserScan, Pose, make, xyz_to_cloud
from visnav.tf import quaternion_from_euler, quaternion_to_matrix, transform_points
from visnav.viz.errors import VizError
from visnav.viz.geometry import (
    cloud_points,
    color_to_rgba8,
    colorize,
    decimate,
    pack_rgba32,
    pose_in,
    scan_points,
    transform_points32,
)
from visnav.viz.placement import FramePlacer

T0 = 1_000_000_000


def test_decimate_keeps_at_most_max_points() -> None:
    assert decimate(100, None) == 1
    assert decimate(100, 100) == 1
    assert decimate(101, 100) == 2
    assert decimate(307_200, 50_000) == 7
    with pytest.raises(VizError, match="max_points is 0"):
        decimate(10, 0)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 5000), st.integers(1, 2000))
def test_cloud_points_bound_and_subset(n: int, max_points: int) -> None:
    pts = np.arange(n * 3, dtype=np.float32).reshape(n, 3)
    xyz, colors = cloud_points(xyz_to_cloud(pts), max_points=max_points)
    assert len(xyz) <= max_points
    assert colors is None
    if n:
        assert len(xyz) == math.ceil(n / decimate(n, max_points))
        assert np.array_equal(xyz[0], pts[0])


def test_cloud_points_needs_xyz(vz: Any) -> None:
    from visnav.msgs import structured_to_cloud

    arr = np.zeros(3, np.dtype([("a", "<f4")]))
    with pytest.raises(VizError, match=r"no field\(s\) \['x', 'y', 'z'\]"):
        cloud_points(structured_to_cloud(arr, header=vz.header("base", 0)))


def test_intensity_colours_a_cloud() -> None:
    from visnav.msgs import structured_to_cloud

    arr = np.zeros(3, np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")]))
    arr["intensity"] = [0.0, 0.5, 1.0]
    _, colors = cloud_points(structured_to_cloud(arr))
    assert colors is not None
    assert colors.shape == (3,)
    assert colors.dtype == np.uint32
    assert (colors & 0xFF).tolist() == [255, 255, 255]  # opaque
    assert colors[0] != colors[2]
    assert colorize(np.zeros(0)).shape == (0, 3)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(0.0, 30.0, width=32), min_size=1, max_size=50),
    st.floats(-math.pi, 0.0),
    st.floats(0.001, 0.1),
)
def test_scan_points_lie_at_their_range_and_angle(
    ranges: list[float], angle_min: float, inc: float
) -> None:
    scan = make(
        LaserScan,
        angle_min=angle_min,
        angle_increment=inc,
        range_min=0.5,
        range_max=20.0,
        ranges=np.array(ranges, np.float32),
    )
    xyz, intensity = scan_points(scan)
    r = np.array(ranges, np.float32)
    valid = (r >= 0.5) & (r <= 20.0)
    assert len(xyz) == int(valid.sum())
    assert intensity is None
    assert np.allclose(np.linalg.norm(xyz, axis=1), r[valid], rtol=1e-5, atol=1e-5)
    angles = angle_min + np.arange(len(r)) * inc
    got = np.arctan2(xyz[:, 1], xyz[:, 0])
    delta = np.angle(np.exp(1j * (got - angles[valid])))
    assert np.allclose(delta[r[valid] > 1e-3], 0.0, atol=1e-4)


@settings(max_examples=40, deadline=None)
@given(
    st.tuples(*[st.floats(-math.pi, math.pi)] * 3),
    st.tuples(*[st.floats(-10, 10)] * 3),
)
def test_transform_points32_matches_tf(rpy: tuple[float, ...], xyz: tuple[float, ...]) -> None:
    m = np.eye(4)
    m[:3, :3] = quaternion_to_matrix(quaternion_from_euler(*rpy))
    m[:3, 3] = xyz
    pts = np.random.default_rng(1).normal(size=(20, 3)).astype(np.float32)
    assert np.allclose(transform_points32(m, pts), transform_points(m, pts), atol=1e-4)


def test_rgb_field_is_packed_for_rerun() -> None:
    rgb = np.array([[255, 0, 0], [0, 128, 255]], np.uint8)
    _, colors = cloud_points(xyz_to_cloud(np.zeros((2, 3), np.float32), rgb=rgb))
    assert colors is not None
    assert colors.tolist() == [0xFF0000FF, 0x0080FFFF]
    assert pack_rgba32(rgb).tolist() == [0xFF0000FF, 0x0080FFFF]


def test_pose_in_and_colour() -> None:
    m = np.eye(4)
    m[0, 3] = 1.0
    pose = make(Pose)  # all-zero quaternion: identity (RViz)
    pose.position.y = 2.0
    t, q = pose_in(m, pose)
    assert np.allclose(t, [1.0, 2.0, 0.0])
    assert np.allclose(q, [0, 0, 0, 1])
    assert color_to_rgba8(ColorRGBA(r=1.0, g=0.5, b=-1.0, a=2.0)) == (255, 128, 0, 255)


class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_placer_waits_retries_and_expires(vz: Any) -> None:
    clock = _Clock()
    placer = FramePlacer("map", queue_size=3, max_wait_s=1.0, clock=clock)
    got: list[np.ndarray] = []
    assert not placer.place("/a", "base", T0, got.append)  # no TF yet: queued
    assert placer.pending == 1
    placer.add_transforms(vz.tf_msg(vz.tf("map", "base", T0, (1.0, 0.0, 0.0))), static=False)
    assert placer.pending == 0
    assert np.allclose(got[0][:3, 3], [1.0, 0.0, 0.0])
    assert placer.place("/a", "base", 0, got.append)  # stamp 0: latest
    assert not placer.place("/a", "ghost", T0, got.append)
    clock.now = 2.0
    placer.expire()
    assert placer.dropped == {"/a": 1}
    assert "[ghost]" in placer.drop_reasons["/a"]


def test_placer_queue_overflow_drops_oldest(vz: Any) -> None:
    placer = FramePlacer("map", queue_size=2)
    for i in range(4):
        placer.place("/a", "base", T0 + i, lambda m: None)
    assert placer.pending == 2
    assert placer.dropped == {"/a": 2}
    assert "queue full" in placer.drop_reasons["/a"]


def test_placer_identity_for_fixed_and_empty_frames() -> None:
    placer = FramePlacer("map")
    got: list[np.ndarray] = []
    assert placer.place("/a", "map", T0, got.append)
    assert placer.place("/a", "", T0, got.append)
    assert placer.place("/a", "/map", T0, got.append)  # leading slash stripped, as tf2 inserts
    assert all(np.array_equal(g, np.eye(4)) for g in got)
    assert "empty frame_id" in placer.drop_reasons["/a"]


def test_placer_auto_fixed_frame(vz: Any) -> None:
    placer = FramePlacer()
    placer.add_transforms(vz.tf_msg(vz.tf("odom", "base", 0)), static=True)
    placer.add_transforms(vz.tf_msg(vz.tf("map", "odom", 0)), static=True)
    assert placer.lookup("base", 0) is not None
    assert placer.fixed_frame == "map"
    with pytest.raises(VizError, match="leading '/'"):
        FramePlacer("/map")
    with pytest.raises(VizError, match="queue_size"):
        FramePlacer("map", queue_size=0)
