"""Geometry, matching and vocabulary building blocks (property tests)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.features import Frame, hamming, hamming_matrix
from visnav.slam.geometry import (
    PoseObservations,
    inverse,
    optimize_pose,
    orthonormalize,
    pose_covariance,
    rotation_angle,
    se3_exp,
    transform,
)
from visnav.slam.matching import match_descriptors, search_by_projection
from visnav.slam.trajectory import Trajectory
from visnav.slam.vocabulary import BowDatabase, Vocabulary

CAM = CameraIntrinsics(500.0, 500.0, 320.0, 240.0, 640, 480, baseline=2.0)
twists = st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=6).map(np.array)


@settings(max_examples=50, deadline=None)
@given(xi=twists)
def test_se3_exp_is_a_rigid_transform(xi: np.ndarray) -> None:
    t = se3_exp(xi)
    np.testing.assert_allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(t[:3, :3]) == pytest.approx(1.0)
    np.testing.assert_allclose(inverse(t) @ t, np.eye(4), atol=1e-12)
    assert rotation_angle(t) == pytest.approx(float(np.linalg.norm(xi[3:])), abs=1e-9)


def test_orthonormalize_projects_onto_so3() -> None:
    t = se3_exp(np.array([0.1, 0.2, 0.3, 0.2, -0.1, 0.05]))
    noisy = t.copy()
    noisy[:3, :3] *= 1.003
    fixed = orthonormalize(noisy)
    np.testing.assert_allclose(fixed[:3, :3] @ fixed[:3, :3].T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(fixed[:3, :3], t[:3, :3], atol=1e-9)


def _observations(t_cw: np.ndarray, rng: np.random.Generator, n: int = 150) -> PoseObservations:
    pw = transform(inverse(t_cw), rng.uniform([-2, -1.5, 1.5], [2, 1.5, 6], (n, 3)))
    pc = transform(t_cw, pw)
    uv = np.stack([CAM.fx * pc[:, 0] / pc[:, 2] + CAM.cx, CAM.fy * pc[:, 1] / pc[:, 2] + CAM.cy], 1)
    ur = uv[:, 0] - CAM.bf / pc[:, 2]
    ur[::3] = np.nan  # a third without depth
    return PoseObservations(pw, uv + rng.normal(scale=0.3, size=uv.shape), ur, np.ones(n))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), xi=twists)
def test_optimize_pose_recovers_the_pose_and_rejects_outliers(seed: int, xi: np.ndarray) -> None:
    rng = np.random.default_rng(seed)
    truth = se3_exp(xi)
    obs = _observations(truth, rng)
    bad = rng.choice(len(obs.uv), 30, replace=False)
    obs.uv[bad] += rng.uniform(15, 60, (30, 2)) * rng.choice([-1, 1], (30, 2))
    start = se3_exp(rng.normal(scale=[0.03] * 3 + [0.02] * 3)) @ truth
    t, inliers = optimize_pose(CAM, start, obs)
    assert np.linalg.norm(t[:3, 3] - truth[:3, 3]) < 0.01
    assert np.degrees(rotation_angle(t @ inverse(truth))) < 0.2
    assert not inliers[bad].any()
    assert inliers.sum() >= 0.9 * (len(obs.uv) - 30)
    cov = pose_covariance(CAM, t, obs, inliers)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    assert np.sqrt(np.linalg.eigvalsh(cov[:3, :3]).max()) < 0.05


def _frame(uv: np.ndarray, desc: np.ndarray, depth: np.ndarray) -> Frame:
    n = len(uv)
    return Frame(
        stamp_ns=0,
        uv=uv,
        octave=np.zeros(n, dtype=np.int64),
        descriptors=desc,
        depth=depth,
        u_right=uv[:, 0] - CAM.bf / depth,
        points_c=np.zeros((n, 3)),
        inv_sigma2=np.ones(n),
    )


def test_search_by_projection_finds_the_right_keypoints() -> None:
    rng = np.random.default_rng(4)
    n = 300
    t_cw = se3_exp(np.array([0.1, 0.0, 0.05, 0.02, 0.1, 0.0]))
    obs = _observations(t_cw, rng, n)
    desc = rng.integers(0, 256, (n, 32), dtype=np.uint8)
    order = rng.permutation(n)  # keypoints in another order than the points
    noisy_desc = desc.copy()
    noisy_desc[:, 0] ^= 0b101  # two bits differ
    depth = transform(t_cw, obs.points_w)[:, 2]
    frame = _frame(obs.uv[order], noisy_desc[order], depth[order])
    guess = se3_exp(np.array([0.01, -0.01, 0.0, 0.0, 0.005, 0.0])) @ t_cw
    pts, kps = search_by_projection(frame, CAM, guess, obs.points_w, desc, radius=15.0)
    inside = (obs.uv[:, 0] >= 5) & (obs.uv[:, 0] < 635) & (obs.uv[:, 1] >= 5) & (obs.uv[:, 1] < 475)
    assert len(pts) >= 0.95 * inside.sum() > 100
    np.testing.assert_array_equal(order[kps], pts)
    # depth that disagrees with the projection blocks the match
    frame.depth[:] = depth[order] * 2.0
    pts, _ = search_by_projection(frame, CAM, guess, obs.points_w, desc, radius=15.0)
    assert len(pts) == 0


def test_descriptor_distances_and_brute_force_matching() -> None:
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (50, 32), dtype=np.uint8)
    b = a.copy()
    b[:, 3] ^= 0xFF
    assert (hamming(a, b) == 8).all()
    m = hamming_matrix(a, a)
    assert (np.diag(m) == 0).all()
    assert m.shape == (50, 50)
    ref = np.array([[bin(int.from_bytes(x ^ y, "big")).count("1") for y in a[:5]] for x in a[:5]])
    np.testing.assert_array_equal(m[:5, :5], ref)
    q, t = match_descriptors(b, a)
    np.testing.assert_array_equal(q, t)
    assert len(q) == 50


def test_vocabulary_is_seeded_and_saves(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    prototypes = rng.integers(0, 256, (400, 32), dtype=np.uint8)
    subsets = [rng.choice(400, 120, replace=False) for _ in range(6)]

    def flip(d: np.ndarray) -> np.ndarray:  # a few random bits differ per observation
        bits = np.unpackbits(d, axis=1)
        mask = rng.random(bits.shape) < 0.03
        return np.packbits(bits ^ mask, axis=1)

    places = [flip(prototypes[s]) for s in subsets]
    v1 = Vocabulary.train(places, k=64, seed=3)
    v2 = Vocabulary.train(places, k=64, seed=3)
    np.testing.assert_array_equal(v1.words, v2.words)
    loaded = Vocabulary.load(v1.save(tmp_path / "voc.npz"))
    np.testing.assert_array_equal(loaded.words, v1.words)
    db = BowDatabase(v1)
    for i, p in enumerate(places):
        db.add(i, v1.transform(p))
    # a noisy revisit of place 4 scores best against place 4
    revisit = flip(prototypes[subsets[4]])
    ids, scores = db.query(v1.transform(revisit))
    assert int(ids[np.argmax(scores)]) == 4
    assert Vocabulary.score(v1.transform(places[2]), v1.transform(places[2])) == pytest.approx(1.0)


def test_trajectory_rejects_inconsistent_arrays() -> None:
    from visnav.slam.errors import TrajectoryFormatError

    with pytest.raises(TrajectoryFormatError, match="disagree"):
        Trajectory(np.zeros(3), np.zeros((2, 3)), np.zeros((3, 4)))
