"""Tracking loss and restart (slam/restart.py): ICP through the loss, the held restart keyframe."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from visnav.slam import SlamConfig, SlamSystem, TrackResult
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.geometry import inverse, rotation_angle
from visnav.slam.restart import RestartAnchor, predict_from_odometry
from visnav.slam.synthetic import SyntheticRoom

from .conftest import Sequence, make_sequence

CONFIG = SlamConfig(n_features=400, vocabulary_keyframes=6, loop_min_inliers=30)
SLIP_DEG = 0.3  # odometry heading error per frame while lost (a turn on the spot slipping)
QVGA = CameraIntrinsics(250.0, 250.0, 159.5, 119.5, 320, 240)


@pytest.fixture(scope="module")
def qvga_sequence() -> Sequence:
    """The start of the short sequence at 320 x 240 (ICP needs more than 160 x 120 pixels)."""
    return make_sequence(17, turns=17 / 130, cam=QVGA)


def _yaw(deg: float) -> np.ndarray:
    """A rotation about the optical frame's y axis (down): a heading change of the robot."""
    a = np.radians(deg)
    r = np.eye(4)
    r[[0, 0, 2, 2], [0, 2, 0, 2]] = [np.cos(a), np.sin(a), -np.sin(a), np.cos(a)]
    return r


def _run(seq: Sequence, config: SlamConfig, n: int) -> tuple[SlamSystem, list[TrackResult]]:
    """Frames 12-14 blank, 15+ in an unseen room: lost, then restarted on the odometry.

    The odometry is exact until frame 11, then its heading slips ``SLIP_DEG`` per frame.
    """
    other_room = SyntheticRoom(seed=7)  # same geometry, unseen texture: nothing to relocalise on
    blank = np.full_like(seq.rgb[0], 128)
    slam = SlamSystem(seq.camera, config, initial_pose=seq.poses[0])
    results = []
    for i in range(n):
        odom = seq.poses[i] @ _yaw(SLIP_DEG * max(i - 11, 0))
        if i < 12:
            rgb, depth = seq.rgb[i], seq.depth[i]
        elif i < 15:
            rgb, depth = blank, seq.depth[i]
        else:
            rgb, depth = other_room.render(seq.camera, seq.poses[i])
        results.append(slam.track(rgb, depth, int(seq.stamps_ns[i]), odom_pose=odom))
    return slam, results


def _errors(seq: Sequence, result: TrackResult, i: int) -> tuple[float, float]:
    assert result.t_wc is not None
    rel = inverse(seq.poses[i]) @ result.t_wc
    return float(np.linalg.norm(rel[:3, 3])), float(np.degrees(rotation_angle(rel)))


def test_predict_from_odometry_moves_the_last_pose_by_the_odometry_motion() -> None:
    t_cw_last = inverse(_yaw(10.0))
    t_cw_last[:3, 3] = [0.1, 0.2, 0.3]
    odom_last = _yaw(3.0)
    step = _yaw(2.0)
    step[:3, 3] = [0.05, 0.0, 0.1]
    pred = predict_from_odometry(odom_last @ step, odom_last @ t_cw_last)
    assert pred is not None
    np.testing.assert_allclose(pred, inverse(step) @ t_cw_last, atol=1e-12)
    assert predict_from_odometry(None, odom_last) is None
    assert predict_from_odometry(odom_last, None) is None


def test_restart_pose_follows_the_depth_not_the_slipping_odometry(
    qvga_sequence: Sequence,
) -> None:
    seq = qvga_sequence
    _, results = _run(seq, CONFIG, 17)
    assert [r.state for r in results[12:16]] == ["lost"] * 4
    assert [i for i, r in enumerate(results) if r.reinitialized] == [16]
    dist, angle = _errors(seq, results[16], 16)
    assert dist < 0.01, dist
    # without the depth (ICP off) the restart takes the slipped odometry's heading
    _, blind = _run(seq, dataclasses.replace(CONFIG, icp_refinement=False), 17)
    assert blind[16].reinitialized
    _, blind_angle = _errors(seq, blind[16], 16)
    assert blind_angle > 1.2, blind_angle
    # the odometry turned 1.5 degrees too far in the 5 lost frames; ICP on the depth
    # (the camera centre held where the odometry puts it) takes at least half of that out.
    # (A regression check, not a guarantee: in this box room the ICP's capture range is
    # small and where it lands depends on the map it started from: 0.16-0.68 degrees with
    # the odometry prior's settings; with a 0.2 degree-per-frame slip it ends 0.2 degrees
    # worse than the odometry. On the car's seed 4 it took 3.2 degrees to 0.5.)
    assert angle < 0.5 * blind_angle, (angle, blind_angle)


def test_restart_keyframe_is_held_in_local_bundle_adjustment(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam, results = _run(seq, CONFIG, 30)
    restart_kf = next(kf for kf in slam.map.keyframes if kf.stamp_ns == results[16].stamp_ns)
    restart = restart_kf.id
    later = [kf for kf in slam.map.keyframes if kf.id > restart]
    assert later, "keyframes after the restart (local bundle adjustments ran)"
    assert slam.ba_runs > 0
    # the new part of the map shares no points with the old one: its first keyframe is held
    assert restart in slam._anchor.held
    pose_at_restart = results[16].t_wc
    assert pose_at_restart is not None
    np.testing.assert_array_equal(restart_kf.t_wc, pose_at_restart)
    # tracking goes on in the new part, consistent with the restart keyframe
    for i in range(17, 30):
        pose = results[i].t_wc
        assert results[i].state == "ok"
        assert pose is not None
        rel = inverse(inverse(pose_at_restart) @ pose) @ (inverse(seq.poses[16]) @ seq.poses[i])
        assert np.linalg.norm(rel[:3, 3]) < 0.01, i
        assert np.degrees(rotation_angle(rel)) < 0.3, i


def test_hold_ends_when_the_new_part_links_to_the_old_map(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam, _ = _run(seq, CONFIG, 30)
    assert slam._anchor.held
    # the camera sees the first room again: relocalised on the old map, keyframes link to it
    stamps = int(seq.stamps_ns[-1])
    released = False
    for k, i in enumerate(range(12, 40)):
        slam.track(seq.rgb[i], seq.depth[i], stamps + (k + 1) * 33_333_333, odom_pose=None)
        if not slam._anchor.held:
            released = True
            break
    assert released


def test_anchor_leaves_held_keyframes_out_of_the_window_until_linked(
    short_sequence: Sequence,
) -> None:
    slam = SlamSystem(short_sequence.camera, CONFIG, initial_pose=short_sequence.poses[0])
    for i in range(20):
        seq = short_sequence
        slam.track(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]))
    m = slam.map
    assert len(m.keyframes) >= 4
    newest, held = m.keyframes[-1], m.keyframes[-2].id
    window = [newest.id, *newest.best_covisibles(7)]
    assert held in window
    _, pts = m.keyframe_points(newest)
    links = sum(1 for p in pts.tolist() if min(m.observations[p]) < held)
    assert links > 0
    # fewer links than required: the held keyframe leaves the window (bundle adjustment
    # then holds it, as every keyframe outside the window that sees the points)
    strict = RestartAnchor(min_links=links + 1)
    strict.hold(held)
    assert strict.window(m, newest, window) == [k for k in window if k != held]
    assert strict.held == {held}
    # enough links: one map again, nothing held from now on
    loose = RestartAnchor(min_links=links)
    loose.hold(held)
    assert loose.window(m, newest, window) == window
    assert loose.held == set()
    assert RestartAnchor().window(m, newest, window) == window  # nothing held
