"""numba kernels of gmapping's scan matcher (``score``, ``likelihoodAndScore``, ``optimize``).

The lookups of one particle's map go through a dense window around the laser
(:func:`_window`: each full cell's mean hit point, and per cell two 3 x 3 bit masks, its
full neighbours and its neighbours that are not below the fullness threshold), falling
back to the patch tables outside it. A beam's candidate cells are then one AND of two
masks (the end point's full neighbours and the not-below neighbours of the cell one free
step back), visited in gmapping's loop order, so the results are those of gmapping's
per-cell rules bit for bit (:mod:`visnav.mapping.gmapping.reference` is the plain-Python
version).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np
from numba import njit, prange
from numba.cpython.unsafe.numbers import trailing_zeros
from numpy.typing import NDArray

from visnav.mapping.gmapping._kernels import (
    FREE_RATIO,
    FULLNESS,
    PATCH,
    PATCH_SHIFT,
    cell,
    laser_origin,
)

__all__ = ["likelihood_and_score", "optimize", "scan_match_all", "score"]

F64 = NDArray[np.float64]
I32 = NDArray[np.int32]
I16 = NDArray[np.int16]
_NULL_LIKELIHOOD = -0.5
_WIN_MARGIN = 10  # cells the hill climbing may move before lookups leave the window
_WIN_HALF_MAX = 90  # (2 * 90 + 1)**2 cells < 2**15: the window's codes are int16
_SEEN = 256  # poses the hill climbing remembers (it scores about 100)
_lowest_bit = cast("Callable[[Any], int]", trailing_zeros)  # index of the lowest set bit
# (code, means, wx0, wy0, near, n): see :func:`_window`
Window = tuple[I16, F64, int, int, NDArray[np.uint32], int]


@njit(cache=True)
def _window(
    table: I32,
    accx: F64,
    accy: F64,
    hits: I32,
    visits: I32,
    lx: float,
    ly: float,
    reach: float,
    delta: float,
    cx0: int,
    cy0: int,
    kernel: int,
) -> Window:  # pragma: no cover - compiled
    """A dense index of a particle's full cells around a laser origin, for fast lookups.

    Returns ``(code, means, wx0, wy0, near, n)`` over an ``n x n`` window whose cell (0, 0) is
    table cell ``(wx0, wy0)``; cell ``(wx, wy)`` is entry ``wy * n + wx`` of the flat arrays.
    ``code`` is -1 for a cell below gmapping's fullness threshold (or unknown), -2 exactly
    at it, else the row of the cell's mean hit point ``(x, y)`` in ``means``. With
    ``kernel`` 1, ``near`` holds each cell's 3 x 3 neighbourhood as bits ``(ox + 1) * 3 +
    (oy + 1)`` (offsets -1..1): bits 0-8 the neighbours that are full, bits 16-24 those
    that are not below the threshold (full or exactly at it); other kernels leave it 0.
    """
    # capped so that every code fits an int16 (lookups beyond the window use the patches)
    half = min(math.ceil(reach / delta) + _WIN_MARGIN, _WIN_HALF_MAX)
    wx0 = math.floor(lx / delta) - cx0 - half
    wy0 = math.floor(ly / delta) - cy0 - half
    n = 2 * half + 1
    code = np.full(n * n, -1, np.int16)
    cap = 256
    means = np.empty((cap, 2))
    where = np.empty(cap, np.int64)
    count = 0
    ph, pw = table.shape
    px0 = max(0, wx0 >> PATCH_SHIFT)
    py0 = max(0, wy0 >> PATCH_SHIFT)
    px1 = min(pw - 1, (wx0 + n - 1) >> PATCH_SHIFT)
    py1 = min(ph - 1, (wy0 + n - 1) >> PATCH_SHIFT)
    for py in range(py0, py1 + 1):
        for px in range(px0, px1 + 1):
            pid = table[py, px]
            if pid < 0:
                continue
            for cy in range(PATCH):
                wy = (py << PATCH_SHIFT) + cy - wy0
                if wy < 0 or wy >= n:
                    continue
                for cx in range(PATCH):
                    wx = (px << PATCH_SHIFT) + cx - wx0
                    if wx < 0 or wx >= n:
                        continue
                    kk = (cy << PATCH_SHIFT) | cx
                    v = visits[pid, kk]
                    if v == 0:
                        continue
                    h = hits[pid, kk]
                    if h / v == FULLNESS:
                        code[wy * n + wx] = -2  # neither full nor below the threshold
                    elif h / v > FULLNESS:
                        if count == cap:
                            grown = np.empty((2 * cap, 2))
                            grown[:count] = means[:count]
                            means = grown
                            grown_w = np.empty(2 * cap, np.int64)
                            grown_w[:count] = where[:count]
                            where = grown_w
                            cap *= 2
                        means[count, 0] = accx[pid, kk] / h
                        means[count, 1] = accy[pid, kk] / h
                        where[count] = wy * n + wx
                        code[wy * n + wx] = np.int16(count)
                        count += 1
    near = np.zeros(n * n, np.uint32)
    if kernel == 1:
        for w in range(n * n):
            q = code[w]
            if q == -1:
                continue
            bits = np.uint32(0x10000) if q == -2 else np.uint32(0x10001)
            wy = w // n
            wx = w - wy * n
            # the cell is neighbour (ox, oy) of the cell at (wx - ox, wy - oy)
            for ox in range(-1, 2):
                tx = wx - ox
                if tx < 0 or tx >= n:
                    continue
                for oy in range(-1, 2):
                    ty = wy - oy
                    if 0 <= ty < n:
                        near[ty * n + tx] |= bits << np.uint32((ox + 1) * 3 + oy + 1)
    return code, means[:count], wx0, wy0, near, n


@njit(cache=True)
def _outside(
    table: I32, accx: F64, accy: F64, hits: I32, visits: I32, ix: int, iy: int
) -> tuple[int, float, float]:  # pragma: no cover - compiled
    """(class, mean x, mean y) of a table cell outside the window (1 full, 2 at, 0 below)."""
    v, mx, my = cell(table, accx, accy, hits, visits, ix, iy)
    if v > FULLNESS:
        return 1, mx, my
    if v == FULLNESS:
        return 2, 0.0, 0.0
    return 0, 0.0, 0.0


@njit(cache=True)
def _used_beams(ranges: F64, usable: float, lskip: int) -> NDArray[np.int64]:  # pragma: no cover
    """Indexes of the beams gmapping's score loop uses: every ``lskip + 1``-th, range <= usable."""
    out = np.empty(ranges.shape[0], np.int64)
    n = 0
    skip = 0
    for i in range(ranges.shape[0]):
        skip += 1
        if skip > lskip:
            skip = 0
        if skip != 0 or not ranges[i] <= usable:  # also NaN
            continue
        out[n] = i
        n += 1
    return out[:n]


