"""Log-odds occupancy mapping: convergence, trinary output, growth, bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from visnav.mapping import MappingError, OccupancyMapper, logit
from visnav.msgs import LaserScan, make


def _scan(ranges: np.ndarray, fov: float = 1.0, rmax: float = 8.0) -> LaserScan:
    n = len(ranges)
    return make(
        LaserScan,
        angle_min=-fov / 2,
        angle_max=fov / 2,
        angle_increment=fov / (n - 1),
        range_min=0.1,
        range_max=rmax,
        ranges=np.asarray(ranges, np.float32),
    )


def _wall_ranges(n: int, fov: float, x_wall: float) -> np.ndarray:
    a = -fov / 2 + np.arange(n) * fov / (n - 1)
    return x_wall / np.cos(a)


def test_log_odds_converge_to_the_clamps() -> None:
    m = OccupancyMapper(width=6.0, height=6.0, origin_x=-1.0, origin_y=-3.0, grow=False)
    scan = _scan(_wall_ranges(101, 0.6, 3.0), fov=0.6)
    for k in range(30):
        m.integrate_scan(scan, np.eye(4))
        if k == 0:
            p_wall = m.probabilities()[60, 80]
            assert p_wall == pytest.approx(0.7, abs=1e-6)  # one hit from 0.5
            p_free = m.probabilities()[60, 40]
            assert p_free == pytest.approx(0.4, abs=1e-6)
    p = m.probabilities()
    wall_x = int((3.0 - m.origin_x) / m.resolution)
    assert p[60, wall_x] == pytest.approx(0.97, abs=1e-3)
    assert p[60, 40] == pytest.approx(0.12, abs=1e-3)
    assert m.logodds.max() <= logit(0.97) + 1e-6
    assert m.logodds.min() >= logit(0.12) - 1e-6
    values = m.occupancy_values()
    assert values[60, wall_x] == 100
    assert values[60, 40] == 0
    assert values[60, wall_x + 5] == -1  # behind the wall: never observed
    assert values[0, 0] == -1
    scaled = m.occupancy_values(trinary=False)
    assert scaled[60, wall_x] == 97
    assert scaled[60, 40] == 12


def test_a_cell_seen_free_and_hit_in_one_scan_counts_as_hit_once() -> None:
    m = OccupancyMapper(width=4.0, height=4.0, origin_x=-2.0, origin_y=-2.0, grow=False)
    # two beams: one ends in cell A, the other passes through A on its way further
    m.integrate_points(
        np.array([0.0, 0.0]), np.array([[1.025, 0.025], [1.825, 0.025]]), np.array([True, True])
    )
    a = m.logodds[40, 60]
    assert a == pytest.approx(logit(0.7))
    assert m.logodds[40, 50] == pytest.approx(logit(0.4))  # one miss, not two


def test_no_return_beams_clear_up_to_max_free_range() -> None:
    m = OccupancyMapper(
        width=20.0, height=4.0, origin_x=-2.0, origin_y=-2.0, grow=False, max_free_range=3.0
    )
    m.integrate_scan(_scan(np.array([math.inf, math.inf, math.nan]), fov=0.02), np.eye(4))
    known_x = np.nonzero(m.known[40])[0]
    assert known_x.max() * m.resolution + m.origin_x == pytest.approx(3.0, abs=0.06)
    assert (m.occupancy_values() == 100).sum() == 0


def test_the_grid_grows_and_keeps_the_map() -> None:
    m = OccupancyMapper(
        width=2.0, height=2.0, origin_x=-1.0, origin_y=-1.0, grow=True, grow_margin=1.0
    )
    m.integrate_points(np.array([0.0, 0.0]), np.array([[0.5, 0.5]]), np.array([True]))
    before = m.probabilities()[30, 30]
    assert before > 0.5
    m.integrate_points(np.array([0.0, 0.0]), np.array([[4.0, -3.0]]), np.array([True]))
    assert m.origin_x == pytest.approx(-1.0)
    assert m.origin_y == pytest.approx(-4.0)
    assert m.origin_x + m.size_x * m.resolution >= 5.0
    cell_x = int((0.5 - m.origin_x) / m.resolution)
    cell_y = int((0.5 - m.origin_y) / m.resolution)
    assert m.probabilities()[cell_y, cell_x] == pytest.approx(before)
    msg = m.to_occupancy_grid("map", 2_000_000_000)
    assert msg.info.width == m.size_x
    assert msg.info.origin.position.y == pytest.approx(-4.0)
    assert msg.data.size == m.size_x * m.size_y


def test_fixed_bounds_cut_rays() -> None:
    m = OccupancyMapper(width=2.0, height=2.0, origin_x=-1.0, origin_y=-1.0, grow=False)
    m.integrate_points(np.array([0.0, 0.0]), np.array([[5.0, 0.0]]), np.array([True]))
    assert m.size_x == 40
    assert (m.occupancy_values() == 100).sum() == 0
    assert m.known[20, 20:].all()


def test_bad_parameters() -> None:
    with pytest.raises(MappingError, match=r"prob_hit is 1\.5"):
        OccupancyMapper(prob_hit=1.5)
    with pytest.raises(MappingError, match=r"prob_miss < 0\.5 < prob_hit"):
        OccupancyMapper(prob_hit=0.4)


def test_beams_are_cropped_to_the_usable_range() -> None:
    """gmapping's maxUrange: a return beyond it only clears space up to it."""
    m = OccupancyMapper(
        width=10.0, height=4.0, origin_x=-1.0, origin_y=-2.0, grow=False, max_usable_range=3.0
    )
    m.integrate_scan(_scan(np.array([2.0, 5.0, math.inf]), fov=0.02), np.eye(4))
    values = m.occupancy_values()
    _rows, cols = np.nonzero(values == 100)
    assert len(cols) == 1  # the far return marks nothing ...
    assert (cols[0] + 0.5) * m.resolution + m.origin_x == pytest.approx(
        2.0, abs=0.05
    )  # the near one
    known_x = np.nonzero(m.known.any(axis=0))[0]
    assert known_x.max() * m.resolution + m.origin_x == pytest.approx(
        3.0, abs=0.06
    )  # ... but clears to 3 m
    uncropped = OccupancyMapper(width=10.0, height=4.0, origin_x=-1.0, origin_y=-2.0, grow=False)
    uncropped.integrate_scan(_scan(np.array([2.0, 5.0, math.inf]), fov=0.02), np.eye(4))
    assert (uncropped.occupancy_values() == 100).sum() == 2


