"""Gradients of every cost term against central finite differences, and the L-BFGS solver."""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.planning.ego_planner import lbfgs
from visnav.planning.ego_planner.costs import (
    distance_cost,
    feasibility_cost,
    fitness_cost,
    smoothness_cost,
)

seeds = st.integers(0, 2**32 - 1)
Cost = Callable[[np.ndarray, np.ndarray], float]


def _check_gradient(cost: Cost, q: np.ndarray, *, h: float = 1e-6, rtol: float = 1e-4) -> None:
    grad = np.zeros_like(q)
    cost(q, grad)
    numeric = np.zeros_like(q)
    for idx in np.ndindex(q.shape):
        plus, minus = q.copy(), q.copy()
        plus[idx] += h
        minus[idx] -= h
        numeric[idx] = (cost(plus, np.zeros_like(q)) - cost(minus, np.zeros_like(q))) / (2 * h)
    scale = max(1.0, float(np.abs(numeric).max()))
    assert np.allclose(grad, numeric, atol=rtol * scale), np.abs(grad - numeric).max()


def _path(seed: int, n: int = 12) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(0.3, 0.4, (n, 3)), axis=0)


@settings(max_examples=25, deadline=None)
@given(seeds, st.floats(0.1, 3.0))
def test_smoothness_gradient(seed: int, weight: float) -> None:
    q = _path(seed)
    _check_gradient(lambda x, g: weight * smoothness_cost(x, g, weight), q)
    # a straight line at constant spacing has no jerk
    line = np.linspace([0, 0, 0], [5, 1, 2], 10)
    assert smoothness_cost(line, np.zeros_like(line), 1.0) == pytest.approx(0.0, abs=1e-20)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_distance_gradient_in_every_regime(seed: int) -> None:
    rng = np.random.default_rng(seed)
    q = _path(seed)
    n = q.shape[0]
    k = 3
    base = q[:, None, :] + rng.normal(0.0, 0.6, (n, k, 3))
    dirs = rng.normal(0.0, 1.0, (n, k, 3))
    dirs /= np.linalg.norm(dirs, axis=2, keepdims=True)
    counts = rng.integers(0, k + 1, n)
    clearance = 0.5
    d = np.einsum("nkc,nkc->nk", q[:, None, :] - base, dirs)
    err = clearance - d
    # keep away from the regime boundaries (err = 0 and err = clearance), where the
    # second derivative jumps and central differences straddle two pieces
    assume_ok = np.all((np.abs(err) > 1e-3) & (np.abs(err - clearance) > 1e-3))
    if not assume_ok:
        return
    _check_gradient(
        lambda x, g: 2.0 * distance_cost(x, g, 2.0, base, dirs, counts, clearance, 3), q
    )


def test_distance_cost_values() -> None:
    q = np.zeros((8, 3))
    base = np.zeros((8, 1, 3))
    dirs = np.zeros((8, 1, 3))
    dirs[:, 0, 0] = 1.0
    counts = np.zeros(8, dtype=np.int64)
    counts[3] = 1
    sf = 0.5
    for d, expected in (
        (0.6, 0.0),
        (0.3, 0.2**3),
        (-0.5, 3 * sf * 1.0**2 - 3 * sf**2 * 1.0 + sf**3),
    ):
        q[3, 0] = d  # signed distance along v beyond p
        assert distance_cost(q, np.zeros_like(q), 1.0, base, dirs, counts, sf, 3) == pytest.approx(
            expected
        )
    # only control points order .. N - order - 1 count
    counts[:] = 0
    counts[1] = 1
    q[1, 0] = -1.0
    assert distance_cost(q, np.zeros_like(q), 1.0, base, dirs, counts, sf, 3) == 0.0


@settings(max_examples=25, deadline=None)
@given(seeds, st.floats(0.1, 0.5))
def test_feasibility_gradient(seed: int, ts: float) -> None:
    q = _path(seed) * 1.5  # fast enough to violate both limits somewhere
    grad = np.zeros_like(q)
    assert feasibility_cost(q, grad, 1.0, ts, 2.0, 3.0) > 0.0
    vel = np.diff(q, axis=0) / ts
    acc = np.diff(q, 2, axis=0) / ts**2
    if np.min(np.abs(np.abs(vel) - 2.0)) < 1e-3 or np.min(np.abs(np.abs(acc) - 3.0)) < 1e-3:
        return  # a kink of the hinge inside the difference step
    _check_gradient(lambda x, g: 0.1 * feasibility_cost(x, g, 0.1, ts, 2.0, 3.0), q, h=1e-7)


