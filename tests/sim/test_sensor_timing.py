"""Sensors fire at their update_rate in sim time, deterministically."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.sim.sensor_timing import SensorClock, sensor_seed


def count_fires(rate: float, step_ns: int, duration_ns: int) -> list[int]:
    clock = SensorClock(rate)
    return [t for t in range(0, duration_ns, step_ns) if clock.due(t)]


def test_rates_do_not_drift_with_the_step() -> None:
    fires = count_fires(30.0, 2_000_000, 10_000_000_000)  # 30 Hz on a 2 ms step, 10 s
    assert len(fires) == 300
    assert fires[0] == 0
    # Each measurement is at the first step at or after k / 30 s.
    for k, t in enumerate(fires):
        assert 0 <= t - k * 1_000_000_000 / 30 < 2_000_000


def test_zero_rate_fires_every_step_and_slow_steps_skip() -> None:
    assert count_fires(0.0, 1_000_000, 10_000_000) == list(range(0, 10_000_000, 1_000_000))
    # A 1 kHz sensor on a 10 ms step fires once per step, never twice.
    assert len(count_fires(1000.0, 10_000_000, 1_000_000_000)) == 100


@settings(max_examples=100, deadline=None)
@given(st.floats(0.5, 500.0), st.integers(100_000, 20_000_000))
def test_fire_count_matches_rate(rate: float, step_ns: int) -> None:
    duration = 2_000_000_000
    fires = count_fires(rate, step_ns, duration)
    expected = duration * rate / 1e9
    assert abs(len(fires) - min(expected, duration / step_ns)) <= 1.0 + 1e-6


def test_bad_rate_and_seeds() -> None:
    with pytest.raises(VisnavError, match="update_rate"):
        SensorClock(-1.0)
    assert sensor_seed(1, "cam") == sensor_seed(1, "cam")
    assert sensor_seed(1, "cam") != sensor_seed(2, "cam")
    assert sensor_seed(1, "cam") != sensor_seed(1, "imu")
    assert 0 <= sensor_seed(123, "x") < 2**63
