"""Dense (point-to-plane ICP) refinement of tracked poses."""

from __future__ import annotations

import numpy as np
import pytest

from visnav.slam import SlamConfig, SlamSystem
from visnav.slam.dense import DenseTracker, depth_model, refine_pose_icp, sample_points
from visnav.slam.errors import SlamInputError
from visnav.slam.evaluation import rpe
from visnav.slam.geometry import inverse, se3_exp
from visnav.slam.synthetic import SyntheticRoom, circle_trajectory
from visnav.slam.trajectory import Trajectory

from .conftest import SMALL, Sequence


def _room_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    room = SyntheticRoom(seed=1)
    poses = circle_trajectory(40, turns=40 / 130)
    (_, d0), (_, d1) = room.render(SMALL, poses[0]), room.render(SMALL, poses[3])
    return poses[0], poses[3], d0, d1


def test_icp_recovers_a_perturbed_pose_in_the_room() -> None:
    p0, p1, d0, d1 = _room_pair()
    model = depth_model(d0, SMALL, step=1)
    pts = sample_points(d1, SMALL, stride=2)
    true_cw = inverse(p1)
    start = se3_exp(np.array([0.008, -0.005, 0.006, 0.004, -0.006, 0.003])) @ true_cw
    res = refine_pose_icp(model, inverse(p0), pts, start, min_inliers=100)
    assert res.ok
    err = res.t_cw @ p1
    assert np.linalg.norm(err[:3, 3]) < 1e-3  # from about 11 mm
    assert np.linalg.norm(start @ p1 - np.eye(4)) > 5e-3
    assert res.information.shape == (6, 6)
    assert np.all(np.linalg.eigvalsh(res.information) > 0)


def test_plane_keeps_the_prior_along_the_directions_it_cannot_see() -> None:
    depth = np.full((SMALL.height, SMALL.width), 2.0, dtype=np.float32)  # a wall facing the camera
    model = depth_model(depth, SMALL)
    pts = sample_points(depth, SMALL, stride=2)
    start = np.eye(4)
    start[:3, 3] = [0.004, 0.0, 0.01]  # 4 mm along the wall (unobservable), 1 cm towards it
    res = refine_pose_icp(model, np.eye(4), pts, start, prior=np.eye(6) * 1e3, min_inliers=100)
    assert res.ok
    assert abs(res.t_cw[2, 3]) < 1e-3  # the depth fixes the distance to the wall
    assert res.t_cw[0, 3] == pytest.approx(0.004, abs=1e-4)  # the prior keeps the rest
    n = model.normals[SMALL.height // 4, SMALL.width // 4]
    np.testing.assert_allclose(n, [0.0, 0.0, -1.0], atol=1e-5)


def test_refinement_without_correspondences_is_refused() -> None:
    depth = np.full((SMALL.height, SMALL.width), np.nan, dtype=np.float32)
    model = depth_model(depth, SMALL)
    start = se3_exp(np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.0]))
    res = refine_pose_icp(model, np.eye(4), np.zeros((0, 3)), start)
    assert not res.ok
    assert res.inliers == 0
    np.testing.assert_array_equal(res.t_cw, start)


def test_correction_beyond_the_limit_is_refused() -> None:
    p0, p1, d0, d1 = _room_pair()
    start = se3_exp(np.array([0.02, 0.0, 0.0, 0.0, 0.0, 0.0])) @ inverse(p1)
    res = refine_pose_icp(
        depth_model(d0, SMALL),
        inverse(p0),
        sample_points(d1, SMALL, stride=2),
        start,
        max_correction=0.005,
        min_inliers=100,
    )
    assert not res.ok
    np.testing.assert_array_equal(res.t_cw, start)


def test_tracker_keeps_only_the_most_recent_keyframes() -> None:
    _, _, d0, _ = _room_pair()
    tracker = DenseTracker(SMALL, keep=2)
    for k in range(4):
        tracker.add_keyframe(k, d0)
    assert [tracker.has(k) for k in range(4)] == [False, False, True, True]
    res = tracker.refine(0, np.eye(4), d0, np.eye(4), None)
    assert not res.ok


def test_refinement_lowers_frame_to_frame_error(short_sequence: Sequence) -> None:
    seq = short_sequence
    gt = Trajectory.from_matrices(seq.stamps_s, seq.poses)
    errors = {}
    for icp in (False, True):
        slam = SlamSystem(seq.camera, SlamConfig(icp_refinement=icp), initial_pose=seq.poses[0])
        for rgb, depth, t in zip(seq.rgb, seq.depth, seq.stamps_ns, strict=True):
            slam.track(rgb, depth, int(t))
        assert len(slam.trajectory()) == len(seq.rgb)
        errors[icp] = rpe(slam.trajectory(), gt).rmse
    assert errors[True] < errors[False]


@pytest.mark.parametrize("name", ["icp_stride", "icp_keyframes"])
def test_bad_icp_settings_are_refused(name: str) -> None:
    with pytest.raises(SlamInputError, match=name):
        SlamConfig(**{name: 0})  # type: ignore[arg-type]
