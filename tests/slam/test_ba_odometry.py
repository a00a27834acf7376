"""Odometry factors in local bundle adjustment: gradients, and the compiled solver against gtsam."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.slam._ba_kernels import _add_odometry, levenberg_marquardt_odometry, odometry_cost
from visnav.slam.config import SlamConfig
from visnav.slam.geometry import inverse, se3_exp
from visnav.slam.odometry_prior import odometry_edges
from visnav.slam.optimizer import bundle_adjustment
from visnav.slam.slam_map import SlamMap
from visnav.slam.system import SlamSystem

from .conftest import Sequence


def _chain(rng: np.random.Generator, n: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses and measured relative poses (b in a's frame) of a chain 0-1-2-..."""
    poses = np.stack([se3_exp(rng.normal(0.0, [0.5] * 3 + [0.3] * 3)) for _ in range(n)])
    z = np.stack([poses[k] @ inverse(poses[k + 1]) for k in range(n - 1)])
    return poses, z, np.arange(n)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_odometry_gradient_matches_finite_differences(seed: int) -> None:
    rng = np.random.default_rng(seed)
    poses, z, _ = _chain(rng)
    # measurements a little off, as odometry is
    zinv = np.stack([inverse(se3_exp(rng.normal(0.0, 0.003, 6)) @ zz) for zz in z])
    ea, eb = np.arange(3, dtype=np.int64), np.arange(1, 4, dtype=np.int64)
    # unequal weights on rotated axes (a diff-drive prior's): a Jacobian that is right only
    # up to a rotation of the residual's frame passes with equal weights, not with these
    basis = np.stack([np.linalg.qr(rng.normal(size=(6, 6)))[0] for _ in range(3)])
    w = np.einsum("nij,j,nkj->nik", basis, [1e4, 1e2, 1e6, 3e5, 3e3, 3e7], basis)
    free = np.array([-1, 0, 1, 2], dtype=np.int64)
    hpp, bp = np.zeros((18, 18)), np.zeros(18)
    _add_odometry(poses, ea, eb, zinv, w, free, hpp, bp)
    np.testing.assert_allclose(hpp, hpp.T, atol=1e-6)
    step = 1e-6
    for k in (1, 2, 3):
        for i in range(6):
            d = np.zeros(6)
            d[i] = step
            up, down = poses.copy(), poses.copy()
            up[k] = se3_exp(d) @ poses[k]
            down[k] = se3_exp(-d) @ poses[k]
            grad = (odometry_cost(up, ea, eb, zinv, w) - odometry_cost(down, ea, eb, zinv, w)) / (
                2 * step
            )
            # bp is minus the gradient
            assert -bp[6 * (k - 1) + i] == pytest.approx(grad, rel=1e-4, abs=1e-2)


def test_a_chain_held_only_by_odometry_follows_it() -> None:
    """No observations at all: the free poses land where the odometry puts them."""
    rng = np.random.default_rng(4)
    truth, z, _ = _chain(rng, 5)
    start = truth.copy()
    for k in range(1, 5):
        start[k] = se3_exp(rng.normal(0.0, 0.05, 6)) @ truth[k]
    fixed = np.zeros(5, dtype=bool)
    fixed[0] = True
    none_i, none_f = np.zeros(0, dtype=np.int64), np.zeros(0)
    out, _, c0, c1 = levenberg_marquardt_odometry(
        start, np.zeros((0, 3)), none_i, none_i, np.zeros((0, 3)), np.zeros(0, dtype=bool),
        none_f, np.array([500.0, 500.0, 320.0, 240.0, 40.0]), 2.4, 2.8, fixed, 20,
        np.arange(4, dtype=np.int64), np.arange(1, 5, dtype=np.int64),
        np.stack([inverse(zz) for zz in z]), np.tile(np.diag([1e4] * 3 + [1e5] * 3), (4, 1, 1)),
    )  # fmt: skip
    assert c1 < 1e-12 < c0
    for k in range(5):
        np.testing.assert_allclose(out[k], truth[k], atol=1e-7)


