"""numba kernels of gmapping's scan matcher (``score``, ``likelihoodAndScore``, ``optimize``).

The lookups of one particle's map go through a dense window around the laser
(:func:`_window`: each cell's class, each full cell's mean hit point, and per cell two
3 x 3 bit masks, its full neighbours and its neighbours that are not below the fullness
threshold), falling back to the patch tables outside it. A beam's candidate cells are
then one AND of two masks (the end point's full neighbours and the not-below neighbours of
the cell one free step back), and its distance is the smallest of the candidates'
distances, taken over all nine neighbours without branches. The results are those of
gmapping's per-cell rules bit for bit (:mod:`visnav.mapping.gmapping.reference` is the
plain-Python version).

The hill climbing only asks whether a move scores above the current score. A score is a
sum of one term ``exp(-u)`` in ``[0, 1]`` per beam, so a move is abandoned as soon as upper
bounds of the terms so far (``min(1, 1 - u + u^2 / 2)``, no ``exp``) plus one per beam left
stay below the current score (with a margin larger than the rounding of the sums); a move
that is not abandoned gets its terms summed in beam order, the same score bit for bit as
without the bound, so the climb takes the same steps as gmapping's.
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
I8 = NDArray[np.int8]
_NULL_LIKELIHOOD = -0.5
_WIN_MARGIN = 10  # cells the hill climbing may move before lookups leave the window
_WIN_HALF_MAX = 90  # at most (2 * 90 + 1)**2 cells (0.6 MB) per particle's window
_SEEN = 256  # poses the hill climbing remembers (it scores about 100)
_lowest_bit = cast("Callable[[Any], int]", trailing_zeros)  # index of the lowest set bit
_BELOW, _AT, _FULL = 0, 1, 2  # cell classes; unknown cells are below the threshold
# (cls, means, wx0, wy0, near, n): see :func:`_window`
Window = tuple[I8, F64, int, int, NDArray[np.uint32], int]


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
    """A dense copy of a particle's map classes around a laser origin, for fast lookups.

    Returns ``(cls, means, wx0, wy0, near, n)`` over an ``n x n`` window whose cell (0, 0) is
    table cell ``(wx0, wy0)``; cell ``(wx, wy)`` is entry ``wy * n + wx`` of the flat arrays.
    ``cls`` is the cell's class: ``_BELOW`` gmapping's fullness threshold (or unknown),
    ``_AT`` exactly at it, ``_FULL`` above it; ``means`` holds a full cell's mean hit point
    ``(x, y)`` (unspecified for the others: their distances are computed and discarded). With
    ``kernel`` 1, ``near`` holds each cell's 3 x 3 neighbourhood as bits ``(ox + 1) * 3 +
    (oy + 1)`` (offsets -1..1): bits 0-8 the neighbours that are full, bits 16-24 those
    that are not below the threshold (full or exactly at it); other kernels leave it 0.
    """
    # capped (lookups beyond the window use the patches)
    half = min(math.ceil(reach / delta) + _WIN_MARGIN, _WIN_HALF_MAX)
    wx0 = math.floor(lx / delta) - cx0 - half
    wy0 = math.floor(ly / delta) - cy0 - half
    n = 2 * half + 1
    cls = np.zeros(n * n, np.int8)
    means = np.empty((n * n, 2))  # set for full cells; the others are never used
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
                    w = wy * n + wx
                    if h / v == FULLNESS:
                        cls[w] = _AT
                    elif h / v > FULLNESS:
                        cls[w] = _FULL
                        means[w, 0] = accx[pid, kk] / h
                        means[w, 1] = accy[pid, kk] / h
    near = np.zeros(n * n, np.uint32)
    if kernel == 1:
        for w in range(n * n):
            c = cls[w]
            if c == _BELOW:
                continue
            bits = np.uint32(0x10001) if c == _FULL else np.uint32(0x10000)
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
    return cls, means, wx0, wy0, near, n


@njit(cache=True)
def _outside(
    table: I32, accx: F64, accy: F64, hits: I32, visits: I32, ix: int, iy: int
) -> tuple[int, float, float]:  # pragma: no cover - compiled
    """(class, mean x, mean y) of a table cell outside the window (classes as in the window)."""
    v, mx, my = cell(table, accx, accy, hits, visits, ix, iy)
    if v > FULLNESS:
        return _FULL, mx, my
    if v == FULLNESS:
        return _AT, 0.0, 0.0
    return _BELOW, 0.0, 0.0


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
    bound: float,
    dists: F64,
) -> tuple[float, float, int]:  # pragma: no cover - compiled
    """gmapping's score (and likelihoodAndScore): returns (score, log likelihood, matched).

    ``beams``: the used beams (:func:`_used_beams`); ``bc``, ``bs``: cos and sin of the beam
    angles (computed once per scan). Per beam, the candidates are the full cells of the
    kernel window around the end point's cell whose cell one ``delta * sqrt(2)`` step back
    along the beam from the candidate is below the threshold; the beam's distance is that
    of the nearest candidate mean (gmapping keeps the first strictly nearest: the same
    distance). With ``kernel`` 1 and the window around the end point inside the window
    (:func:`_window`), the candidates are the set bits of ``full(end cell) & ~notbelow(free
    cell)`` of the ``near`` masks; else the loops read the window's classes and, beyond it,
    the patches.

    With a finite ``bound`` (and without the likelihood) it returns ``(-inf, 0, 0)`` as soon
    as the score cannot exceed ``bound``: the beams' distances go to ``dists`` (scratch, one
    per used beam) and the bound adds ``min(1, 1 - u + u^2 / 2) >= exp(-u)`` per matched
    beam, so no ``exp`` is spent on a move that loses; a move that does not lose gets its
    terms summed in beam order afterwards, the same numbers as without a bound.
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
    cls, means, wx0, wy0, near, n = win
    fast = kernel == 1
    total = 0.0
    like = 0.0
    matched = 0
    nb = beams.shape[0] - 1
    bounded = bound > -math.inf and not with_likelihood
    # each term is <= 1 and <= its upper bound; the margin covers the sums' rounding (< nb^2
    # ulps of terms <= 1) and the bound's rounding (a few ulps per term)
    bound -= 1e-9 + 1e-15 * nb * nb
    inv_sigma = 1.0 / sigma
    upper = 0.0
    for j in range(beams.shape[0]):
        i = beams[j]
        r = ranges[i]
        if r == 0.0 and not with_likelihood:
            if bounded:
                dists[j] = -1.0
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
            if valid != 0:
                for bb in range(9):
                    ox = bb // 3 - 1
                    oy = bb % 3 - 1
                    q = t + oy * n + ox
                    mux = hx - means[q, 0]
                    muy = hy - means[q, 1]
                    d = mux * mux + muy * muy
                    take = (((valid >> np.uint32(bb)) & np.uint32(1)) != 0) & (d < best_d)
                    best_d = d if take else best_d
            found = best_d < math.inf
            d2 = best_d if found else 0.0
        else:
            for xx in range(-kernel, kernel + 1):
                for yy in range(-kernel, kernel + 1):
                    prx = ihx + xx
                    pry = ihy + yy
                    wx = prx - wx0
                    wy = pry - wy0
                    if 0 <= wx < n and 0 <= wy < n:
                        if cls[wy * n + wx] != _FULL:
                            continue
                        mx = means[wy * n + wx, 0]
                        my = means[wy * n + wx, 1]
                    else:
                        c1, mx, my = _outside(table, accx, accy, hits, visits, prx, pry)
                        if c1 != _FULL:
                            continue
                    wx += ifx
                    wy += ify
                    if 0 <= wx < n and 0 <= wy < n:
                        if cls[wy * n + wx] != _BELOW:
                            continue
                    elif (
                        _outside(table, accx, accy, hits, visits, prx + ifx, pry + ify)[0] != _BELOW
                    ):
                        continue
                    mux = hx - mx
                    muy = hy - my
                    if not found or mux * mux + muy * muy < bx * bx + by * by:
                        bx = mux
                        by = muy
                        found = True
            d2 = bx * bx + by * by
        if bounded:
            dists[j] = d2 if found else -1.0
            if found:
                u = d2 * inv_sigma
                upper += min(1.0, 1.0 - u + 0.5 * u * u)
            if upper + (nb - j) < bound:
                return -math.inf, 0.0, 0
            continue
        if found:
            total += math.exp(-d2 / sigma)
            matched += 1
        if with_likelihood:
            like += -d2 / lsigma if found else no_hit
    if bounded:
        for j in range(beams.shape[0]):
            if dists[j] >= 0.0:
                total += math.exp(-dists[j] / sigma)
                matched += 1
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
        laser, sigma, lsigma, delta, cx0, cy0, kernel, True, -math.inf, np.empty(0),
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
    dists = np.empty(beams.shape[0])
    current = _match(
        win, table, accx, accy, hits, visits, cx, cy, ct, ranges,
        beams, bc, bs, laser, sigma, 1.0, delta, cx0, cy0, kernel, False, -math.inf, dists,
    )[0]  # fmt: skip
    # poses scored so far: a move back onto one of them (bit for bit, as x + d - d often is)
    # reuses its score, which the same arithmetic would reproduce exactly (-inf for an
    # abandoned move: it stays below the current score, which only grows)
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
                    current, dists,
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
            sigma, lsigma, delta, cx0, cy0, kernel, True, -math.inf, np.empty(0),
        )  # fmt: skip
        out_like[p] = like
