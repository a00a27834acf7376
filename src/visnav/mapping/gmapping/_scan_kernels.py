"""numba kernels of gmapping's scan matcher (``score``, ``likelihoodAndScore``, ``optimize``).

The lookups of one particle's map go through a dense window around the laser
(:func:`_window`: each cell's class, each full cell's mean hit point, and per cell two
3 x 3 bit masks, its full neighbours and its neighbours that are not below the fullness
threshold), falling back to the patch tables outside it. A beam's candidate cells are
then one AND of two masks (the end point's full neighbours and the not-below neighbours of
the cell one free step back), and its distance is the smallest of the candidates'
distances, taken over all nine neighbours without branches (a neighbour that is not a
candidate reads a mean at infinity instead of its own). The results are those of
gmapping's per-cell rules bit for bit (:mod:`visnav.mapping.gmapping.reference` is the
plain-Python version).

Each beam's offsets from the laser (``r * (cos, sin)`` of its world direction and the
free step back) depend on the heading only: they are computed once per heading
(:func:`_beam_geometry`) and shared by the four moves of the hill climbing that keep it,
with the same arithmetic, so the end points are the same numbers.

The hill climbing only asks whether a move scores above the current score. A score is a
sum of one term ``exp(-u)`` in ``[0, 1]`` per beam, so a move is abandoned as soon as upper
bounds of the terms so far (``min(1, 1 - u + u^2 / 2)``, no ``exp``) plus one per beam left
stay below the current score (with a margin larger than the rounding of the sums); a move
that is not abandoned gets its terms summed in beam order, the same score bit for bit as
without the bound, so the climb takes the same steps as gmapping's.
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
I8 = NDArray[np.int8]
_NULL_LIKELIHOOD = -0.5
_WIN_MARGIN = 10  # cells the hill climbing may move before lookups leave the window
_WIN_HALF_MAX = 90  # at most (2 * 90 + 1)**2 cells (0.6 MB) per particle's window
_SEEN = 256  # poses the hill climbing remembers (it scores about 100)
_BELOW, _AT, _FULL = 0, 1, 2  # cell classes; unknown cells are below the threshold
# (cls, mx, my, wx0, wy0, near, n): see :func:`_window`
Window = tuple[I8, F64, F64, int, int, NDArray[np.uint32], int]


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

    Returns ``(cls, mx, my, wx0, wy0, near, n)`` over an ``n x n`` window whose cell (0, 0)
    is table cell ``(wx0, wy0)``; cell ``(wx, wy)`` is entry ``wy * n + wx`` of the flat
    arrays. ``cls`` is the cell's class: ``_BELOW`` gmapping's fullness threshold (or
    unknown), ``_AT`` exactly at it, ``_FULL`` above it; ``mx``, ``my`` hold a full cell's
    mean hit point (unspecified for the others, which are never read) and, at entry
    ``n * n``, a point at infinity. With ``kernel`` 1, ``near`` holds each cell's 3 x 3
    neighbourhood as bits ``(oy + 1) * 4 + (ox + 1)`` (offsets -1..1): bits 0-10 the
    neighbours that are full, bits 16-26 those that are not below the threshold (full or
    exactly at it); other kernels leave it 0.
    """
    # capped (lookups beyond the window use the patches)
    half = min(math.ceil(reach / delta) + _WIN_MARGIN, _WIN_HALF_MAX)
    wx0 = math.floor(lx / delta) - cx0 - half
    wy0 = math.floor(ly / delta) - cy0 - half
    n = 2 * half + 1
    cls = np.zeros(n * n, np.int8)
    # mean hit point of full cells (the others are never read); entry n * n is a sentinel
    # at infinity that candidates which are not taken read instead
    mx = np.empty(n * n + 1)
    my = np.empty(n * n + 1)
    mx[n * n] = math.inf
    my[n * n] = 0.0
    near = np.zeros(n * n, np.uint32)
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
            oy0 = (py << PATCH_SHIFT) - wy0  # window row of the patch's row 0
            ox0 = (px << PATCH_SHIFT) - wx0
            for cy in range(max(0, -oy0), min(PATCH, n - oy0)):
                wy = oy0 + cy
                for cx in range(max(0, -ox0), min(PATCH, n - ox0)):
                    wx = ox0 + cx
                    kk = (cy << PATCH_SHIFT) | cx
                    v = visits[pid, kk]
                    if v == 0:
                        continue
                    h = hits[pid, kk]
                    w = wy * n + wx
                    if h / v == FULLNESS:
                        cls[w] = _AT
                        bits = np.uint32(0x10000)
                    elif h / v > FULLNESS:
                        cls[w] = _FULL
                        mx[w] = accx[pid, kk] / h
                        my[w] = accy[pid, kk] / h
                        bits = np.uint32(0x10001)
                    else:
                        continue
                    if kernel != 1:
                        continue
                    # the cell is neighbour (ox, oy) of the cell at (wx - ox, wy - oy)
                    for oy in range(-1, 2):
                        ty = wy - oy
                        if ty < 0 or ty >= n:
                            continue
                        for ox in range(-1, 2):
                            tx = wx - ox
                            if 0 <= tx < n:
                                near[ty * n + tx] |= bits << np.uint32((oy + 1) * 4 + ox + 1)
    return cls, mx, my, wx0, wy0, near, n


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


