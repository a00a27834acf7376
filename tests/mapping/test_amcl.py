"""AMCL's filter without a graph: convergence, refusal to converge, determinism, models."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.mapping.amcl import Amcl, AmclError, AmclParams, kld_sample_limit
from visnav.mapping.amcl_models import (
    beam_endpoints,
    likelihood_field_weights,
    sample_diff_motion,
    select_beams,
)
from visnav.mapping.likelihood_field import LikelihoodField
from visnav.mapping.map_io import MapMetadata, OccupancyMap

ANGLES = np.linspace(-0.76, 0.76, 160)  # the car's 87 degree depth scan, every 4th beam
INC = float(ANGLES[1] - ANGLES[0])
LASER = (0.1, 0.0, 0.0)  # the scan frame 0.1 m ahead of the base
# the car's configuration (car.launch.yaml): tighter than nav2's defaults for a clean sim
CAR = {
    "laser_model_type": "likelihood_field_prob",
    "alpha1": 0.05, "alpha2": 0.05, "alpha3": 0.05, "alpha4": 0.05,
    "update_min_d": 0.1, "update_min_a": 0.1,
}  # fmt: skip


@pytest.fixture(scope="module")
def field(amcl_world: SimpleNamespace) -> LikelihoodField:
    w = amcl_world
    return LikelihoodField(w.office_grid(), w.RES, w.ORIGIN, max_dist=2.0)


def _scans(w: SimpleNamespace, steps: int) -> list[tuple[tuple[float, float, float], np.ndarray]]:
    grid = w.office_grid()
    out = []
    for p in w.square_drive(steps):
        lx, ly = p[0] + LASER[0] * math.cos(p[2]), p[1] + LASER[0] * math.sin(p[2])
        out.append((p, w.raycast(grid, (lx, ly, p[2]), ANGLES)))
    return out


@pytest.fixture(scope="module")
def drive(amcl_world: SimpleNamespace) -> list[tuple[tuple[float, float, float], np.ndarray]]:
    """Ground-truth poses and exact scans of a 12 m loop (ray casting is the slow part)."""
    return _scans(amcl_world, 240)


@pytest.fixture(scope="module")
def short_drive(amcl_world: SimpleNamespace) -> list[tuple[tuple[float, float, float], np.ndarray]]:
    """The loop's first 1.5 m."""
    return _scans(amcl_world, 30)


def _run(
    amcl: Amcl,
    drive: list[tuple[tuple[float, float, float], np.ndarray]],
    *,
    seed: int = 7,
    slip: float = 0.02,
) -> list[float]:
    """Feed a drifting odometry and noisy scans; return the map-pose error at every step."""
    rng = np.random.default_rng(seed)
    odom = np.array(drive[0][0], dtype=float)
    prev = drive[0][0]
    errors = []
    for truth, ranges in drive:
        dx, dy = truth[0] - prev[0], truth[1] - prev[1]
        c, s = math.cos(prev[2]), math.sin(prev[2])
        fwd, lat = c * dx + s * dy, -s * dx + c * dy
        turn = math.remainder(truth[2] - prev[2], 2 * math.pi)
        fwd *= 1 + rng.normal(0, slip)
        turn = turn * (1 + rng.normal(0, slip)) + 0.02 * fwd  # heading drift 0.02 rad/m
        co, so = math.cos(odom[2]), math.sin(odom[2])
        odom += (co * fwd - so * lat, so * fwd + co * lat, turn)
        prev = truth
        noisy = ranges + rng.normal(0, 0.01, ranges.shape)
        beams = select_beams(noisy, -0.76, INC, range_min=0.1, range_max=10.0, max_beams=60)
        amcl.update((odom[0], odom[1], odom[2]), beams, LASER)
        mo = amcl.map_to_odom()
        if mo is None:
            errors.append(math.inf)
            continue
        cm, sm = math.cos(mo[2]), math.sin(mo[2])
        ex = mo[0] + cm * odom[0] - sm * odom[1]
        ey = mo[1] + sm * odom[0] + cm * odom[1]
        errors.append(math.hypot(ex - truth[0], ey - truth[1]))
    return errors