@njit(cache=True, error_model="numpy")  # no zero-division checks: divisors are not 0
def _match(
    win: Window,
    table: I32,
    accx: F64,
    accy: F64,
    hits: I32,
    visits: I32,
    x: float,
    y: float,
    th: float,
    ranges: F64,
    beams: NDArray[np.int64],
    bc: F64,
    bs: F64,
    laser: F64,
    sigma: float,
    lsigma: float,
    delta: float,
    cx0: int,
    cy0: int,
    kernel: int,
    with_likelihood: bool,
) -> tuple[float, float, int]:  # pragma: no cover - compiled
    """gmapping's score (and likelihoodAndScore): returns (score, log likelihood, matched).

    ``beams``: the used beams (:func:`_used_beams`); ``bc``, ``bs``: cos and sin of the beam
    angles (computed once per scan). Per beam, the candidates are the full cells of the
    kernel window around the end point's cell whose cell one ``delta * sqrt(2)`` step back
    along the beam from the candidate is below the threshold; the first strictly nearest
    mean wins. With ``kernel`` 1 and the window around the end point inside the window
    (:func:`_window`), the candidates are the set bits of ``full(end cell) & ~notbelow(free
    cell)`` of the ``near`` masks, visited in the loops' order; else the loops read the
    window's codes and, beyond it, the patches.
    """
    c = math.cos(th)
    s = math.sin(th)
    lx = x + c * laser[0] - s * laser[1]
    ly = y + s * laser[0] + c * laser[1]
    lth = th + laser[2]
    cl = math.cos(lth)
    sl = math.sin(lth)
    free_delta = delta * FREE_RATIO
    inv_delta = 1.0 / delta
    no_hit = _NULL_LIKELIHOOD / lsigma
    code, means, wx0, wy0, near, n = win
    fast = kernel == 1
    total = 0.0
    like = 0.0
    matched = 0
    for j in range(beams.shape[0]):
        i = beams[j]
        r = ranges[i]
        if r == 0.0 and not with_likelihood:
            continue
        ca = cl * bc[i] - sl * bs[i]
        sa = sl * bc[i] + cl * bs[i]
        hx = lx + r * ca
        hy = ly + r * sa
        ihx = math.floor(hx * inv_delta) - cx0
        ihy = math.floor(hy * inv_delta) - cy0
        ifx = math.floor((hx - free_delta * ca) * inv_delta) - cx0 - ihx
        ify = math.floor((hy - free_delta * sa) * inv_delta) - cy0 - ihy
        found = False
        bx = 0.0
        by = 0.0
        wcx = ihx - wx0
        wcy = ihy - wy0
        if fast and 3 <= wcx < n - 3 and 3 <= wcy < n - 3:
            # |ifx|, |ify| <= 2: both 3 x 3 neighbourhoods are inside the window
            t = wcy * n + wcx
            valid = near[t] & ~(near[t + ify * n + ifx] >> np.uint32(16)) & np.uint32(0x1FF)
            best_d = math.inf
            while valid != 0:
                b = _lowest_bit(valid)
                valid &= valid - np.uint32(1)
                ox = b // 3 - 1
                oy = b - (ox + 1) * 3 - 1
                q = code[t + oy * n + ox]
                mux = hx - means[q, 0]
                muy = hy - means[q, 1]
                d = mux * mux + muy * muy
                take = d < best_d
                best_d = d if take else best_d
                bx = mux if take else bx
                by = muy if take else by
            found = best_d < math.inf
        else:
            for xx in range(-kernel, kernel + 1):
                for yy in range(-kernel, kernel + 1):
                    prx = ihx + xx
                    pry = ihy + yy
                    wx = prx - wx0
                    wy = pry - wy0
                    if 0 <= wx < n and 0 <= wy < n:
                        q = code[wy * n + wx]
                        if q < 0:
                            continue
                        mx = means[q, 0]
                        my = means[q, 1]
                    else:
                        c1, mx, my = _outside(table, accx, accy, hits, visits, prx, pry)
                        if c1 != 1:
                            continue
                    wx += ifx
                    wy += ify
                    if 0 <= wx < n and 0 <= wy < n:
                        if code[wy * n + wx] != -1:
                            continue
                    elif _outside(table, accx, accy, hits, visits, prx + ifx, pry + ify)[0] != 0:
                        continue
                    mux = hx - mx
                    muy = hy - my
                    if not found or mux * mux + muy * muy < bx * bx + by * by:
                        bx = mux
                        by = muy
                        found = True
        d2 = bx * bx + by * by
        if found:
            total += math.exp(-d2 / sigma)
            matched += 1
        if with_likelihood:
            like += -d2 / lsigma if found else no_hit
    return total, like, matched