@njit(cache=True)
def _beam_table(ranges: F64, beams: NDArray[np.int64], angles: F64) -> F64:  # pragma: no cover
    """(3, U) range, cos and sin of the beam angle of each used beam, contiguous."""
    out = np.empty((3, beams.shape[0]))
    for j in range(beams.shape[0]):
        i = beams[j]
        out[0, j] = ranges[i]
        out[1, j] = math.cos(angles[i])
        out[2, j] = math.sin(angles[i])
    return out


@njit(cache=True)
def _beam_geometry(
    th: float, rcs: F64, laser: F64, delta: float, geo: F64
) -> None:  # pragma: no cover - compiled
    """Each used beam's end point and free step relative to the laser, at heading ``th``.

    ``rcs``: :func:`_beam_table`. ``geo[0:2, j]``: ``r * (cos, sin)`` of the beam's world
    direction, ``geo[2:4, j]``: ``delta * sqrt(2) * (cos, sin)``. Moves that keep the
    heading share them; the arithmetic is that of one beam at a time (no reordering).
    """
    lth = th + laser[2]
    cl = math.cos(lth)
    sl = math.sin(lth)
    free_delta = delta * FREE_RATIO
    for j in range(rcs.shape[1]):
        r = rcs[0, j]
        ca = cl * rcs[1, j] - sl * rcs[2, j]
        sa = sl * rcs[1, j] + cl * rcs[2, j]
        geo[0, j] = r * ca
        geo[1, j] = r * sa
        geo[2, j] = free_delta * ca
        geo[3, j] = free_delta * sa


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
    rcs: F64,
    geo: F64,
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

    ``rcs``: the used beams (:func:`_beam_table`); ``geo``: their geometry at heading ``th``
    (:func:`_beam_geometry`). Per beam, the candidates are the full cells of the
    kernel window around the end point's cell whose cell one ``delta * sqrt(2)`` step back
    along the beam from the candidate is below the threshold; the beam's distance is that
    of the nearest candidate mean (gmapping keeps the first strictly nearest: the same
    distance). With ``kernel`` 1 and the window around the end point inside the window
    (:func:`_window`), the candidates are the set bits of ``full(end cell) & ~notbelow(free
    cell)`` of the ``near`` masks (the others read the window's point at infinity); else
    the loops read the window's classes and, beyond it, the patches.

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
    inv_delta = 1.0 / delta
    no_hit = _NULL_LIKELIHOOD / lsigma
    cls, mx, my, wx0, wy0, near, n = win
    sentinel = np.uint64(n * n)
    fast = kernel == 1
    total = 0.0
    like = 0.0
    matched = 0
    nb = rcs.shape[1] - 1
    bounded = bound > -math.inf and not with_likelihood
    # each term is <= 1 and <= its upper bound; the margin covers the sums' rounding (< nb^2
    # ulps of terms <= 1) and the bound's rounding (a few ulps per term)
    bound -= 1e-9 + 1e-15 * nb * nb
    inv_sigma = 1.0 / sigma
    upper = 0.0
    for j in range(nb + 1):
        if rcs[0, j] == 0.0 and not with_likelihood:
            if bounded:
                dists[j] = -1.0
            continue
        hx = lx + geo[0, j]
        hy = ly + geo[1, j]
        ihx = math.floor(hx * inv_delta) - cx0
        ihy = math.floor(hy * inv_delta) - cy0
        ifx = math.floor((hx - geo[2, j]) * inv_delta) - cx0 - ihx
        ify = math.floor((hy - geo[3, j]) * inv_delta) - cy0 - ihy
        found = False
        bx = 0.0
        by = 0.0
        wcx = ihx - wx0
        wcy = ihy - wy0
        if fast and 3 <= wcx < n - 3 and 3 <= wcy < n - 3:
            # |ifx|, |ify| <= 2: both 3 x 3 neighbourhoods are inside the window
            t = wcy * n + wcx
            ut = np.uint64(t)
            valid = near[ut] & ~(near[np.uint64(t + ify * n + ifx)] >> np.uint32(16))
            valid &= np.uint32(0xFFF)
            best_d = math.inf
            if valid != 0:
                for row in range(3):
                    base = np.uint64(t + (row - 1) * n - 1)
                    for col in range(3):
                        on = ((valid >> np.uint32(row * 4 + col)) & np.uint32(1)) != 0
                        q = base + np.uint64(col) if on else sentinel
                        mux = hx - mx[q]
                        muy = hy - my[q]
                        best_d = min(best_d, mux * mux + muy * muy)
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
                        cmx = mx[wy * n + wx]
                        cmy = my[wy * n + wx]
                    else:
                        c1, cmx, cmy = _outside(table, accx, accy, hits, visits, prx, pry)
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
                    mux = hx - cmx
                    muy = hy - cmy
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
        for j in range(nb + 1):
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
    rcs = _beam_table(ranges, _used_beams(ranges, usable, lskip), angles)
    geo = np.empty((4, rcs.shape[1]))
    _beam_geometry(pose[2], rcs, laser, delta, geo)
    return _match(
        win, table, accx, accy, hits, visits, pose[0], pose[1], pose[2], rcs, geo,
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
    rcs: F64,
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
    nb = rcs.shape[1]
    dists = np.empty(nb)
    geo = np.empty((4, nb))  # at heading geo_th: the current pose's, shared by x and y moves
    turned = np.empty((4, nb))  # at a turned heading
    _beam_geometry(ct, rcs, laser, delta, geo)
    geo_th = ct
    current = _match(
        win, table, accx, accy, hits, visits, cx, cy, ct, rcs, geo,
        laser, sigma, 1.0, delta, cx0, cy0, kernel, False, -math.inf, dists,
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
                g = geo
                if t != geo_th:
                    _beam_geometry(t, rcs, laser, delta, turned)
                    g = turned
                sc = _match(
                    win, table, accx, accy, hits, visits, x, y, t, rcs, g,
                    laser, sigma, 1.0, delta, cx0, cy0, kernel, False, current, dists,
                )[0]  # fmt: skip
                if n_seen < _SEEN:
                    seen[n_seen, 0], seen[n_seen, 1], seen[n_seen, 2] = x, y, t
                    seen[n_seen, 3] = sc
                    n_seen += 1
            if sc > current:
                current = sc
                bx, by, bt = x, y, t
        cx, cy, ct = bx, by, bt
        if ct != geo_th:
            _beam_geometry(ct, rcs, laser, delta, geo)
            geo_th = ct
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
    rcs = _beam_table(ranges, _used_beams(ranges, usable, lskip), angles)
    return _optimize(
        win, table, accx, accy, hits, visits, init, rcs, laser, sigma, delta,
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
    rcs = _beam_table(ranges, _used_beams(ranges, usable, lskip), angles)
    for p in prange(poses.shape[0]):  # particles are independent: deterministic
        table = tables[p]
        lx, ly, _ = laser_origin(poses[p], laser)
        win = _window(table, accx, accy, hits, visits, lx, ly, usable, delta, cx0, cy0, kernel)
        x, y, t, best = _optimize(
            win, table, accx, accy, hits, visits, poses[p], rcs, laser, sigma, delta,
            cx0, cy0, kernel, lstep, astep, iterations,
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
        geo = np.empty((4, rcs.shape[1]))
        _beam_geometry(out_poses[p, 2], rcs, laser, delta, geo)
        _, like, _ = _match(
            win, table, accx, accy, hits, visits, out_poses[p, 0], out_poses[p, 1],
            out_poses[p, 2], rcs, geo, laser, sigma, lsigma, delta, cx0, cy0, kernel, True,
            -math.inf, np.empty(0),
        )  # fmt: skip
        out_like[p] = like
