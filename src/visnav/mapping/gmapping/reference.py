"""A plain-Python scan matcher: the reference the compiled kernels are checked and timed against.

The same arithmetic as :mod:`visnav.mapping.gmapping._scan_kernels` (gmapping's ``score``,
``likelihoodAndScore`` and hill-climbing ``optimize``), written as per-beam Python loops
over one particle's patch table, without the dense window. Tests compare the two; the
benchmark (``bench/bench_gmapping.py``) times both on the same scans.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.gmapping._kernels import PATCH, PATCH_SHIFT
from visnav.mapping.gmapping.maps import ParticleMaps

__all__ = ["optimize_py", "scan_match_py", "score_py"]

_FULLNESS = 0.1
_FREE_RATIO = math.sqrt(2.0)


def _cell(maps: ParticleMaps, particle: int, ix: int, iy: int) -> tuple[float, float, float]:
    table = maps.tables[particle]
    if ix < 0 or iy < 0:
        return -1.0, 0.0, 0.0
    px, py = ix >> PATCH_SHIFT, iy >> PATCH_SHIFT
    if px >= table.shape[1] or py >= table.shape[0]:
        return -1.0, 0.0, 0.0
    pid = int(table[py, px])
    if pid < 0:
        return -1.0, 0.0, 0.0
    k = ((iy & (PATCH - 1)) << PATCH_SHIFT) | (ix & (PATCH - 1))
    v = int(maps.visits[pid, k])
    if v == 0:
        return -1.0, 0.0, 0.0
    n = int(maps.hits[pid, k])
    if n == 0:
        return 0.0, 0.0, 0.0
    return n / v, float(maps.accx[pid, k]) / n, float(maps.accy[pid, k]) / n


def score_py(
    maps: ParticleMaps,
    particle: int,
    pose: tuple[float, float, float],
    ranges: NDArray[np.float64],
    angles: NDArray[np.float64],
    laser: tuple[float, float, float],
    *,
    usable: float,
    sigma: float,
    lsigma: float = 1.0,
    kernel: int = 1,
    lskip: int = 0,
) -> tuple[float, float, int]:
    """gmapping's ``likelihoodAndScore`` in Python: (score, log likelihood, matched beams)."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    lx = x + c * laser[0] - s * laser[1]
    ly = y + s * laser[0] + c * laser[1]
    lth = th + laser[2]
    cl, sl = math.cos(lth), math.sin(lth)
    delta = maps.delta
    free_delta = delta * _FREE_RATIO
    inv = 1.0 / delta
    total, like, matched, skip = 0.0, 0.0, 0, 0
    for i in range(len(ranges)):
        skip += 1
        if skip > lskip:
            skip = 0
        r = float(ranges[i])
        if not r <= usable or skip != 0:
            continue
        bc, bs = math.cos(float(angles[i])), math.sin(float(angles[i]))
        ca, sa = cl * bc - sl * bs, sl * bc + cl * bs
        hx, hy = lx + r * ca, ly + r * sa
        ihx = math.floor(hx * inv) - maps.cx0
        ihy = math.floor(hy * inv) - maps.cy0
        ifx = math.floor((hx - free_delta * ca) * inv) - maps.cx0 - ihx
        ify = math.floor((hy - free_delta * sa) * inv) - maps.cy0 - ihy
        best: tuple[float, float] | None = None
        for xx in range(-kernel, kernel + 1):
            for yy in range(-kernel, kernel + 1):
                v, mx, my = _cell(maps, particle, ihx + xx, ihy + yy)
                if v <= _FULLNESS:
                    continue
                if _cell(maps, particle, ihx + xx + ifx, ihy + yy + ify)[0] >= _FULLNESS:
                    continue
                mu = (hx - mx, hy - my)
                if best is None or mu[0] ** 2 + mu[1] ** 2 < best[0] ** 2 + best[1] ** 2:
                    best = mu
        d2 = 0.0 if best is None else best[0] * best[0] + best[1] * best[1]
        if best is not None:
            total += math.exp(-d2 / sigma)
            matched += 1
        like += -d2 / lsigma if best is not None else -0.5 / lsigma
    return total, like, matched


def optimize_py(
    maps: ParticleMaps,
    particle: int,
    init: tuple[float, float, float],
    ranges: NDArray[np.float64],
    angles: NDArray[np.float64],
    laser: tuple[float, float, float],
    *,
    usable: float,
    sigma: float,
    kernel: int = 1,
    lskip: int = 0,
    lstep: float = 0.05,
    astep: float = 0.05,
    iterations: int = 5,
) -> tuple[float, float, float, float]:
    """gmapping's hill-climbing ``optimize`` in Python: (x, y, theta, best score)."""

    def sc(p: tuple[float, float, float]) -> float:
        return score_py(
            maps, particle, p, ranges, angles, laser, usable=usable, sigma=sigma,
            kernel=kernel, lskip=lskip,
        )[0]  # fmt: skip

    current_pose = init
    current = sc(current_pose)
    best, ld, ad, refinement = -1.0, lstep, astep, 0
    while True:
        if best >= current:
            refinement += 1
            ad, ld = ad * 0.5, ld * 0.5
        best = current
        x, y, t = current_pose
        best_pose = current_pose
        for cand in (
            (x + ld, y, t), (x - ld, y, t), (x, y - ld, t), (x, y + ld, t),
            (x, y, t + ad), (x, y, t - ad),
        ):  # fmt: skip
            value = sc(cand)
            if value > current:
                current, best_pose = value, cand
        current_pose = best_pose
        if not (current > best or refinement < iterations):
            break
    return (*current_pose, best)


def scan_match_py(
    maps: ParticleMaps,
    poses: NDArray[np.float64],
    ranges: NDArray[np.float64],
    angles: NDArray[np.float64],
    laser: tuple[float, float, float],
    *,
    usable: float,
    sigma: float,
    lsigma: float,
    minimum_score: float,
    kernel: int = 1,
    lskip: int = 0,
    lstep: float = 0.05,
    astep: float = 0.05,
    iterations: int = 5,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """gmapping's ``scanMatch``, one particle at a time: (new poses, log likelihoods)."""
    out = np.array(poses, dtype=np.float64)
    like = np.zeros(len(poses))
    for p in range(len(poses)):
        init = (float(poses[p, 0]), float(poses[p, 1]), float(poses[p, 2]))
        x, y, t, best = optimize_py(
            maps, p, init, ranges, angles, laser, usable=usable, sigma=sigma, kernel=kernel,
            lskip=lskip, lstep=lstep, astep=astep, iterations=iterations,
        )  # fmt: skip
        if best > minimum_score:
            out[p] = (x, y, math.atan2(math.sin(t), math.cos(t)))
        kept = (float(out[p, 0]), float(out[p, 1]), float(out[p, 2]))
        like[p] = score_py(
            maps, p, kept, ranges, angles, laser, usable=usable, sigma=sigma, lsigma=lsigma,
            kernel=kernel, lskip=lskip,
        )[1]  # fmt: skip
    return out, like