@pytest.mark.slow
@pytest.mark.ci
def test_converges_from_an_offset_initial_pose(field: LikelihoodField, drive: list) -> None:
    amcl = Amcl(field, AmclParams(seed=1, **CAR))
    x, y, yaw = drive[0][0]
    amcl.set_initial_pose(x + 0.3, y - 0.25, yaw + 0.1)
    assert amcl.estimate is not None
    assert math.hypot(amcl.estimate.x - x, amcl.estimate.y - y) > 0.2  # it starts off
    errors = np.array(_run(amcl, drive))
    assert amcl.status.state == "localized", amcl.status.text
    settled = errors[100:]  # after 5 m of driving (and 3 turns)
    assert math.sqrt(np.mean(settled**2)) < 0.05
    assert settled.max() < 0.1
    assert AmclParams().min_particles <= amcl.poses.shape[0] <= AmclParams().max_particles


@pytest.mark.slow
@pytest.mark.ci
def test_nav2_defaults_also_localise(field: LikelihoodField, drive: list) -> None:
    amcl = Amcl(field, AmclParams(seed=2))
    amcl.set_initial_pose(*drive[0][0])
    errors = np.array(_run(amcl, drive))
    assert amcl.status.localized
    assert math.sqrt(np.mean(errors[60:] ** 2)) < 0.15


def test_far_outside_the_map_never_localises(field: LikelihoodField, short_drive: list) -> None:
    amcl = Amcl(field, AmclParams(seed=1, **CAR))
    amcl.set_initial_pose(40.0, -30.0, 0.0)
    assert amcl.status.state == "not_converged"
    assert "outside the map" in amcl.status.text
    assert "(40.00, -30.00)" in amcl.status.text
    _run(amcl, short_drive)
    assert amcl.status.state == "not_converged"
    assert not amcl.status.localized


def test_wrong_start_inside_the_map_is_refused(field: LikelihoodField, short_drive: list) -> None:
    amcl = Amcl(field, AmclParams(seed=1, **CAR))
    amcl.set_initial_pose(8.0, 6.0, 2.5)  # the right-hand room, facing elsewhere
    _run(amcl, short_drive[:5])
    assert amcl.status.state == "not_converged", amcl.status.text
    assert "cannot localise" in amcl.status.text
    assert "beams fit the map" in amcl.status.text
    assert amcl.status.scan_fit is not None
    assert amcl.status.scan_fit < 0.5


@pytest.mark.slow
@pytest.mark.ci
def test_kidnapped_after_localising_is_lost(field: LikelihoodField, drive: list) -> None:
    amcl = Amcl(field, AmclParams(seed=1, **CAR))
    amcl.set_initial_pose(*drive[0][0])
    _run(amcl, drive[:40])
    assert amcl.status.localized
    amcl.poses[:, 0] += 2.5  # teleport the belief (a kidnapped robot, seen from the filter)
    amcl.poses[:, 2] += 1.0
    states = []
    for k in range(40, 80, 5):
        _run(amcl, drive[k : k + 5])
        states.append(amcl.status.state)
    assert "lost" in states, states  # (a filter without recovery may later settle elsewhere)
    assert "lost after" in amcl.status.text or amcl.status.state != "lost"


@pytest.mark.slow
@pytest.mark.ci
def test_same_seed_same_particles(field: LikelihoodField, drive: list) -> None:
    runs = []
    for seed in (5, 5, 6):
        amcl = Amcl(field, AmclParams(seed=seed, **CAR))
        amcl.set_initial_pose(*drive[0][0])
        _run(amcl, drive[:50])
        runs.append(amcl.poses.copy())
    np.testing.assert_array_equal(runs[0], runs[1])
    assert runs[0].shape != runs[2].shape or not np.array_equal(runs[0], runs[2])


