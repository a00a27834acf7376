"""numba kernels of gmapping's scan matcher (``score``, ``likelihoodAndScore``, ``optimize``).

The lookups of one particle's map go through a dense window around the laser
(:func:`_window`: for each full cell its mean hit point and which neighbours are free),
falling back to the patch tables outside it, so the results are those of gmapping's
per-cell rules (:mod:`visnav.mapping.gmapping.reference` is the plain-Python version).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
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
) -> tuple[I16, F64, NDArray[np.uint32], int, int]:  # pragma: no cover - compiled
    """A dense index of a particle's full cells around a laser origin, for fast lookups.

    Returns ``(code, means, masks, wx0, wy0)``: ``code[wy, wx]`` is -1 for a cell below
    gmapping's fullness threshold (or unknown), -2 exactly at it, else an index into
    ``means`` (K, 4) (the cell's mean hit point x, y, then its mask as a float) and
    ``masks`` (K,): bit
    ``(ox + 2) * 5 + (oy + 2)`` is set when the cell at offset ``(ox, oy)`` (each in -2..2)
    is below the threshold (free or unknown). The window's cell (0, 0) is table cell ``(wx0, wy0)``.
    """
    # capped so that every code fits an int16 (lookups beyond the window use the patches)
    half = min(math.ceil(reach / delta) + _WIN_MARGIN, _WIN_HALF_MAX)
    wx0 = math.floor(lx / delta) - cx0 - half
    wy0 = math.floor(ly / delta) - cy0 - half
    n = 2 * half + 1
    code = np.full((n, n), -1, np.int16)
    cap = 256
    means = np.empty((cap, 2))
    where = np.empty((cap, 2), np.int64)
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
                        code[wy, wx] = -2  # neither full nor below the threshold
                    elif h / v > FULLNESS:
                        if count == cap:
                            grown = np.empty((2 * cap, 2))
                            grown[:count] = means[:count]
                            means = grown
                            grown_w = np.empty((2 * cap, 2), np.int64)
                            grown_w[:count] = where[:count]
                            where = grown_w
                            cap *= 2
                        means[count, 0] = accx[pid, kk] / h
                        means[count, 1] = accy[pid, kk] / h
                        where[count, 0] = wx
                        where[count, 1] = wy
                        code[wy, wx] = np.int16(count)
                        count += 1
    masks = np.zeros(count, np.uint32)
    for c in range(count):
        wx = where[c, 0]
        wy = where[c, 1]
        m = np.uint32(0)
        for ox in range(-2, 3):
            for oy in range(-2, 3):
                nx = wx + ox
                ny = wy + oy
                if 0 <= nx < n and 0 <= ny < n:
                    below = code[ny, nx] == -1
                else:
                    below = _outside(table, accx, accy, hits, visits, nx + wx0, ny + wy0)[0] == 0
                if below:
                    m |= np.uint32(1) << np.uint32((ox + 2) * 5 + (oy + 2))
        masks[c] = m
    # the fast path reads a full cell's mean and mask from one 32-byte record
    rec = np.zeros((count + 1, 4))  # row ``count``: no cell (mask 0)
    for c in range(count):
        rec[c, 0] = means[c, 0]
        rec[c, 1] = means[c, 1]
        rec[c, 2] = masks[c]
        rec[c, 3] = 0.0
    return code, rec, masks, wx0, wy0


@njit(cache=True)
def _outside(
    table: I32, accx: F64, accy: F64, hits: I32, visits: I32, ix: int, iy: int
) -> tuple[int, float, float]:  # pragma: no cover - compiled
    """(class, mean x, mean y) of a table cell outside the window (as :func:`_window`)."""
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


@njit(cache=True)
def _match(
    code: I16,
    means: F64,
    masks: NDArray[np.uint32],
    wx0: int,
    wy0: int,
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
    angles (computed once per scan); the window (:func:`_window`) answers the lookups it
    covers (branch-free when the whole kernel window is inside it), the patches the others.
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
    wh, ww = code.shape
    none = means.shape[0] - 1
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
        if kernel <= wcx < ww - kernel and kernel <= wcy < wh - kernel:
            # branch-free over the kernel window: a cell that is not full reads record
            # ``none`` (mask 0); the first strictly nearest valid mean wins, as in the loops
            free_bit = (ifx + 2) * 5 + (ify + 2)
            best_d = math.inf
            for xx in range(-kernel, kernel + 1):
                for yy in range(-kernel, kernel + 1):
                    q = code[wcy + yy, wcx + xx]
                    q = q if q >= 0 else none
                    mux = hx - means[q, 0]
                    muy = hy - means[q, 1]
                    d = mux * mux + muy * muy
                    take = ((np.int64(means[q, 2]) >> free_bit) & 1 != 0) & (d < best_d)
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
                    if 0 <= wx < ww and 0 <= wy < wh:
                        q = code[wy, wx]
                        if q < 0 or (masks[q] >> ((ifx + 2) * 5 + (ify + 2))) & 1 == 0:
                            continue
                        mx = means[q, 0]
                        my = means[q, 1]
                    else:
                        c1, mx, my = _outside(table, accx, accy, hits, visits, prx, pry)
                        if c1 != 1:
                            continue
                        c2 = _outside(table, accx, accy, hits, visits, prx + ifx, pry + ify)[0]
                        if c2 != 0:
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
    code, means, masks, wx0, wy0 = _window(
        table, accx, accy, hits, visits, lx, ly, usable, delta, cx0, cy0
    )
    return _match(
        code, means, masks, wx0, wy0, table, accx, accy, hits, visits, pose[0], pose[1],
        pose[2], ranges, _used_beams(ranges, usable, lskip), np.cos(angles), np.sin(angles),
        laser, sigma, lsigma, delta, cx0, cy0, kernel, True,
    )  # fmt: skip


@njit(cache=True)
def _optimize(
    code: I16,
    means: F64,
    masks: NDArray[np.uint32],
    wx0: int,
    wy0: int,
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
        code, means, masks, wx0, wy0, table, accx, accy, hits, visits, cx, cy, ct, ranges,
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
                    code, means, masks, wx0, wy0, table, accx, accy, hits, visits, x, y, t,
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
    code, means, masks, wx0, wy0 = _window(
        table, accx, accy, hits, visits, lx, ly, usable, delta, cx0, cy0
    )
    return _optimize(
        code, means, masks, wx0, wy0, table, accx, accy, hits, visits, init, ranges,
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
        code, means, masks, wx0, wy0 = _window(
            table, accx, accy, hits, visits, lx, ly, usable, delta, cx0, cy0
        )
        x, y, t, best = _optimize(
            code, means, masks, wx0, wy0, table, accx, accy, hits, visits, poses[p],
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
            code, means, masks, wx0, wy0, table, accx, accy, hits, visits,
            out_poses[p, 0], out_poses[p, 1], out_poses[p, 2], ranges, beams, bc, bs, laser,
            sigma, lsigma, delta, cx0, cy0, kernel, True,
        )  # fmt: skip
        out_like[p] = like