@njit(cache=True)
def score(
    table: I32,
    accx: F64,
    accy: F64,
    hits: I32,
    visits: I32,
    pose: F64,
    ranges: F64,
    angles: F64,
    laser: F64,
    usable: float,
    sigma: float,
    delta: float,
    cx0: int,
    cy0: int,
    kernel: int,
    lskip: int,
) -> float:  # pragma: no cover - compiled
    """gmapping's ``ScanMatcher::score`` of ``pose`` in one particle's map (its table)."""
    return likelihood_and_score(
        table, accx, accy, hits, visits, pose, ranges, angles, laser, usable, sigma, 1.0,
        delta, cx0, cy0, kernel, lskip,
    )[0]  # fmt: skip


@njit(cache=True)
def likelihood_and_score(
    table: I32,
    accx: F64,
    accy: F64,
    hits: I32,
    visits: I32,
    pose: F64,
    ranges: F64,
    angles: F64,
    laser: F64,
    usable: float,
    sigma: float,
    lsigma: float,
    delta: float,
    cx0: int,
    cy0: int,
    kernel: int,
    lskip: int,
) -> tuple[float, float, int]:  # pragma: no cover - compiled
    """gmapping's ``likelihoodAndScore``: (score, log likelihood, matched beams)."""
    lx, ly, _ = laser_origin(pose, laser)
    win = _window(table, accx, accy, hits, visits, lx, ly, usable, delta, cx0, cy0, kernel)
    return _match(
        win, table, accx, accy, hits, visits, pose[0], pose[1],
        pose[2], ranges, _used_beams(ranges, usable, lskip), np.cos(angles), np.sin(angles),
        laser, sigma, lsigma, delta, cx0, cy0, kernel, True,
    )  # fmt: skip