def test_feasibility_cost_is_zero_within_limits() -> None:
    line = np.linspace([0, 0, 1], [3, 0, 1], 11)  # 0.3 m per 0.2 s = 1.5 m/s
    assert feasibility_cost(line, np.zeros_like(line), 1.0, 0.2, 2.0, 3.0) == 0.0
    assert feasibility_cost(line, np.zeros_like(line), 1.0, 0.1, 2.0, 3.0) > 0.0


@settings(max_examples=25, deadline=None)
@given(seeds, st.floats(0.1, 3.0))
def test_fitness_gradient(seed: int, weight: float) -> None:
    q = _path(seed)
    ref = _path(seed + 1, q.shape[0] - 2)
    _check_gradient(lambda x, g: weight * fitness_cost(x, g, weight, ref, 3), q)


def test_fitness_is_anisotropic() -> None:
    ref = np.column_stack([np.arange(10.0), np.zeros(10), np.zeros(10)])
    step = np.array([1.0, 0.0, 0.0])
    q = np.vstack([ref[:1] - step, ref, ref[-1:] + step])  # knot points = ref
    assert fitness_cost(q, np.zeros_like(q), 1.0, ref, 3) == pytest.approx(0.0, abs=1e-20)
    along = q + np.array([0.1, 0.0, 0.0])
    across = q + np.array([0.0, 0.1, 0.0])
    # an error along the reference direction costs 1/25 of one across it
    a = fitness_cost(along, np.zeros_like(q), 1.0, ref, 3)
    b = fitness_cost(across, np.zeros_like(q), 1.0, ref, 3)
    assert a == pytest.approx(b / 25.0)


@numba.njit(cache=True)
def _rosenbrock(x: np.ndarray, g: np.ndarray) -> float:
    f = 0.0
    g[:] = 0.0
    for i in range(x.shape[0] - 1):
        f += (1.0 - x[i]) ** 2 + 100.0 * (x[i + 1] - x[i] ** 2) ** 2
        g[i] += -2 * (1.0 - x[i]) - 400.0 * x[i] * (x[i + 1] - x[i] ** 2)
        g[i + 1] += 200.0 * (x[i + 1] - x[i] ** 2)
    return f


@numba.njit(cache=True)
def _minimise(x: np.ndarray, stop_after: int) -> tuple[float, int, int]:
    ws = lbfgs.workspace(x.shape[0], 16)
    g = np.empty_like(x)
    f = _rosenbrock(x, g)
    evals = 1
    action = lbfgs.start(ws, x, f, g, 1e-8)
    while action == lbfgs.EVALUATE:
        if 0 < stop_after <= evals:
            return f, lbfgs.CANCELED, evals
        f = _rosenbrock(x, g)
        evals += 1
        action = lbfgs.iterate(ws, x, f, g, 2000, 1e-8, 40)
    return lbfgs.result_f(ws), lbfgs.result_status(ws), evals


def test_lbfgs_minimises_rosenbrock() -> None:
    x = np.full(10, -1.2)
    f, status, evals = _minimise(x, 0)
    assert status == lbfgs.CONVERGENCE, lbfgs.status_text(status)
    assert np.allclose(x, 1.0, atol=1e-5)
    assert f < 1e-10
    assert evals > 20
    x = np.ones(4)
    _f, status, evals = _minimise(x, 0)
    assert status == lbfgs.ALREADY_MINIMIZED
    assert evals == 1
    # a driver may stop at any evaluation (ego-planner's early exit for rebounds)
    x = np.full(6, -1.2)
    _f, status, evals = _minimise(x, 7)
    assert status == lbfgs.CANCELED
    assert evals == 7
    assert lbfgs.status_text(lbfgs.MAXIMUM_LINESEARCH).startswith("the line search")
