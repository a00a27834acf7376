"""B-splines and polynomials of ego-planner: continuity, convex hull, fitting, time stretching."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.planning.ego_planner.bspline import (
    BsplineError,
    UniformBspline,
    parameterize_to_bspline,
)
from visnav.planning.ego_planner.polynomial import PolynomialError, PolynomialTraj

seeds = st.integers(0, 2**32 - 1)


def _random_spline(seed: int, *, n: int | None = None) -> UniformBspline:
    rng = np.random.default_rng(seed)
    n = n or int(rng.integers(7, 25))
    ctrl = np.cumsum(rng.normal(0.0, 0.5, (n, 3)), axis=0)
    return UniformBspline(ctrl, 3, float(rng.uniform(0.05, 0.5)))


@settings(max_examples=40, deadline=None)
@given(seeds)
def test_value_velocity_and_acceleration_are_continuous_at_knots(seed: int) -> None:
    spline = _random_spline(seed)
    vel = spline.derivative()
    acc = vel.derivative()
    ts = spline.interval
    inner = np.arange(1, round(spline.duration / ts)) * ts
    eps = 1e-7
    for curve in (spline, vel, acc):
        left = curve.evaluate(inner - eps)
        right = curve.evaluate(inner + eps)
        scale = 1.0 + np.abs(curve.control_points).max()
        assert np.allclose(left, right, atol=1e-4 * scale)
    # jerk (order 0) jumps at knots: that is what the smoothness cost penalises
    jerk = acc.derivative()
    assert jerk.order == 0


@settings(max_examples=40, deadline=None)
@given(seeds)
def test_derivative_spline_matches_finite_differences(seed: int) -> None:
    spline = _random_spline(seed)
    times = np.linspace(0.01, spline.duration - 0.01, 37)
    h = 1e-5
    fd = (spline.evaluate(times + h) - spline.evaluate(times - h)) / (2 * h)
    assert np.allclose(spline.derivative().evaluate(times), fd, atol=1e-4)
    # uniform cubic: velocity control points are (P_{i+1} - P_i) / ts
    ctrl = spline.control_points
    assert np.allclose(spline.derivative().control_points, np.diff(ctrl, axis=0) / spline.interval)


@settings(max_examples=40, deadline=None)
@given(seeds, st.floats(0.0, 1.0))
def test_points_lie_in_the_convex_hull_of_their_four_control_points(seed: int, frac: float) -> None:
    spline = _random_spline(seed)
    n = spline.control_points.shape[0]
    # evaluating with unit control points gives the basis functions themselves
    basis = UniformBspline(np.eye(n), 3, spline.interval)
    t = frac * spline.duration
    weights = basis.evaluate(t)
    assert np.all(weights >= -1e-12)
    assert weights.sum() == pytest.approx(1.0)
    span = min(int(t / spline.interval), n - 4)
    support = np.nonzero(weights > 1e-12)[0]
    assert support.min() >= span
    assert support.max() <= span + 3
    assert np.allclose(weights @ spline.control_points, spline.evaluate(t))


def test_knot_points_and_time_span() -> None:
    ctrl = np.arange(30, dtype=float).reshape(10, 3) ** 1.5
    spline = UniformBspline(ctrl, 3, 0.2)
    assert spline.duration == pytest.approx(7 * 0.2)
    # at knot k the value is (P_k + 4 P_{k+1} + P_{k+2}) / 6
    for k in range(8):
        expected = (ctrl[k] + 4 * ctrl[k + 1] + ctrl[k + 2]) / 6
        assert np.allclose(spline.evaluate(k * 0.2), expected)
    assert np.allclose(spline.evaluate(-1.0), spline.evaluate(0.0))  # clamped
    assert np.allclose(spline.evaluate(99.0), spline.evaluate(spline.duration))


@settings(max_examples=30, deadline=None)
@given(seeds)
def test_parameterize_to_bspline_passes_through_the_points(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ts = 0.25
    k = int(rng.integers(4, 20))
    # samples of a cubic polynomial: a B-spline reproduces it exactly
    c = rng.normal(0, 1, (4, 3))
    times = np.arange(k) * ts

    def poly(t: np.ndarray, d: int = 0) -> np.ndarray:
        coeffs = [np.polyder(np.poly1d(c[::-1, j]), d) for j in range(3)]
        return np.column_stack([p(t) for p in coeffs])

    pts = poly(times)
    der = np.array(
        [
            poly(times[:1], 1)[0],
            poly(times[-1:], 1)[0],
            poly(times[:1], 2)[0],
            poly(times[-1:], 2)[0],
        ]
    )
    ctrl = parameterize_to_bspline(ts, pts, der)
    spline = UniformBspline(ctrl, 3, ts)
    assert ctrl.shape == (k + 2, 3)
    assert np.allclose(spline.evaluate(times), pts, atol=1e-8)
    assert np.allclose(spline.derivative().evaluate(0.0), der[0], atol=1e-8)
    assert np.allclose(
        spline.derivative().derivative().evaluate(spline.duration), der[3], atol=1e-7
    )


def test_feasibility_check_and_time_stretching() -> None:
    ctrl = np.column_stack([np.arange(20) * 0.8, np.zeros(20), np.ones(20)])
    spline = UniformBspline(ctrl, 3, 0.2)  # 4 m/s along x
    ok, ratio = spline.check_feasibility(2.0, 3.0, 0.05)
    assert not ok
    assert ratio == pytest.approx(2.0)
    longer = spline.lengthen_time(ratio)
    # the span between knots 5 and len - 6 doubles; the rest keeps its length
    inner = spline.knots[-6] - spline.knots[5]
    assert longer.duration == pytest.approx(spline.duration + inner)
    assert np.allclose(longer.evaluate(longer.duration), spline.evaluate(spline.duration))
    slow = UniformBspline(ctrl, 3, 0.4)  # 2 m/s: exactly at the limit
    assert slow.check_feasibility(2.0, 3.0, 0.0)[0]


def test_bspline_errors() -> None:
    with pytest.raises(BsplineError, match="N > 3"):
        UniformBspline(np.zeros((3, 3)), 3, 0.1)
    with pytest.raises(BsplineError, match="interval"):
        UniformBspline(np.zeros((5, 3)), 3, 0.0)
    with pytest.raises(BsplineError, match="K >= 4"):
        parameterize_to_bspline(0.1, np.zeros((3, 3)), np.zeros((4, 3)))
    with pytest.raises(BsplineError, match="derivatives"):
        parameterize_to_bspline(0.1, np.zeros((5, 3)), np.zeros((3, 3)))


def test_quintic_meets_both_end_states() -> None:
    traj = PolynomialTraj.one_segment(
        [0, 0, 1], [1, 0, 0], [0, 0.5, 0], [5, 1, 1], [0, 1, 0], [0, 0, 0], 4.0
    )
    assert np.allclose(traj.evaluate(0.0), [0, 0, 1])
    assert np.allclose(traj.evaluate_vel(0.0), [1, 0, 0])
    assert np.allclose(traj.evaluate_acc(0.0), [0, 0.5, 0])
    assert np.allclose(traj.evaluate(4.0), [5, 1, 1])
    assert np.allclose(traj.evaluate_vel(4.0), [0, 1, 0])
    assert np.allclose(traj.evaluate_acc(4.0), [0, 0, 0], atol=1e-9)


def test_min_snap_is_continuous_and_beats_other_interior_derivatives() -> None:
    wps = np.array([[0, 0, 1], [4, 0, 1], [8, 3, 1], [12, 3, 2.0]])
    zero = np.zeros(3)
    traj = PolynomialTraj.min_snap(wps, zero, zero, zero, zero, [4.0, 2.5, 4.0])
    assert np.allclose(traj.evaluate(traj.boundaries), wps)
    for t in traj.boundaries[1:-1]:
        for f in (traj.evaluate, traj.evaluate_vel, traj.evaluate_acc):
            assert np.allclose(f(t - 1e-9), f(t + 1e-9), atol=1e-6)

    def snap_cost(p: PolynomialTraj) -> float:
        times = np.linspace(0.0, p.duration, 4001)
        # snap of a quintic piece: 24 c4 + 120 c5 t
        seg = np.clip(np.searchsorted(p.boundaries, times, side="right") - 1, 0, 2)
        local = times - p.boundaries[seg]
        c = p.coefficients[seg]
        snap = 24 * c[:, :, 4] + 120 * c[:, :, 5] * local[:, None]
        return float((snap**2).sum() * (times[1] - times[0]))

    # perturbing an interior velocity (keeping continuity) can only raise the cost
    base = snap_cost(traj)
    for delta in (0.3, -0.3):
        bumped = []
        for j in range(3):
            t0 = traj.boundaries[j]
            t1 = traj.boundaries[j + 1]
            v0 = traj.evaluate_vel(t0) + (delta if j == 1 else 0.0) * np.array([0, 1, 0])
            v1 = traj.evaluate_vel(t1) + (delta if j == 0 else 0.0) * np.array([0, 1, 0])
            bumped.append(
                PolynomialTraj.one_segment(
                    traj.evaluate(t0),
                    v0,
                    traj.evaluate_acc(t0),
                    traj.evaluate(t1),
                    v1,
                    traj.evaluate_acc(t1),
                    t1 - t0,
                )
            )
        joined = PolynomialTraj(np.concatenate([b.coefficients for b in bumped]), traj.durations)
        assert snap_cost(joined) > base
    with pytest.raises(PolynomialError, match="durations"):
        PolynomialTraj.min_snap(wps, zero, zero, zero, zero, [1.0, 1.0])
