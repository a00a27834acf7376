"""ScanHistory: which scans are kept, and their map poses from a corrected trajectory."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.mapping.scan_history import PathProbe, ScanHistory, pose_displacement
from visnav.msgs import Header, LaserScan, Path, PoseStamped, make, ns_to_time
from visnav.tf.transforms import matrix_to_pose

S = 1_000_000_000


def _pose(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    t = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    t[:2, :2] = [[c, -s], [s, c]]
    t[:3, 3] = x, y, z
    return t


def _scan(stamp: int) -> LaserScan:
    return make(LaserScan, header=Header(stamp=ns_to_time(stamp), frame_id="laser"))


def _path(items: list[tuple[int, np.ndarray]]) -> Path:
    return Path(
        header=Header(stamp=ns_to_time(0), frame_id="map"),
        poses=[
            PoseStamped(header=Header(stamp=ns_to_time(t), frame_id="map"), pose=matrix_to_pose(m))
            for t, m in items
        ],
    )


def test_scans_are_kept_after_enough_motion() -> None:
    h = ScanHistory(linear_update=0.1, angular_update=0.2)
    base = _pose(0.1, 0.0, 0.0)
    for k, (x, yaw, kept) in enumerate(
        [
            (0.0, 0.0, True),
            (0.05, 0.0, False),
            (0.11, 0.0, True),
            (0.11, 0.15, False),
            (0.11, 0.25, True),
        ]
    ):
        odom = _pose(x, 0.0, yaw)
        assert h.wants(odom) is kept, k
        if kept:
            h.add(_scan(k * S), odom, base)
    assert len(h) == 3
    assert ScanHistory().wants(_pose(0.0, 0.0, 0.0))  # 0 / 0: every scan


def test_without_keep_only_the_last_pose_is_held() -> None:
    h = ScanHistory(linear_update=0.1, keep=False)
    h.add(_scan(0), _pose(0.0, 0.0, 0.0), np.eye(4))
    assert len(h) == 0
    assert not h.wants(_pose(0.05, 0.0, 0.0))
    assert h.wants(_pose(0.1, 0.0, 0.0))


def test_poses_come_from_the_path_and_unmatched_scans_from_the_nearest_correction() -> None:
    base_laser = _pose(0.2, 0.0, 0.0, z=0.3)
    h = ScanHistory()
    odom = [_pose(0.5 * k, 0.0, 0.1 * k) for k in range(4)]
    for k in range(4):
        h.add(_scan(k * S), odom[k] @ base_laser, base_laser)
    # the SLAM path knows scans 0 and 1 (scan 2 was lost, 3 is newer than the path):
    # map -> odom is a 1 m shift for scan 0 and a 1 m shift plus 0.1 rad for scan 1
    c0, c1 = _pose(1.0, 0.0, 0.0), _pose(1.0, 0.0, 0.1)
    tilted = c1 @ odom[1] @ _pose(0.0, 0.0, 0.0, z=0.4)  # SLAM's z stays out of the grid
    poses = h.poses_from_path(_path([(0, c0 @ odom[0]), (1 * S, tilted)]))
    assert poses is not None
    np.testing.assert_allclose(poses[0], c0 @ odom[0] @ base_laser, atol=1e-9)
    np.testing.assert_allclose(poses[1][:2], (c1 @ odom[1] @ base_laser)[:2], atol=1e-9)
    assert poses[1][2, 3] == pytest.approx(0.3)
    for k in (2, 3):  # scan 1's correction is the nearest
        np.testing.assert_allclose(poses[k][:2], (c1 @ odom[k] @ base_laser)[:2], atol=1e-9)
    assert h.poses_from_path(_path([(7 * S, c0)])) is None  # no kept stamp in it
    assert h.poses_from_path(_path([])) is None


@settings(max_examples=50, deadline=None)
@given(
    st.floats(-5, 5),
    st.floats(-5, 5),
    st.floats(-3, 3),
    st.floats(-1, 1),
    st.floats(-1, 1),
    st.floats(-0.5, 0.5),
    st.floats(0.0, 5.0),
)
def test_displacement_is_the_planar_shift_plus_reach_times_the_turn(
    x: float, y: float, yaw: float, dx: float, dy: float, dyaw: float, reach: float
) -> None:
    a = _pose(x, y, yaw)[None]
    b = _pose(x + dx, y + dy, yaw + dyaw, z=3.0)[None]  # z does not count
    got = pose_displacement(a, b, reach)[0]
    assert got == pytest.approx(math.hypot(dx, dy) + reach * abs(dyaw), abs=1e-9)


def test_a_probe_tells_an_appended_path_from_a_corrected_one() -> None:
    items = [(k * S, _pose(0.1 * k, 0.0, 0.0)) for k in range(100)]
    probe = PathProbe.of(_path(items))
    assert probe.same_past(_path([*items, (100 * S, _pose(10.0, 0.0, 0.0))]))  # appended
    moved = [(t, _pose(0.0, 0.01, 0.0) @ m) for t, m in items]  # a loop moved the past 1 cm
    assert not probe.same_past(_path(moved))
    assert not probe.same_past(_path(items[:50]))  # shorter: not the same past
    assert not PathProbe().same_past(_path(items))  # nothing probed yet


def test_a_robot_standing_still_keeps_a_scan_per_temporal_update() -> None:
    h = ScanHistory(linear_update=0.1, angular_update=0.1, temporal_update=0.5)
    still = _pose(0.0, 0.0, 0.0)
    kept = []
    for k in range(21):  # 1 s at 20 Hz, not moving
        stamp = k * S // 20
        if h.wants(still, stamp):
            h.add(_scan(stamp), still, np.eye(4))
            kept.append(k)
    assert kept == [0, 10, 20]
