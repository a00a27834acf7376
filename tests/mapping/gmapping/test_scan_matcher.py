"""gmapping's scan matcher: hill climbing recovers known offsets; kernels equal the Python loop."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from visnav.mapping.gmapping import _scan_kernels as k
from visnav.mapping.gmapping.maps import ParticleMaps
from visnav.mapping.gmapping.reference import optimize_py, score_py

ANGLES = np.arange(360) * (2 * math.pi / 360)
LASER = np.array([-0.032, 0.0, 0.0])
TRUE = (0.3, -1.6, 0.4)
USABLE, SIGMA, LSIGMA = 3.0, 0.05, 0.075


def _scan(room: SimpleNamespace, pose: tuple[float, float, float]) -> np.ndarray:
    x, y, t = pose
    lx, ly = x + math.cos(t) * LASER[0], y + math.sin(t) * LASER[0]
    return room.cast(room.segments, lx, ly, t + ANGLES)


def _map(room: SimpleNamespace, particles: int = 1) -> ParticleMaps:
    """A map made of scans from poses around TRUE (each registered at its true pose)."""
    maps = ParticleMaps(particles, 0.05, (-4.0, -4.0, 4.0, 4.0))
    for dx, dy, dt in [(0, 0, 0), (-0.3, 0.1, 0.2), (0.25, 0.3, -0.3), (-0.1, 0.5, 1.0)]:
        pose = (TRUE[0] + dx, TRUE[1] + dy, TRUE[2] + dt)
        poses = np.tile(np.array(pose), (particles, 1))
        maps.register(poses, _scan(room, pose), ANGLES, LASER, USABLE)
    return maps


def _optimize(
    maps: ParticleMaps, init: tuple[float, float, float], ranges: np.ndarray
) -> tuple[float, float, float, float]:
    return k.optimize(
        maps.tables[0], maps.accx, maps.accy, maps.hits, maps.visits, np.array(init), ranges,
        ANGLES, LASER, USABLE, SIGMA, maps.delta, maps.cx0, maps.cy0, 1, 0, 0.05, 0.05, 5,
    )  # fmt: skip


@pytest.mark.parametrize(
    "offset", [(0.08, 0.0, 0.0), (0.0, -0.07, 0.03), (-0.05, 0.05, -0.05), (0.1, 0.06, 0.06)]
)
def test_scan_matcher_recovers_a_known_offset(
    synthetic_room: SimpleNamespace, offset: tuple[float, float, float]
) -> None:
    maps = _map(synthetic_room)
    # a new scan from a pose the map never saw, matched from a wrong initial guess
    truth = (TRUE[0] + 0.05, TRUE[1] + 0.12, TRUE[2] - 0.1)
    ranges = _scan(synthetic_room, truth)
    init = (truth[0] + offset[0], truth[1] + offset[1], truth[2] + offset[2])
    x, y, t, best = _optimize(maps, init, ranges)
    # gmapping's score compares endpoints with cell means (5 cm cells): its optimum is
    # within about a third of a cell of the truth, whatever the start
    assert math.hypot(x - truth[0], y - truth[1]) < 0.02, (x, y)
    assert abs(t - truth[2]) < 0.015, t
    start = k.score(
        maps.tables[0], maps.accx, maps.accy, maps.hits, maps.visits, np.array(init), ranges,
        ANGLES, LASER, USABLE, SIGMA, maps.delta, maps.cx0, maps.cy0, 1, 0,
    )  # fmt: skip
    assert best > start


def test_scan_matcher_without_a_map_keeps_the_pose(synthetic_room: SimpleNamespace) -> None:
    maps = ParticleMaps(1, 0.05, (-4.0, -4.0, 4.0, 4.0))
    x, y, t, best = _optimize(maps, TRUE, _scan(synthetic_room, TRUE))
    assert (x, y, t) == TRUE
    assert best == 0.0


def test_compiled_scores_equal_the_plain_python_loop(synthetic_room: SimpleNamespace) -> None:
    maps = _map(synthetic_room)
    rng = np.random.default_rng(7)
    ranges = _scan(synthetic_room, TRUE)
    for _ in range(12):
        pose = np.array(TRUE) + rng.normal(0.0, [0.05, 0.05, 0.05])
        for kernel, lskip in [(1, 0), (0, 0), (2, 1)]:
            got = k.likelihood_and_score(
                maps.tables[0], maps.accx, maps.accy, maps.hits, maps.visits, pose, ranges,
                ANGLES, LASER, USABLE, SIGMA, LSIGMA, maps.delta, maps.cx0, maps.cy0, kernel, lskip,
            )  # fmt: skip
            want = score_py(
                maps, 0, tuple(pose), ranges, ANGLES, tuple(LASER), usable=USABLE, sigma=SIGMA,
                lsigma=LSIGMA, kernel=kernel, lskip=lskip,
            )  # fmt: skip
            assert got == want  # bit for bit: the same arithmetic in the same order


def test_compiled_optimize_equals_the_plain_python_loop(synthetic_room: SimpleNamespace) -> None:
    maps = _map(synthetic_room)
    truth = (TRUE[0] + 0.05, TRUE[1] + 0.12, TRUE[2] - 0.1)
    ranges = _scan(synthetic_room, truth)
    init = (truth[0] + 0.04, truth[1] - 0.03, truth[2] + 0.02)
    got = _optimize(maps, init, ranges)
    want = optimize_py(maps, 0, init, ranges, ANGLES, tuple(LASER), usable=USABLE, sigma=SIGMA)
    assert got == want  # bit for bit


def test_a_write_to_a_shared_patch_copies_it(synthetic_room: SimpleNamespace) -> None:
    maps = _map(synthetic_room, particles=3)
    maps.resample(np.array([0, 0, 0]))  # three particles share particle 0's patches
    shared = maps.patches_in_use
    assert np.array_equal(maps.tables[0], maps.tables[2])
    assert maps.refcount[maps.tables[0][maps.tables[0] >= 0]].min() == 3
    other = (TRUE[0] + 0.6, TRUE[1] + 0.9, TRUE[2])
    poses = np.array([TRUE, TRUE, other])  # particle 2 sees the scan elsewhere
    maps.register(poses, _scan(synthetic_room, TRUE), ANGLES, LASER, USABLE)
    np.testing.assert_array_equal(maps.values(0)[0], maps.values(1)[0])
    assert not np.array_equal(maps.values(0)[0], maps.values(2)[0])
    assert maps.patches_in_use > shared
    assert maps.refcount.max() <= 3


def test_a_bounded_score_is_exact_or_below_the_bound(synthetic_room: SimpleNamespace) -> None:
    """The hill climbing's early exit never changes a score that could exceed the bound."""
    maps = _map(synthetic_room)
    ranges = _scan(synthetic_room, TRUE)
    lx, ly = TRUE[0] + math.cos(TRUE[2]) * LASER[0], TRUE[1] + math.sin(TRUE[2]) * LASER[0]
    win = k._window(
        maps.tables[0], maps.accx, maps.accy, maps.hits, maps.visits, lx, ly, USABLE,
        maps.delta, maps.cx0, maps.cy0, 1,
    )  # fmt: skip
    rcs = k._beam_table(ranges, k._used_beams(ranges, USABLE, 0), ANGLES)
    dists = np.empty(rcs.shape[1])
    geo = np.empty((4, rcs.shape[1]))
    rng = np.random.default_rng(3)
    abandoned = kept = 0
    for _ in range(20):
        x, y, t = np.array(TRUE) + rng.normal(0.0, [0.03, 0.03, 0.03])

        def match(bound: float, x: float = x, y: float = y, t: float = t) -> float:
            k._beam_geometry(t, rcs, LASER, maps.delta, geo)
            return float(
                k._match(
                    win, maps.tables[0], maps.accx, maps.accy, maps.hits, maps.visits, x, y, t,
                    rcs, geo, LASER, SIGMA, 1.0,
                    maps.delta, maps.cx0, maps.cy0, 1, False, bound, dists,
                )[0]
            )  # fmt: skip

        exact = match(-math.inf)
        for bound in (exact - 5.0, exact - 1e-9, exact, exact + 1e-9, exact + 0.5, exact + 40.0):
            got = match(bound)
            if got == -math.inf:
                abandoned += 1
                assert exact < bound
            else:
                kept += 1
                assert got == exact  # bit for bit
    assert abandoned > 0
    assert kept > 0
