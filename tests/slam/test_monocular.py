"""Monocular SLAM: two-view initialisation, metric scale, tracking a loop, bad input."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from visnav.slam import SlamConfig, SlamInputError, SlamSystem, Trajectory, ate, slam_tum
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.features import OrbExtractor
from visnav.slam.geometry import inverse, rotation_angle
from visnav.slam.monocular import MonoInitializer, create_initial_map, mono_ba_window
from visnav.slam.slam_map import SlamMap
from visnav.slam.synthetic import SyntheticRoom, circle_trajectory, write_tum_folder

from .conftest import SMALL, Sequence

# Monocular SLAM needs parallax in pixels: 320 x 240 and a camera looking outward
# (moving sideways) instead of the RGB-D tests' 160 x 120 looking along the motion.
MONO_CAM = CameraIntrinsics(250.0, 250.0, 159.5, 119.5, 320, 240)
MONO = SlamConfig(n_features=800, vocabulary_keyframes=6, loop_min_inliers=30, sensor="mono")


def _mono_sequence(n: int, turns: float) -> Sequence:
    room = SyntheticRoom(seed=1)
    poses = circle_trajectory(n, turns=turns, look_offset_deg=0.0)
    frames = [room.render(MONO_CAM, p) for p in poses]
    stamps = (1_000_000_000 + np.arange(n) * 33_333_333).astype(np.int64)
    return Sequence(MONO_CAM, poses, stamps, [f[0] for f in frames], [f[1] for f in frames])


@pytest.fixture(scope="module")
def mono_short() -> Sequence:
    return _mono_sequence(12, 12 / 150 * 1.15)


def _gray(rgb: np.ndarray) -> np.ndarray:
    return np.asarray(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), dtype=np.uint8)


@pytest.mark.parametrize("scale", ["depth", "odometry"])
def test_two_view_initialisation_recovers_pose_and_metric_scale(
    mono_short: Sequence, scale: str
) -> None:
    seq = mono_short
    ex = OrbExtractor(n_features=800)
    init = MonoInitializer(seq.camera, scale=scale, min_parallax_deg=3.0)  # type: ignore[arg-type]
    for i in range(len(seq.poses)):
        frame = ex.extract(_gray(seq.rgb[i]), None, seq.camera, i)
        ref = init.ref
        view, why = init.step(frame, depth_m=seq.depth[i], odom_pose=seq.poses[i])
        if view is not None:
            break
        assert why.startswith("monocular initialisation: ")
    assert view is not None, "never initialised"
    assert ref is not None
    j, r = int(frame.stamp_ns), int(ref.stamp_ns)
    assert j > r
    slam_map = SlamMap()
    kf0, kf1 = create_initial_map(
        slam_map,
        seq.camera,
        ref,
        frame,
        view,
        seq.poses[r],
        inv_sigma2_levels=ex.inv_level_sigma2,
        depth_m=init.ref_depth if scale == "depth" else None,
    )
    gt = inverse(seq.poses[j]) @ seq.poses[r]  # T_cur_ref
    est = kf1.t_cw @ kf0.t_wc
    assert np.degrees(rotation_angle(est @ inverse(gt))) < 1.0
    cos = est[:3, 3] @ gt[:3, 3] / np.linalg.norm(est[:3, 3]) / np.linalg.norm(gt[:3, 3])
    assert np.degrees(np.arccos(min(cos, 1.0))) < 10.0  # direction of a 12-17 cm baseline
    ratio = np.linalg.norm(est[:3, 3]) / np.linalg.norm(gt[:3, 3])
    assert abs(ratio - 1.0) < 0.05, ratio  # metric scale within 5 %
    # the map points lie on the room's walls at the metric scale
    pts = slam_map.positions[slam_map.good_points()]
    size = np.array([8.0, 6.0, 3.0])
    dist = np.minimum(np.abs(pts), np.abs(pts - size)).min(axis=1)
    assert np.median(dist) < 0.1


def test_too_little_parallax_keeps_trying_and_says_why(mono_short: Sequence) -> None:
    seq = mono_short
    slam = SlamSystem(seq.camera, MONO, initial_pose=seq.poses[0])
    first = slam.track(seq.rgb[0], seq.depth[0], 0)
    assert first.state == "uninitialized"
    assert any("reference frame set" in w for w in first.warnings)
    for k in range(1, 4):  # the same view again: no parallax
        res = slam.track(seq.rgb[0], seq.depth[0], k)
        assert res.state == "uninitialized"
        assert res.t_wc is None
        assert any("parallax" in w for w in res.warnings), res.warnings
    states = [
        slam.track(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i])).state
        for i in range(1, len(seq.poses))
    ]
    assert "ok" in states
    assert slam.n_lost == 0
    assert len(slam.map.keyframes) >= 2
    assert slam.dense_cloud(0.1)[0].shape == (0, 3)  # no depth-image cloud in mono mode


def test_mono_with_odometry_scale_but_no_odometry_is_refused(mono_short: Sequence) -> None:
    seq = mono_short
    cfg = dataclasses.replace(MONO, mono_scale="odometry")
    slam = SlamSystem(seq.camera, cfg)
    with pytest.raises(SlamInputError, match="odom_pose"):
        slam.track(seq.rgb[0], None, 0)
    slam = SlamSystem(seq.camera, MONO)  # scale from depth without depth
    with pytest.raises(SlamInputError, match="without depth"):
        slam.track(seq.rgb[0], None, 0)
    rgbd = SlamSystem(seq.camera, SlamConfig())
    with pytest.raises(SlamInputError, match="depth is None"):
        rgbd.track(seq.rgb[0], None, 0)


def test_unknown_sensor_or_scale_is_refused() -> None:
    with pytest.raises(SlamInputError, match="sensor 'stereo'"):
        SlamSystem(SMALL, SlamConfig(sensor="stereo"))  # type: ignore[arg-type]
    with pytest.raises(SlamInputError, match="mono_scale 'imu'"):
        SlamSystem(SMALL, SlamConfig(sensor="mono", mono_scale="imu"))  # type: ignore[arg-type]


def test_the_config_itself_refuses_an_unknown_sensor() -> None:
    # the node decides which topics to subscribe from the config before any SlamSystem exists
    with pytest.raises(SlamInputError, match="sensor 'stereo'"):
        SlamConfig(sensor="stereo")  # type: ignore[arg-type]
    with pytest.raises(SlamInputError, match="mono_scale 'imu'"):
        dataclasses.replace(SlamConfig(sensor="mono"), mono_scale="imu")  # type: ignore[arg-type]


def test_tum_mono_odometry_scale_needs_groundtruth(tmp_path: Path) -> None:
    cam = CameraIntrinsics(125.0, 125.0, 79.5, 59.5, 160, 120)
    folder = write_tum_folder(tmp_path / "tum", SyntheticRoom(seed=1), cam, circle_trajectory(3))
    (folder / "groundtruth.txt").unlink()
    cfg = SlamConfig(sensor="mono", mono_scale="odometry")
    with pytest.raises(SlamInputError, match=r"groundtruth\.txt"):
        slam_tum(folder, config=cfg, output="")


def test_ba_window_holds_the_two_oldest_keyframes() -> None:
    assert mono_ba_window([9, 4, 7, 8]) == [9, 8]
    assert mono_ba_window([3, 1, 2]) == [3]
    assert mono_ba_window([1, 0]) == [1]


@pytest.mark.slow
@pytest.mark.parametrize("scale", ["depth", "odometry"])
def test_mono_tracks_a_loop(scale: str) -> None:
    seq = _mono_sequence(150, 1.15)
    cfg = dataclasses.replace(MONO, mono_scale=scale, final_global_ba=False)
    slam = SlamSystem(seq.camera, cfg, initial_pose=seq.poses[0])
    results = []
    for i in range(len(seq.poses)):
        depth = seq.depth[i] if scale == "depth" else None
        odom = seq.poses[i] if scale == "odometry" and slam.state == "uninitialized" else None
        results.append(slam.track(seq.rgb[i], depth, int(seq.stamps_ns[i]), odom_pose=odom))
    first = next(i for i, r in enumerate(results) if r.state == "ok")
    assert first <= 5
    assert all(r.state == "ok" for r in results[first:])  # never lost
    assert slam.n_lost == 0
    traj = slam.trajectory()
    assert len(traj) == len(seq.poses) - first + 1  # and the reference frame
    gt = Trajectory.from_matrices(seq.stamps_s, seq.poses)
    sim3 = ate(traj, gt, align=True, scale=True)
    assert sim3.rmse < 0.05, sim3.summary()
    assert sim3.alignment is not None
    assert 0.7 < sim3.alignment.scale < 1.4  # the scale drifts, but stays near the metric one