@pytest.mark.slow
@pytest.mark.ci
def test_global_localisation_with_recovery(field: LikelihoodField, drive: list) -> None:
    params = AmclParams(
        seed=3, max_particles=5000, recovery_alpha_slow=0.001, recovery_alpha_fast=0.1, **CAR
    )
    amcl = Amcl(field, params)
    amcl.global_localization()
    assert amcl.status.state == "initial"
    errors = np.array(_run(amcl, drive))
    assert amcl.status.localized, amcl.status.text
    assert errors[-40:].max() < 0.15


# ---------------------------------------------------------------------- models and parts
def test_motion_model_without_noise_moves_every_particle_alike() -> None:
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, math.pi / 2]])
    rng = np.random.default_rng(0)
    sample_diff_motion(poses, (0.0, 0.0, 0.0), (1.0, 0.0, 0.3), (0.0, 0.0, 0.0, 0.0), rng)
    np.testing.assert_allclose(poses, [[1.0, 0.0, 0.3], [1.0, 2.0, math.pi / 2 + 0.3]], atol=1e-12)
    back = np.array([[0.0, 0.0, 0.0]])
    sample_diff_motion(back, (0.0, 0.0, 0.0), (-0.5, 0.0, 0.0), (0.1, 0.1, 0.1, 0.1), rng)
    assert back[0, 0] == pytest.approx(-0.5, abs=0.2)  # backwards, not a half turn
    assert abs(back[0, 2]) < 0.3


