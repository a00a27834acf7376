"""A small L-BFGS in numba, in the manner of the ``lbfgs.hpp`` ego-planner bundles.

Directions come from the two-loop recursion over the last ``mem_size``
correction pairs (scaled by ``y.s / y.y``); steps come from a weak Wolfe line
search by bracketing and bisection (Lewis and Overton; sufficient decrease 1e-4,
curvature 0.9), starting at ``1 / |d|`` on the first iteration and at 1 after.
A run converges when ``|g| <= g_epsilon * max(1, |x|)``.

The solver uses *reverse communication*, so cost functions need not be passed
as arguments (numba cannot cache functions compiled for function-typed
arguments). A driver, written per cost function, evaluates and steps::

    @numba.njit(cache=True)
    def minimise(x, data):
        ws = workspace(x.shape[0], 16)
        g = np.empty_like(x)
        f = cost(x, g, data)
        action = start(ws, x, f, g, 1e-5)
        while action == EVALUATE:
            f = cost(x, g, data)  # x was moved to the next trial point
            action = iterate(ws, x, f, g, 200, 1e-5, 40)
        return result_status(ws), result_f(ws)

On return ``x`` holds the solution (the last accepted point on a line-search
failure). A driver may stop at any evaluation (ego-planner's ``earlyExit``) and
report :data:`CANCELED`. Status codes follow libLBFGS where they exist
(``CONVERGENCE`` 0, ``ALREADY_MINIMIZED`` 2, negative values are errors).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "ALREADY_MINIMIZED",
    "CANCELED",
    "CONVERGENCE",
    "EVALUATE",
    "INCREASE_GRADIENT",
    "MAXIMUM_ITERATION",
    "MAXIMUM_LINESEARCH",
    "MINIMUM_STEP",
    "Workspace",
    "iterate",
    "result_f",
    "result_iterations",
    "result_status",
    "start",
    "status_text",
    "workspace",
]

CONVERGENCE = 0
ALREADY_MINIMIZED = 2
CANCELED = -1023
MINIMUM_STEP = -1006
MAXIMUM_LINESEARCH = -1004
MAXIMUM_ITERATION = -1003
INCREASE_GRADIENT = -1000
EVALUATE = 1  # action: evaluate the cost at x, then call iterate()
DONE = 0  # action: finished, see result_status()

_TEXT = {
    CONVERGENCE: "converged",
    ALREADY_MINIMIZED: "the initial point is already a minimiser",
    CANCELED: "cancelled by the cost function",
    MINIMUM_STEP: "the line search step became too small",
    MAXIMUM_LINESEARCH: "the line search reached its evaluation limit",
    MAXIMUM_ITERATION: "the iteration limit was reached",
    INCREASE_GRADIENT: "the search direction does not descend",
}

# integer state
_IT, _LS, _STORED, _NEWEST, _STATUS = range(5)
# float state
_STEP, _LO, _HI, _FP, _DG0, _F = range(6)
_F_DEC = 1e-4
_S_CURV = 0.9

Workspace = tuple[
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
    np.ndarray,
]


def status_text(status: int) -> str:
    """Human-readable meaning of a status code."""
    return _TEXT.get(status, f"unknown status {status}")


@numba.njit(cache=True)
def workspace(n: int, mem_size: int) -> Workspace:
    """Scratch state for ``n`` variables and ``mem_size`` correction pairs."""
    ints = np.zeros(5, np.int64)
    floats = np.zeros(6)
    return (
        ints,
        floats,
        np.zeros(n),  # xp
        np.zeros(n),  # gp
        np.zeros(n),  # d
        np.zeros((mem_size, n)),  # s
        np.zeros((mem_size, n)),  # y
        np.zeros(mem_size),  # ys
        np.zeros(mem_size),  # alpha
        np.zeros(1),  # spare
    )


@numba.njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i] * b[i]
    return s


@numba.njit(cache=True)
def _norm(a: np.ndarray) -> float:
    return math.sqrt(_dot(a, a))


@numba.njit(cache=True)
def _begin_line_search(ws: Workspace, x: np.ndarray, f: float, g: np.ndarray, step: float) -> int:
    ints, floats, xp, gp, d = ws[0], ws[1], ws[2], ws[3], ws[4]
    xp[:] = x
    gp[:] = g
    floats[_FP] = f
    floats[_F] = f
    dg0 = _dot(g, d)
    if dg0 >= 0.0:
        ints[_STATUS] = INCREASE_GRADIENT
        return DONE
    floats[_DG0] = dg0
    floats[_STEP] = step
    floats[_LO] = 0.0
    floats[_HI] = np.inf
    ints[_LS] = 0
    for i in range(x.shape[0]):
        x[i] = xp[i] + step * d[i]
    return EVALUATE


@numba.njit(cache=True)
def start(ws: Workspace, x: np.ndarray, f: float, g: np.ndarray, g_epsilon: float) -> int:
    """Begin a run at ``x`` with cost ``f`` and gradient ``g``; returns the next action."""
    ints, floats, d = ws[0], ws[1], ws[4]
    ints[:] = 0
    ints[_NEWEST] = -1
    floats[_F] = f
    if _norm(g) <= g_epsilon * max(1.0, _norm(x)):
        ints[_STATUS] = ALREADY_MINIMIZED
        return DONE
    for i in range(x.shape[0]):
        d[i] = -g[i]
    ints[_IT] = 1
    return _begin_line_search(ws, x, f, g, 1.0 / _norm(d))


@numba.njit(cache=True)
def _restore(ws: Workspace, x: np.ndarray, g: np.ndarray, status: int) -> int:
    ints, floats, xp, gp = ws[0], ws[1], ws[2], ws[3]
    x[:] = xp
    g[:] = gp
    floats[_F] = floats[_FP]
    ints[_STATUS] = status
    return DONE


@numba.njit(cache=True)
def iterate(
    ws: Workspace,
    x: np.ndarray,
    f: float,
    g: np.ndarray,
    max_iterations: int,
    g_epsilon: float,
    max_linesearch: int,
) -> int:
    """Take the cost ``f`` and gradient ``g`` at the trial ``x``; returns the next action.

    On :data:`EVALUATE` ``x`` holds the next trial point; on :data:`DONE` the run
    ended (:func:`result_status`).
    """
    ints, floats, xp, gp, d = ws[0], ws[1], ws[2], ws[3], ws[4]
    s_mem, y_mem, ys_mem, alpha = ws[5], ws[6], ws[7], ws[8]
    ints[_LS] += 1
    step = floats[_STEP]
    accepted = False
    if f > floats[_FP] + _F_DEC * step * floats[_DG0]:
        floats[_HI] = step
    elif _dot(g, d) < _S_CURV * floats[_DG0]:
        floats[_LO] = step
    else:
        accepted = True
    if not accepted:
        if ints[_LS] >= max_linesearch:
            return _restore(ws, x, g, MAXIMUM_LINESEARCH)
        step = 0.5 * (floats[_LO] + floats[_HI]) if floats[_HI] < np.inf else 2.0 * step
        if step < 1e-20:
            return _restore(ws, x, g, MINIMUM_STEP)
        floats[_STEP] = step
        for i in range(x.shape[0]):
            x[i] = xp[i] + step * d[i]
        return EVALUATE
    floats[_F] = f
    if _norm(g) <= g_epsilon * max(1.0, _norm(x)):
        ints[_STATUS] = CONVERGENCE
        return DONE
    if 0 < max_iterations <= ints[_IT]:
        ints[_STATUS] = MAXIMUM_ITERATION
        return DONE
    mem = s_mem.shape[0]
    n = x.shape[0]
    newest = (ints[_NEWEST] + 1) % mem
    ints[_NEWEST] = newest
    for i in range(n):
        s_mem[newest, i] = x[i] - xp[i]
        y_mem[newest, i] = g[i] - gp[i]
    ys = _dot(y_mem[newest], s_mem[newest])
    yy = _dot(y_mem[newest], y_mem[newest])
    ys_mem[newest] = ys
    stored = min(ints[_STORED] + 1, mem)
    ints[_STORED] = stored
    for i in range(n):
        d[i] = -g[i]
    j = newest
    for _ in range(stored):
        if ys_mem[j] > 0.0:
            alpha[j] = _dot(s_mem[j], d) / ys_mem[j]
            for i in range(n):
                d[i] -= alpha[j] * y_mem[j, i]
        j = (j - 1) % mem
    if ys > 0.0 and yy > 0.0:
        scale = ys / yy
        for i in range(n):
            d[i] *= scale
    for _ in range(stored):
        j = (j + 1) % mem
        if ys_mem[j] > 0.0:
            beta = _dot(y_mem[j], d) / ys_mem[j]
            for i in range(n):
                d[i] += (alpha[j] - beta) * s_mem[j, i]
    ints[_IT] += 1
    return _begin_line_search(ws, x, f, g, 1.0)


@numba.njit(cache=True)
def result_status(ws: Workspace) -> int:
    """Status of a finished run."""
    return int(ws[0][_STATUS])


@numba.njit(cache=True)
def result_f(ws: Workspace) -> float:
    """Cost at the returned ``x``."""
    return float(ws[1][_F])


@numba.njit(cache=True)
def result_iterations(ws: Workspace) -> int:
    """Iterations started."""
    return int(ws[0][_IT])