def test_a_bad_usable_range_is_refused() -> None:
    with pytest.raises(MappingError, match="max_usable_range is -1"):
        OccupancyMapper(max_usable_range=-1.0)


def test_clear_forgets_every_observation() -> None:
    m = OccupancyMapper(width=6.0, height=6.0, origin_x=-1.0, origin_y=-3.0, grow=False)
    scan = _scan(_wall_ranges(101, 0.6, 3.0), fov=0.6)
    m.integrate_scan(scan, np.eye(4))
    first = m.occupancy_values().copy()
    m.integrate_scan(scan, np.eye(4))
    m.clear()
    assert m.scans == 0
    assert (m.occupancy_values() == -1).all()
    m.integrate_scan(scan, np.eye(4))
    np.testing.assert_array_equal(m.occupancy_values(), first)


def test_far_returns_clear_a_share_of_their_range() -> None:
    """far_clear_ratio: space well short of a far return is free, its wall is not marked."""
    m = OccupancyMapper(
        width=12.0,
        height=4.0,
        origin_x=-1.0,
        origin_y=-2.0,
        grow=False,
        max_usable_range=3.0,
        far_clear_ratio=0.9,
    )
    m.integrate_scan(_scan(np.array([6.0, 6.0, 6.0]), fov=0.02), np.eye(4))
    assert (m.occupancy_values() == 100).sum() == 0
    known_x = np.nonzero(m.known.any(axis=0))[0]
    assert known_x.max() * m.resolution + m.origin_x == pytest.approx(5.4, abs=0.06)
    for bad in (-0.1, 1.0):
        with pytest.raises(MappingError, match="far_clear_ratio"):
            OccupancyMapper(far_clear_ratio=bad)
