"""numba kernel of AMCL's likelihood field model (one pass per particle, no temporaries).

The numpy form in :func:`visnav.mapping.amcl_models.likelihood_field_weights` built
``(N, B, 2)`` end points and looked them up in four passes; this kernel does the same
arithmetic (the laser pose, each beam's end point, the bilinear lookup in the padded
signed distance grid, ``pz^3``) per particle in one loop.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["likelihood_field_kernel"]


@numba.njit(cache=True)
def likelihood_field_kernel(
    poses: np.ndarray,
    ranges: np.ndarray,
    angles: np.ndarray,
    laser: np.ndarray,
    padded: np.ndarray,
    grid_pose: np.ndarray,
    resolution: float,
    max_dist: float,
    z_hit: float,
    z_rand_term: float,
    inv_two_sigma2: float,
    product: bool,
) -> np.ndarray:
    """``1 + sum(pz^3)`` (or ``sum(log pz)``) per particle.

    Args:
        poses: ``(N, 3)`` particle poses.
        ranges: ``(B,)`` ranges.
        angles: ``(B,)`` beam angles in the laser frame.
        laser: ``(3,)`` laser pose in the base frame.
        padded: The signed distance grid with one cell of ``max_dist`` around it.
        grid_pose: ``(ox, oy, cos, sin)`` of the grid origin.
        resolution: Cell size (m).
        max_dist: Distance cap (m).
        z_hit: Hit weight.
        z_rand_term: ``z_rand / range_max``.
        inv_two_sigma2: ``1 / (2 sigma_hit^2)``.
        product: Return ``sum(log pz)`` (nav2's ``likelihood_field_prob``) instead.
    """
    n = poses.shape[0]
    b = ranges.shape[0]
    out = np.empty(n)
    ox, oy, gc, gs = grid_pose[0], grid_pose[1], grid_pose[2], grid_pose[3]
    inv = 1.0 / resolution
    height = padded.shape[0] - 2
    width = padded.shape[1] - 2
    for i in range(n):
        c = math.cos(poses[i, 2])
        s = math.sin(poses[i, 2])
        lx = poses[i, 0] + c * laser[0] - s * laser[1]
        ly = poses[i, 1] + s * laser[0] + c * laser[1]
        lt = poses[i, 2] + laser[2]
        total = 0.0 if product else 1.0
        for j in range(b):
            th = lt + angles[j]
            px = lx + ranges[j] * math.cos(th) - ox
            py = ly + ranges[j] * math.sin(th) - oy
            gx = (gc * px + gs * py) * inv - 0.5
            gy = (-gs * px + gc * py) * inv - 0.5
            c0 = math.floor(gx)
            r0 = math.floor(gy)
            d = max_dist
            if c0 >= -1 and c0 < width and r0 >= -1 and r0 < height:
                fx = gx - c0
                fy = gy - r0
                ci = int(c0) + 1
                ri = int(r0) + 1
                top = padded[ri, ci] + (padded[ri, ci + 1] - padded[ri, ci]) * fx
                bottom = padded[ri + 1, ci] + (padded[ri + 1, ci + 1] - padded[ri + 1, ci]) * fx
                d = min(abs(top + (bottom - top) * fy), max_dist)
            pz = z_hit * math.exp(-d * d * inv_two_sigma2) + z_rand_term
            total += math.log(pz) if product else pz * pz * pz
        out[i] = total
    return out