def _mapped_with_odometry(seq: Sequence) -> SlamSystem:
    cfg = SlamConfig(n_features=400, local_ba=False, loop_closure=False)
    slam = SlamSystem(seq.camera, cfg, initial_pose=seq.poses[0])
    rng = np.random.default_rng(2)
    for i in range(30):  # odometry = the true camera pose with a growing error
        odom = se3_exp(rng.normal(0.0, 0.002 * (i + 1), 6)) @ seq.poses[i]
        slam.track(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]), odom_pose=odom)
    return slam


def test_odometry_edges_link_consecutive_keyframes(short_sequence: Sequence) -> None:
    slam = _mapped_with_odometry(short_sequence)
    m: SlamMap = slam.map
    ids = [kf.id for kf in m.keyframes]
    assert all(m.keyframes[k].odom_pose is not None for k in ids)
    edges = odometry_edges(slam.config, m, ids[-3:])
    assert [(e.i, e.j) for e in edges] == [(k - 1, k) for k in ids[-3:]]
    limit = slam.config.odometry_sigma_t**-2
    assert all(np.linalg.eigvalsh(e.information[:3, :3]).max() <= limit * (1 + 1e-9) for e in edges)
    m.keyframes[ids[-2]].bad = True  # a culled keyframe: its neighbours link across it
    edges = odometry_edges(slam.config, m, ids[-3:])
    assert [(e.i, e.j) for e in edges] == [(ids[-4], ids[-3]), (ids[-3], ids[-1])]
    assert odometry_edges(SlamConfig(odom_prior=False), m, ids) == []


def test_compiled_odometry_factors_match_gtsam(short_sequence: Sequence) -> None:
    """The same window and odometry factors, both solvers: the same optimum."""
    slam = _mapped_with_odometry(short_sequence)
    m0: SlamMap = slam.map
    ids = [kf.id for kf in m0.keyframes][-6:]
    edges = odometry_edges(slam.config, m0, ids)
    assert len(edges) >= 5
    levels = slam.extractor.inv_level_sigma2
    results = {}
    for name, dense in (("compiled", 100), ("gtsam", 0)):
        m = copy.deepcopy(m0)
        r = bundle_adjustment(
            m, slam.camera, ids, inv_sigma2_levels=levels, iterations=10,
            max_dense_keyframes=dense, odometry=edges,
        )  # fmt: skip
        assert r.ok, r.error
        results[name] = (m, r)
    (mc, rc), (mg, rg) = results["compiled"], results["gtsam"]
    # gtsam's Pose3 log differs from the first-order twist at second order
    assert rc.error_before == pytest.approx(rg.error_before, rel=1e-3)
    assert rc.error_after == pytest.approx(rg.error_after, rel=0.02)
    for k in ids:
        dt = np.linalg.norm(mc.keyframes[k].t_cw[:3, 3] - mg.keyframes[k].t_cw[:3, 3])
        assert dt < 5e-4
    # and the factors did something: without them the optimum differs
    plain = copy.deepcopy(m0)
    bundle_adjustment(plain, slam.camera, ids, inv_sigma2_levels=levels, iterations=10)
    moved = max(
        np.linalg.norm(plain.keyframes[k].t_cw[:3, 3] - mc.keyframes[k].t_cw[:3, 3]) for k in ids
    )
    assert moved > 1e-5


def _gtsam_camera_1(gtsam: Any, start: np.ndarray, zs: list[np.ndarray], models: list[Any]) -> Any:
    """Camera 1's pose (T_wc) from gtsam: camera 0 fixed, one BetweenFactorPose3 per measurement."""
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    values.insert(0, gtsam.Pose3(np.eye(4)))
    values.insert(1, gtsam.Pose3(start))
    graph.add(gtsam.NonlinearEqualityPose3(0, gtsam.Pose3(np.eye(4))))
    for z, model in zip(zs, models, strict=True):
        graph.add(gtsam.BetweenFactorPose3(0, 1, gtsam.Pose3(z), model))
    result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    return result.atPose3(1).matrix()


