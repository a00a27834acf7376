"""RGB-D SLAM on synthetic sequences: accuracy, determinism, relocalisation, loops, bad input."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from visnav.slam import SlamConfig, SlamInputError, SlamSystem, TrackResult, Trajectory, ate
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.synthetic import SyntheticRoom

from .conftest import SMALL, Sequence

CONFIG = SlamConfig(n_features=400, vocabulary_keyframes=6, loop_min_inliers=30)


def _run(seq: Sequence, config: SlamConfig = CONFIG, n: int | None = None) -> SlamSystem:
    slam = SlamSystem(seq.camera, config, initial_pose=seq.poses[0])
    for rgb, depth, t in list(zip(seq.rgb, seq.depth, seq.stamps_ns, strict=True))[:n]:
        slam.track(rgb, depth, int(t))
    return slam


def _gt(seq: Sequence) -> Trajectory:
    return Trajectory.from_matrices(seq.stamps_s, seq.poses)


def test_tracking_follows_the_ground_truth(short_sequence: Sequence) -> None:
    slam = _run(short_sequence)
    traj = slam.trajectory()
    assert len(traj) == len(short_sequence.poses)  # every frame tracked
    assert slam.n_lost == 0
    assert 2 <= len(slam.map.keyframes) < len(short_sequence.poses)
    err = ate(traj, _gt(short_sequence))
    assert err.rmse < 0.015, err.summary()
    assert err.max < 0.03


def test_same_inputs_and_seed_give_the_same_trajectory(short_sequence: Sequence) -> None:
    a = _run(short_sequence, n=25).trajectory()
    b = _run(short_sequence, n=25).trajectory()
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.quaternions, b.quaternions)


def test_relocalises_after_losing_track(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam = _run(seq, n=30)
    blank = np.full_like(seq.rgb[0], 128)
    lost = slam.track(blank, seq.depth[0], int(seq.stamps_ns[-1]) + 10**9)
    assert lost.state == "lost"
    assert lost.t_wc is None
    assert any("lost" in w for w in lost.warnings)
    # the camera reappears at a place mapped earlier: relocalisation, not tracking
    back = slam.track(seq.rgb[12], seq.depth[12], int(seq.stamps_ns[-1]) + 2 * 10**9)
    assert back.state == "ok"
    assert back.relocalized
    assert back.t_wc is not None
    assert np.linalg.norm(back.t_wc[:3, 3] - seq.poses[12][:3, 3]) < 0.03
    nxt = slam.track(seq.rgb[13], seq.depth[13], int(seq.stamps_ns[-1]) + 3 * 10**9)
    assert nxt.state == "ok"
    assert not nxt.relocalized


def test_odometry_restarts_tracking_where_relocalisation_cannot(short_sequence: Sequence) -> None:
    seq = short_sequence
    other_room = SyntheticRoom(seed=7)  # same geometry, unseen texture: nothing to relocalise on
    blank = np.full_like(seq.rgb[0], 128)

    def run(with_odometry: bool) -> tuple[SlamSystem, list[TrackResult]]:
        slam = SlamSystem(seq.camera, CONFIG, initial_pose=seq.poses[0])
        results = []
        for i in range(22):
            odom = seq.poses[i] if with_odometry else None
            t = int(seq.stamps_ns[i])
            if i < 12:
                rgb, depth = seq.rgb[i], seq.depth[i]
            elif i < 15:
                rgb, depth = blank, seq.depth[i]
            else:
                rgb, depth = other_room.render(seq.camera, seq.poses[i])
            results.append(slam.track(rgb, depth, t, odom_pose=odom))
        return slam, results

    slam, results = run(with_odometry=True)
    assert [r.state for r in results[12:15]] == ["lost"] * 3
    restarted = [i for i, r in enumerate(results) if r.reinitialized]
    assert restarted == [16]  # after reinit_after_lost = 5 lost frames (3 blank, 2 unknown)
    assert any("tracking restarted" in w for w in results[16].warnings)
    assert slam.n_reinitialized == 1
    for i in range(16, 22):
        pose = results[i].t_wc
        assert pose is not None
        assert np.linalg.norm(pose[:3, 3] - seq.poses[i][:3, 3]) < 0.02
    # without odometry the system stays lost in the unseen room
    _, blind = run(with_odometry=False)
    assert all(r.state == "lost" for r in blind[12:])


def test_clouds(short_sequence: Sequence) -> None:
    slam = _run(short_sequence, n=15)
    sparse = slam.map_cloud()
    assert sparse.dtype == np.float32
    assert sparse.shape[1] == 3
    assert len(sparse) > 100
    # every map point lies on a wall of the room (0..8 x 0..6 x 0..3 m)
    size = np.array([8.0, 6.0, 3.0])
    dist = np.minimum(np.abs(sparse), np.abs(sparse - size)).min(axis=1)
    assert np.median(dist) < 0.01
    fine, rgb = slam.dense_cloud(0.05)
    coarse, _ = slam.dense_cloud(0.5)
    assert rgb.shape == fine.shape
    assert rgb.dtype == np.uint8
    assert len(coarse) < len(fine)
    with pytest.raises(SlamInputError, match="voxel_size"):
        slam.dense_cloud(0.0)


def test_mono_image_input_tracks(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam = SlamSystem(seq.camera, CONFIG, initial_pose=seq.poses[0])
    for rgb, depth, t in list(zip(seq.rgb, seq.depth, seq.stamps_ns, strict=True))[:8]:
        result = slam.track(rgb[:, :, 0].copy(), depth, int(t))
    assert result.state == "ok"


def test_millimetre_uint16_depth_is_accepted(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam = SlamSystem(seq.camera, CONFIG, initial_pose=seq.poses[0])
    for rgb, depth, t in list(zip(seq.rgb, seq.depth, seq.stamps_ns, strict=True))[:6]:
        mm = np.rint(depth * 1000.0).astype(np.uint16)
        result = slam.track(rgb, mm, int(t))
    assert result.state == "ok"
    assert result.t_wc is not None
    assert np.linalg.norm(result.t_wc[:3, 3] - seq.poses[5][:3, 3]) < 0.02


@pytest.mark.parametrize(("factor", "needle"), [(1000.0, "1000x"), (0.001, "0.001x")])
def test_depth_scale_off_by_1000_is_detected(
    short_sequence: Sequence, factor: float, needle: str
) -> None:
    seq = short_sequence
    slam = SlamSystem(seq.camera, CONFIG)
    with pytest.raises(SlamInputError, match=needle) as info:
        slam.track(seq.rgb[0], (seq.depth[0] * factor).astype(np.float32), int(seq.stamps_ns[0]))
    assert "depth_scale" in str(info.value)


def test_uint16_depth_with_a_wrong_scale_is_detected(short_sequence: Sequence) -> None:
    seq = short_sequence
    config = dataclasses.replace(CONFIG, depth_scale=1.0)  # millimetres read as metres
    slam = SlamSystem(seq.camera, config)
    mm = np.rint(seq.depth[0] * 1000.0).astype(np.uint16)
    with pytest.raises(SlamInputError, match="median depth"):
        slam.track(seq.rgb[0], mm, int(seq.stamps_ns[0]))


def test_image_that_does_not_fit_the_camera_is_refused(short_sequence: Sequence) -> None:
    seq = short_sequence
    other = CameraIntrinsics(250.0, 250.0, 159.5, 119.5, 320, 240)
    slam = SlamSystem(other, CONFIG)
    with pytest.raises(SlamInputError, match="160x120 but the camera_info describes 320x240"):
        slam.track(seq.rgb[0], seq.depth[0], 0)
    slam = SlamSystem(SMALL, CONFIG)
    with pytest.raises(SlamInputError, match="registered"):
        slam.track(seq.rgb[0], seq.depth[0][:60], 0)
    with pytest.raises(SlamInputError, match="dtype"):
        slam.track(seq.rgb[0].astype(np.float32), seq.depth[0], 0)


def test_featureless_start_waits_with_a_warning(short_sequence: Sequence) -> None:
    seq = short_sequence
    slam = SlamSystem(seq.camera, CONFIG)
    result = slam.track(np.full_like(seq.rgb[0], 90), seq.depth[0], 0)
    assert result.state == "uninitialized"
    assert any("need 50" in w for w in result.warnings)
    assert slam.track(seq.rgb[0], seq.depth[0], 1).state == "ok"


@pytest.mark.slow
@pytest.mark.ci
def test_loop_closure_reduces_drift(loop_sequence: Sequence) -> None:
    gt = _gt(loop_sequence)
    open_loop = _run(
        loop_sequence, dataclasses.replace(CONFIG, loop_closure=False, final_global_ba=False)
    )
    closed = _run(loop_sequence, dataclasses.replace(CONFIG, final_global_ba=False))
    assert not open_loop.loops
    assert closed.loops, "the revisit of the start was not detected"
    err_open = ate(open_loop.trajectory(), gt)
    err_closed = ate(closed.trajectory(), gt)
    # the end of the run is where drift shows most and where the loop pulls it back
    tail = slice(-15, None)
    assert err_closed.errors[tail].mean() < 0.5 * err_open.errors[tail].mean()
    assert err_closed.rmse < err_open.rmse
    assert err_closed.rmse < 0.02
    closed.global_bundle_adjustment()  # what finish() runs at the end of offline runs
    assert ate(closed.trajectory(), gt).rmse < 0.02