@njit(cache=True)
def _optimize(
    win: Window,
    table: I32,
    accx: F64,
    accy: F64,
    hits: I32,
    visits: I32,
    init: F64,
    ranges: F64,
    beams: NDArray[np.int64],
    bc: F64,
    bs: F64,
    laser: F64,
    sigma: float,
    delta: float,
    cx0: int,
    cy0: int,
    kernel: int,
    lstep: float,
    astep: float,
    iterations: int,
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    cx, cy, ct = init[0], init[1], init[2]
    current = _match(
        win, table, accx, accy, hits, visits, cx, cy, ct, ranges,
        beams, bc, bs, laser, sigma, 1.0, delta, cx0, cy0, kernel, False,
    )[0]  # fmt: skip
    # poses scored so far: a move back onto one of them (bit for bit, as x + d - d often is)
    # reuses its score, which the same arithmetic would reproduce exactly
    seen = np.empty((_SEEN, 4))
    seen[0, 0], seen[0, 1], seen[0, 2], seen[0, 3] = cx, cy, ct, current
    n_seen = 1
    best = -1.0
    ld = lstep
    ad = astep
    refinement = 0
    while True:
        if best >= current:
            refinement += 1
            ad *= 0.5
            ld *= 0.5
        best = current
        bx, by, bt = cx, cy, ct
        for move in range(6):
            x, y, t = cx, cy, ct
            if move == 0:
                x += ld
            elif move == 1:
                x -= ld
            elif move == 2:
                y -= ld
            elif move == 3:
                y += ld
            elif move == 4:
                t += ad
            else:
                t -= ad
            k = 0
            while k < n_seen and not (seen[k, 0] == x and seen[k, 1] == y and seen[k, 2] == t):
                k += 1
            if k < n_seen:
                sc = seen[k, 3]
            else:
                sc = _match(
                    win, table, accx, accy, hits, visits, x, y, t,
                    ranges, beams, bc, bs, laser, sigma, 1.0, delta, cx0, cy0, kernel, False,
                )[0]  # fmt: skip
                if n_seen < _SEEN:
                    seen[n_seen, 0], seen[n_seen, 1], seen[n_seen, 2] = x, y, t
                    seen[n_seen, 3] = sc
                    n_seen += 1
            if sc > current:
                current = sc
                bx, by, bt = x, y, t
        cx, cy, ct = bx, by, bt
        if not (current > best or refinement < iterations):
            break
    return cx, cy, ct, best


@njit(cache=True)
def optimize(
    table: I32,
    accx: F64,
    accy: F64,
    hits: I32,
    visits: I32,
    init: F64,
    ranges: F64,
    angles: F64,
    laser: F64,
    usable: float,
    sigma: float,
    delta: float,
    cx0: int,
    cy0: int,
    kernel: int,
    lskip: int,
    lstep: float,
    astep: float,
    iterations: int,
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """gmapping's hill climbing ``optimize``: (x, y, theta, best score).

    Six moves (x +-, y -+, theta +-) of the current steps; the best improving move is
    taken; when none improves, both steps halve; stop after ``iterations`` halvings
    without improvement.
    """
    lx, ly, _ = laser_origin(init, laser)
    win = _window(table, accx, accy, hits, visits, lx, ly, usable, delta, cx0, cy0, kernel)
    return _optimize(
        win, table, accx, accy, hits, visits, init, ranges,
        _used_beams(ranges, usable, lskip), np.cos(angles), np.sin(angles), laser, sigma, delta,
        cx0, cy0, kernel, lstep, astep, iterations,
    )  # fmt: skip


@njit(cache=True, parallel=True)
def scan_match_all(
    tables: I32,
    accx: F64,
    accy: F64,
    hits: I32,
    visits: I32,
    poses: F64,
    ranges: F64,
    angles: F64,
    laser: F64,
    usable: float,
    sigma: float,
    lsigma: float,
    delta: float,
    cx0: int,
    cy0: int,
    kernel: int,
    lskip: int,
    lstep: float,
    astep: float,
    iterations: int,
    minimum_score: float,
    out_poses: F64,
    out_scores: F64,
    out_like: F64,
) -> None:  # pragma: no cover - compiled
    """gmapping's ``scanMatch`` over all particles (improved proposal + weight term).

    Each particle's pose becomes its scan-matched pose when the match score exceeds
    ``minimum_score`` (else the odometry-propagated pose stays); ``out_like`` is the
    log likelihood of the scan at the kept pose. Particles run in parallel threads
    (numba ``prange``); each writes only its own outputs, so results do not depend on
    the thread count.
    """
    bc = np.cos(angles)
    bs = np.sin(angles)
    beams = _used_beams(ranges, usable, lskip)
    for p in prange(poses.shape[0]):  # particles are independent: deterministic
        table = tables[p]
        lx, ly, _ = laser_origin(poses[p], laser)
        win = _window(table, accx, accy, hits, visits, lx, ly, usable, delta, cx0, cy0, kernel)
        x, y, t, best = _optimize(
            win, table, accx, accy, hits, visits, poses[p],
            ranges, beams, bc, bs, laser, sigma, delta, cx0, cy0, kernel, lstep, astep,
            iterations,
        )  # fmt: skip
        if best > minimum_score:
            out_poses[p, 0] = x
            out_poses[p, 1] = y
            out_poses[p, 2] = math.atan2(math.sin(t), math.cos(t))
        else:
            out_poses[p, 0] = poses[p, 0]
            out_poses[p, 1] = poses[p, 1]
            out_poses[p, 2] = poses[p, 2]
        out_scores[p] = best
        _, like, _ = _match(
            win, table, accx, accy, hits, visits,
            out_poses[p, 0], out_poses[p, 1], out_poses[p, 2], ranges, beams, bc, bs, laser,
            sigma, lsigma, delta, cx0, cy0, kernel, True,
        )  # fmt: skip
        out_like[p] = like