def test_per_axis_sigmas_mean_the_same_axes_in_both_solvers() -> None:
    """Two disagreeing measurements of one motion, each trusted on other axes.

    The optimum takes each axis from the measurement that is sure of it, in the compiled
    solver as in gtsam's ``BetweenFactorPose3`` (its tangent is rotation first).
    """
    gtsam = pytest.importorskip("gtsam")
    rng = np.random.default_rng(7)
    base = se3_exp(np.array([0.3, -0.1, 0.5, 0.05, 0.2, -0.1]))
    z1 = se3_exp(rng.normal(0.0, 0.01, 6)) @ base
    z2 = se3_exp(rng.normal(0.0, 0.01, 6)) @ base
    s1 = np.array([0.001, 0.05, 0.05, 0.0005, 0.05, 0.0005])  # sure of x, rot x, rot z
    s2 = np.array([0.05, 0.001, 0.001, 0.05, 0.0005, 0.05])  # sure of y, z, rot y
    poses = np.stack([np.eye(4), inverse(base)])  # T_cw: camera 1 at `base` in camera 0
    none_i, none_f = np.zeros(0, dtype=np.int64), np.zeros(0)
    out, _, _, _ = levenberg_marquardt_odometry(
        poses, np.zeros((0, 3)), none_i, none_i, np.zeros((0, 3)), np.zeros(0, dtype=bool),
        none_f, np.array([500.0, 500.0, 320.0, 240.0, 40.0]), 2.4, 2.8,
        np.array([True, False]), 30, np.zeros(2, dtype=np.int64), np.ones(2, dtype=np.int64),
        np.stack([inverse(z1), inverse(z2)]), np.stack([np.diag(s1**-2), np.diag(s2**-2)]),
    )  # fmt: skip
    models = [
        gtsam.noiseModel.Diagonal.Sigmas(np.concatenate([sig[3:], sig[:3]])) for sig in (s1, s2)
    ]
    t_wc_gtsam = _gtsam_camera_1(gtsam, base, [z1, z2], models)
    t_wc_compiled = inverse(out[1])
    np.testing.assert_allclose(t_wc_compiled[:3, 3], t_wc_gtsam[:3, 3], atol=2e-4)
    np.testing.assert_allclose(t_wc_compiled[:3, :3], t_wc_gtsam[:3, :3], atol=2e-4)
    # and each axis came from the measurement sure of it (camera 1's frame)
    for z, sure in ((z1, [0]), (z2, [1, 2])):
        local = inverse(z) @ t_wc_compiled
        assert np.abs(local[sure, 3]).max() < 0.003


def test_full_information_means_the_same_in_both_solvers() -> None:
    """Information matrices with cross terms (a diff drive's sideways axis is no camera axis).

    The compiled solver and gtsam's ``BetweenFactorPose3`` with ``Gaussian.Information``
    (rows and columns swapped to gtsam's rotation-first tangent, as the optimiser does)
    reach the same optimum.
    """
    gtsam = pytest.importorskip("gtsam")
    rng = np.random.default_rng(11)
    base = se3_exp(np.array([0.2, 0.05, 0.4, -0.05, 0.1, 0.02]))
    zs = [se3_exp(rng.normal(0.0, 0.01, 6)) @ base for _ in range(2)]
    infos = []
    for _ in range(2):
        q = np.linalg.qr(rng.normal(size=(6, 6)))[0]
        infos.append(q @ np.diag(rng.uniform(1e2, 1e7, 6)) @ q.T)
    poses = np.stack([np.eye(4), inverse(base)])
    none_i, none_f = np.zeros(0, dtype=np.int64), np.zeros(0)
    out, _, _, _ = levenberg_marquardt_odometry(
        poses, np.zeros((0, 3)), none_i, none_i, np.zeros((0, 3)), np.zeros(0, dtype=bool),
        none_f, np.array([500.0, 500.0, 320.0, 240.0, 40.0]), 2.4, 2.8,
        np.array([True, False]), 30, np.zeros(2, dtype=np.int64), np.ones(2, dtype=np.int64),
        np.stack([inverse(z) for z in zs]), np.stack(infos),
    )  # fmt: skip
    swap = np.r_[3:6, 0:3]
    models = [gtsam.noiseModel.Gaussian.Information(i[np.ix_(swap, swap)]) for i in infos]
    t_wc_gtsam = _gtsam_camera_1(gtsam, base, zs, models)
    t_wc_compiled = inverse(out[1])
    np.testing.assert_allclose(t_wc_compiled[:3, 3], t_wc_gtsam[:3, 3], atol=2e-4)
    np.testing.assert_allclose(t_wc_compiled[:3, :3], t_wc_gtsam[:3, :3], atol=2e-4)
