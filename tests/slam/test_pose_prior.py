"""The odometry prior of the tracked pose (geometry.PosePrior, slam.odometry_prior)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.config import SlamConfig
from visnav.slam.errors import SlamInputError
from visnav.slam.geometry import (
    PoseObservations,
    PosePrior,
    inverse,
    optimize_pose,
    rotation_angle,
    se3_exp,
    so3_log,
    transform,
)
from visnav.slam.odometry_prior import odometry_prior

CAM = CameraIntrinsics(554.0, 554.0, 320.0, 240.0, 640, 480, baseline=0.002)
rotations = (
    st.lists(st.floats(-1.8, 1.8), min_size=3, max_size=3)
    .map(np.array)
    .filter(lambda phi: float(np.linalg.norm(phi)) < 3.1)  # log's range: angles below pi
)


@settings(max_examples=60, deadline=None)
@given(phi=rotations)
def test_so3_log_inverts_the_exponential(phi: np.ndarray) -> None:
    r = se3_exp(np.concatenate([np.zeros(3), phi]))[:3, :3]
    np.testing.assert_allclose(so3_log(r), phi, atol=1e-9)


def test_so3_log_at_the_identity_and_at_half_a_turn() -> None:
    np.testing.assert_array_equal(so3_log(np.eye(3)), np.zeros(3))
    half = se3_exp(np.array([0, 0, 0, 0, 0, np.pi]))[:3, :3]
    assert np.linalg.norm(so3_log(half)) == pytest.approx(np.pi)
    assert abs(so3_log(half)[2]) == pytest.approx(np.pi)


def _corridor_end(t_cw: np.ndarray, rng: np.random.Generator, n: int = 300) -> PoseObservations:
    """Points on the far wall of a corridor, 5-6 m ahead, within +-0.6 m: the pose is weak."""
    pc = np.stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-0.5, 0.5, n), rng.uniform(5, 6, n)], 1)
    pw = transform(inverse(t_cw), pc)
    uv = np.stack([CAM.fx * pc[:, 0] / pc[:, 2] + CAM.cx, CAM.fy * pc[:, 1] / pc[:, 2] + CAM.cy], 1)
    # depth noise of a Kinect at 5 m (~4 cm) in the virtual right image
    z_meas = pc[:, 2] + rng.normal(scale=0.04, size=n)
    ur = uv[:, 0] - CAM.bf / z_meas
    uv = uv + rng.normal(scale=0.5, size=uv.shape)
    return PoseObservations(pw, uv, ur, np.ones(n))


def _err(t: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    e = t @ inverse(truth)
    return float(np.linalg.norm(e[:3, 3])), float(np.degrees(rotation_angle(e)))


def test_the_prior_holds_a_pose_far_points_leave_weak() -> None:
    cam_cfg = SlamConfig()
    rng = np.random.default_rng(3)
    worst_free, worst_prior = 0.0, 0.0
    for _ in range(20):
        truth = se3_exp(rng.normal(scale=[0.2] * 3 + [0.1] * 3))
        obs = _corridor_end(truth, rng)
        # odometry's prediction: 3 mm off, 0.05 degrees off
        pred = se3_exp(np.array([0.003, 0, 0, 0, np.radians(0.05), 0])) @ truth
        info = np.diag(
            [cam_cfg.odometry_sigma_t**-2] * 3
            + [np.radians(cam_cfg.odometry_sigma_r_deg) ** -2] * 3
        )
        start = se3_exp(np.array([0.08, 0, 0, 0, 0.0, 0])) @ truth  # 8 cm sideways
        free, _ = optimize_pose(CAM, start, obs)
        held, inl = optimize_pose(CAM, start, obs, prior=PosePrior(pred, info))
        worst_free = max(worst_free, _err(free, truth)[0])
        worst_prior = max(worst_prior, _err(held, truth)[0])
        assert inl.sum() > 250
    assert worst_prior < 0.01
    assert worst_free > 2 * worst_prior  # the far points alone leave the sideways shift


def test_the_prior_does_not_override_strong_matches() -> None:
    rng = np.random.default_rng(5)
    truth = se3_exp(np.array([0.1, -0.05, 0.2, 0.05, 0.1, -0.02]))
    pc = rng.uniform([-2, -1.5, 1.0], [2, 1.5, 4], (300, 3))
    pw = transform(inverse(truth), pc)
    uv = np.stack([CAM.fx * pc[:, 0] / pc[:, 2] + CAM.cx, CAM.fy * pc[:, 1] / pc[:, 2] + CAM.cy], 1)
    obs = PoseObservations(
        pw, uv + rng.normal(scale=0.3, size=uv.shape), uv[:, 0] - CAM.bf / pc[:, 2], np.ones(300)
    )
    wrong = se3_exp(np.array([0.05, 0, 0, 0, 0.02, 0])) @ truth  # 5 cm, 1.1 degrees off
    info = np.diag([0.005**-2] * 3 + [np.radians(0.1) ** -2] * 3)
    t, _ = optimize_pose(CAM, wrong, obs, prior=PosePrior(wrong, info))
    dt, dr = _err(t, truth)
    assert dt < 0.005  # the matches win; the prior pulls by under a fifth of its offset
    assert dr < 0.25


def test_odometry_prior_grows_with_the_motion_and_can_be_off() -> None:
    cfg = SlamConfig()
    last = np.eye(4)
    pred = np.eye(4)
    still = odometry_prior(cfg, pred, np.eye(4), last)
    assert still is not None
    assert np.diag(still.information)[0] == pytest.approx(cfg.odometry_sigma_t**-2)
    moved = se3_exp(np.array([0, 0, 0.5, 0, 0.3, 0]))  # 0.5 m ahead, 17 degrees turned
    p = odometry_prior(cfg, pred, moved, last)
    assert p is not None
    sigma_t = cfg.odometry_sigma_t + cfg.odometry_sigma_t_rel * np.linalg.norm(
        inverse(moved)[:3, 3]
    )
    assert np.diag(p.information)[0] == pytest.approx(sigma_t**-2)
    moved_m = np.linalg.norm(inverse(moved)[:3, 3])
    sigma_r = np.radians(cfg.odometry_sigma_r_deg) + cfg.odometry_sigma_r_rel * 0.3
    sigma_r += cfg.odometry_sigma_r_per_m * moved_m
    assert np.diag(p.information)[5] == pytest.approx(sigma_r**-2)
    assert odometry_prior(SlamConfig(odom_prior=False), pred, moved, last) is None
    assert odometry_prior(cfg, None, moved, last) is None
    assert odometry_prior(cfg, pred, moved, None) is None


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("odometry_sigma_t", 0.0),
        ("odometry_sigma_r_deg", -1.0),
        ("odometry_sigma_t_rel", -0.1),
        ("odometry_sigma_r_rel", float("nan")),
        ("odometry_sigma_t", "5 mm"),
        ("odometry_sigma_r_per_m", -0.01),
        ("odometry_sigma_t_lateral", 0.0),
        ("odometry_model", "ackermann"),
    ],
)
def test_bad_odometry_sigmas_are_refused(field: str, value: object) -> None:
    with pytest.raises(SlamInputError, match=field):
        SlamConfig(**{field: value})  # type: ignore[arg-type]


def _camera_on_a_ground_robot(x: float, yaw: float) -> np.ndarray:
    """``T_odom_camera`` of an optical camera (z ahead, y down) on a base at (x, 0, yaw)."""
    c, s = np.cos(yaw), np.sin(yaw)
    base = np.eye(4)
    base[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    base[0, 3] = x
    optical = np.eye(4)
    optical[:3, :3] = [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
    optical[:3, 3] = [0.2, 0.0, 0.3]  # ahead of the wheel axle, as the car's camera
    return base @ optical


def test_a_diff_drive_prior_is_tight_only_sideways() -> None:
    """Driving straight ahead: the optical x axis (sideways, horizontal) is held tighter."""
    last, now = _camera_on_a_ground_robot(0.0, 0.0), _camera_on_a_ground_robot(0.25, 0.0)
    omni = odometry_prior(SlamConfig(), np.eye(4), now, last)
    diff = odometry_prior(SlamConfig(odometry_model="diff"), np.eye(4), now, last)
    assert omni is not None
    assert diff is not None
    cfg = SlamConfig()
    sigma_t = cfg.odometry_sigma_t + cfg.odometry_sigma_t_rel * 0.25
    sigma_r = np.radians(cfg.odometry_sigma_r_deg) + cfg.odometry_sigma_r_per_m * 0.25
    lateral = cfg.odometry_sigma_t_lateral + 0.25 * sigma_r
    expected = np.diag([lateral**-2, sigma_t**-2, sigma_t**-2] + [sigma_r**-2] * 3)
    np.testing.assert_allclose(diff.information, expected, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(omni.information, np.diag([sigma_t**-2] * 3 + [sigma_r**-2] * 3))


@settings(max_examples=50, deadline=None)
@given(
    x=st.floats(-2.0, 2.0),
    yaw=st.floats(-np.pi, np.pi),
    step=st.floats(0.0, 0.5),
    turn=st.floats(-0.5, 0.5),
)
def test_a_diff_drive_prior_is_never_looser_than_omni(
    x: float, yaw: float, step: float, turn: float
) -> None:
    """Same or tighter in every direction, symmetric and positive definite."""
    last = _camera_on_a_ground_robot(x, yaw)
    now = _camera_on_a_ground_robot(x + step * np.cos(yaw), yaw + turn)
    now[1, 3] += step * np.sin(yaw)
    omni = odometry_prior(SlamConfig(), np.eye(4), now, last)
    diff = odometry_prior(SlamConfig(odometry_model="diff"), np.eye(4), now, last)
    assert omni is not None
    assert diff is not None
    np.testing.assert_allclose(diff.information, diff.information.T)
    assert np.linalg.eigvalsh(diff.information).min() > 0.0
    assert (
        np.linalg.eigvalsh(diff.information - omni.information).min()
        > -1e-6 * np.abs(omni.information).max()
    )