def test_select_beams_follows_amcl() -> None:
    ranges = np.array([1.0, np.nan, 0.05, 10.0, np.inf, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    beams = select_beams(ranges, -1.0, 0.1, range_min=0.1, range_max=10.0, max_beams=6)
    np.testing.assert_allclose(beams.ranges, [1.0, 3.0, 5.0, 7.0])  # step 2, 6 considered
    np.testing.assert_allclose(beams.angles, [-1.0, -0.4, -0.2, 0.0], atol=1e-12)
    assert beams.total == 6


def test_likelihood_field_distances() -> None:
    grid = np.zeros((20, 20), dtype=np.int8)
    grid[:, 10:] = 100  # wall surface at x = 1.0 m (cells of 0.1 m)
    f = LikelihoodField(grid, 0.1, (0.0, 0.0, 0.0), max_dist=0.5)
    d = f.distance_at(np.array([[1.0, 1.0], [0.7, 1.0], [0.0, 1.0], [-3.0, 1.0], [1.2, 1.0]]))
    np.testing.assert_allclose(d, [0.0, 0.3, 0.5, 0.5, 0.2], atol=1e-6)
    rotated = LikelihoodField(grid, 0.1, (5.0, 5.0, math.pi / 2), max_dist=0.5)
    assert rotated.distance_at(np.array([[4.0, 6.0]]))[0] == pytest.approx(0.0, abs=1e-6)
    poses = f.sample_free(500, np.random.default_rng(0))
    assert f.is_free(poses[:, :2]).all()
    assert f.bounds() == pytest.approx((0.0, 0.0, 2.0, 2.0))


def test_kld_limit_grows_with_bins_within_bounds() -> None:
    p = AmclParams()
    n = kld_sample_limit(np.arange(1, 400), p)
    assert n[0] == p.max_particles  # one bin: no information, amcl keeps the maximum
    assert (np.diff(n[1:]) >= 0).all()
    assert n.min() >= p.min_particles
    assert n.max() <= p.max_particles


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(AmclError, match="min_particles 3000 > max_particles 2000"):
        AmclParams(min_particles=3000)
    with pytest.raises(AmclError, match="laser_model_type 'beam'"):
        AmclParams(laser_model_type="beam")
    with pytest.raises(AmclError, match="omni"):
        AmclParams(robot_model_type="nav2_amcl::OmniMotionModel")


@settings(max_examples=60, deadline=None)
@given(
    width=st.integers(-2, 6),
    height=st.integers(-2, 6),
    data=st.lists(st.integers(-128, 127), max_size=40),
    resolution=st.floats(allow_nan=True, allow_infinity=True),
)
def test_fuzz_map_message_raises_only_visnav_errors(
    width: int, height: int, data: list[int], resolution: float
) -> None:

    grid = np.zeros((1, 1), dtype=np.int8)
    msg = OccupancyMap(
        grid, MapMetadata(image=Path("x"), resolution=1.0, origin=(0, 0, 0))
    ).to_msg()
    msg.info.width, msg.info.height, msg.info.resolution = width, height, resolution
    msg.data = np.array(data, dtype=np.int8)
    try:
        field = LikelihoodField.from_msg(msg)
    except VisnavError:
        return
    assert field.distance.shape == (height, width)
    amcl = Amcl(field, AmclParams(max_particles=50, min_particles=10))
    amcl.set_initial_pose(0.0, 0.0, 0.0)
    beams = select_beams(np.ones(10), -0.5, 0.1, range_min=0.1, range_max=5.0, max_beams=10)
    amcl.update((0.0, 0.0, 0.0), beams, (0.0, 0.0, 0.0))


def test_same_seed_same_particles_short(field: LikelihoodField, short_drive: list) -> None:
    runs = []
    for seed in (5, 5, 6):
        amcl = Amcl(field, AmclParams(seed=seed, **CAR))
        amcl.set_initial_pose(*short_drive[0][0])
        _run(amcl, short_drive)
        runs.append((amcl.poses.copy(), amcl.map_to_odom()))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    assert runs[0][1] == runs[1][1]
    assert runs[0][1] != runs[2][1]


def test_laser_kernel_matches_a_numpy_reference(field: LikelihoodField, short_drive: list) -> None:
    pose, ranges = short_drive[0]
    beams = select_beams(ranges, -0.76, INC, range_min=0.1, range_max=10.0, max_beams=60)
    rng = np.random.default_rng(0)
    poses = np.array(pose) + rng.normal(0.0, 0.5, (300, 3))
    poses[:5, :2] = [[-30.0, 0.0], [0.0, 40.0], [-1.0, -1.0], [10.95, 7.95], [11.2, 8.1]]
    got = likelihood_field_weights(
        field, poses, beams, LASER, z_hit=0.6, z_rand=0.4, sigma_hit=0.15
    )
    d = field.distance_at(beam_endpoints(poses, beams, LASER)).astype(np.float64)
    pz = 0.6 * np.exp(-d * d / (2 * 0.15**2)) + 0.4 / beams.range_max
    np.testing.assert_allclose(got, 1.0 + (pz**3).sum(axis=1), rtol=1e-6)
    assert got.max() > 1.5 * got.min()  # the poses are told apart
    logp = likelihood_field_weights(
        field, poses, beams, LASER, z_hit=0.6, z_rand=0.4, sigma_hit=0.15, product=True
    )
    np.testing.assert_allclose(logp, np.log(pz).sum(axis=1), rtol=1e-6)


def test_beams_into_unknown_space_are_no_evidence(
    field: LikelihoodField, short_drive: list
) -> None:
    amcl = Amcl(field, AmclParams(seed=1, **CAR))
    pose, ranges = short_drive[0]
    amcl.set_initial_pose(*pose)
    beams = select_beams(ranges, -0.76, INC, range_min=0.1, range_max=10.0, max_beams=60)
    assert amcl.scan_fit(beams, LASER) == 1.0
    blind = LikelihoodField(np.full((180, 240), -1, dtype=np.int8), 0.05, (-1.0, -1.0, 0.0))
    amcl.set_map(blind)  # the same place, never mapped: nothing to judge the pose by
    assert amcl.scan_fit(beams, LASER) is None
    half = np.asarray(field.free, dtype=np.int8) * 0 - 1  # unknown, but keep the walls
    half[field.occupied] = 100
    amcl.set_map(LikelihoodField(half, 0.05, (-1.0, -1.0, 0.0)))
    assert amcl.scan_fit(beams, LASER) == 1.0
    wrong = select_beams(ranges * 0.5, -0.76, INC, range_min=0.1, range_max=10.0, max_beams=60)
    amcl.set_map(field)  # known free space where the beams end: evidence against the pose
    fit = amcl.scan_fit(wrong, LASER)
    assert fit is not None
    assert fit < 0.3
