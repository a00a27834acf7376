"""Per-particle occupancy maps that share memory: patch tables over one copy-on-write pool.

gmapping's ``ScanMatcherMap`` stores each particle's map as reference-counted patches,
so that the particles made from one parent by resampling share its map until they write
to it. :class:`ParticleMaps` does the same with numpy arrays: ``tables[p]`` maps a
patch position to a pool id; :meth:`resample` copies tables (not cells) and recounts the
references; the numba kernels copy a shared patch on its first write.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.gmapping import _kernels as k

__all__ = ["ParticleMaps"]


class ParticleMaps:
    """The particles' maps on a global cell grid of ``delta`` metres.

    Args:
        particles: Number of maps.
        delta: Cell size (m).
        bounds: Initial ``(xmin, ymin, xmax, ymax)`` in metres; the maps grow by whole
            patches when a scan reaches beyond them (gmapping's map resize).
    """

    def __init__(
        self, particles: int, delta: float, bounds: tuple[float, float, float, float]
    ) -> None:
        self.delta = float(delta)
        xmin, ymin, xmax, ymax = bounds
        gx0, gy0 = math.floor(xmin / delta), math.floor(ymin / delta)
        pw = max(1, -(-(math.ceil(xmax / delta) - gx0) // k.PATCH))
        ph = max(1, -(-(math.ceil(ymax / delta) - gy0) // k.PATCH))
        self.cx0, self.cy0 = int(gx0), int(gy0)
        self.tables = np.full((particles, ph, pw), -1, np.int32)
        cap = 64
        cells = k.PATCH * k.PATCH
        self.accx = np.zeros((cap, cells), np.float64)
        self.accy = np.zeros((cap, cells), np.float64)
        self.hits = np.zeros((cap, cells), np.int32)
        self.visits = np.zeros((cap, cells), np.int32)
        self.refcount = np.zeros(cap, np.int32)
        self.free = np.arange(cap - 1, -1, -1, dtype=np.int32)
        self.free_top = np.array([cap], np.int64)

    @property
    def particles(self) -> int:
        """Number of particle maps."""
        return int(self.tables.shape[0])

    @property
    def capacity(self) -> int:
        """Patches the pool holds (used or free)."""
        return int(self.refcount.shape[0])

    @property
    def patches_in_use(self) -> int:
        """Distinct patches referenced by some particle."""
        return int(np.count_nonzero(self.refcount))

    @property
    def nbytes(self) -> int:
        """Bytes of the pool and the tables."""
        arrays = (self.accx, self.accy, self.hits, self.visits, self.refcount, self.tables)
        return int(sum(a.nbytes for a in arrays))

    def cell_origin(self) -> tuple[int, int]:
        """The global cell of table cell ``(0, 0)``."""
        return self.cx0, self.cy0

    # ---------------------------------------------------------------- growth
    def ensure_cells(self, gxmin: int, gymin: int, gxmax: int, gymax: int) -> None:
        """Grow the tables by whole patches so the global cells in the box are inside."""
        _, ph, pw = self.tables.shape
        p = k.PATCH
        left = max(0, -(-(self.cx0 - gxmin) // p))
        below = max(0, -(-(self.cy0 - gymin) // p))
        right = max(0, -(-(gxmax + 1 - (self.cx0 + pw * p)) // p))
        above = max(0, -(-(gymax + 1 - (self.cy0 + ph * p)) // p))
        if left == below == right == above == 0:
            return
        grown = np.full((self.particles, ph + below + above, pw + left + right), -1, np.int32)
        grown[:, below : below + ph, left : left + pw] = self.tables
        self.tables = grown
        self.cx0 -= left * p
        self.cy0 -= below * p

    def reserve(self, count: int) -> None:
        """Make sure ``count`` patch ids are free (the pool doubles as needed)."""
        free = int(self.free_top[0])
        if free >= count:
            return
        cap = self.capacity
        new_cap = max(2 * cap, cap + count - free)
        extra = new_cap - cap
        cells = k.PATCH * k.PATCH
        self.accx = np.concatenate([self.accx, np.zeros((extra, cells))])
        self.accy = np.concatenate([self.accy, np.zeros((extra, cells))])
        self.hits = np.concatenate([self.hits, np.zeros((extra, cells), np.int32)])
        self.visits = np.concatenate([self.visits, np.zeros((extra, cells), np.int32)])
        self.refcount = np.concatenate([self.refcount, np.zeros(extra, np.int32)])
        new_ids = np.arange(new_cap - 1, cap - 1, -1, dtype=np.int32)
        self.free = np.concatenate([new_ids, self.free[:free]])
        self.free_top[0] = self.free.shape[0]

    # ---------------------------------------------------------------- updates
    def register(
        self,
        poses: NDArray[np.float64],
        ranges: NDArray[np.float64],
        angles: NDArray[np.float64],
        laser: NDArray[np.float64],
        limit: float,
    ) -> None:
        """Add each particle's scan endpoints (ranges <= ``limit``) as hits to its map."""
        points = k.hit_points(poses, ranges, angles, laser, limit)
        gx0, gy0, gx1, gy1, n = k.hit_cell_bounds(poses, points, laser, self.delta)
        if n == 0:
            return
        self.ensure_cells(gx0, gy0, gx1, gy1)
        need = k.count_new_patches(
            self.tables, self.refcount, points, self.delta, self.cx0, self.cy0
        )
        self.reserve(need)
        k.register_hits(
            self.tables, self.accx, self.accy, self.hits, self.visits, self.refcount,
            self.free, self.free_top, points, self.delta, self.cx0, self.cy0,
        )  # fmt: skip

    def resample(self, indexes: NDArray[np.int64]) -> None:
        """Particle ``i`` takes the map of particle ``indexes[i]`` (shared, copy-on-write)."""
        self.tables = np.ascontiguousarray(self.tables[indexes])
        used = self.tables[self.tables >= 0]
        self.refcount = np.bincount(used, minlength=self.capacity).astype(np.int32)
        unused = np.flatnonzero(self.refcount == 0).astype(np.int32)[::-1]
        self.free = np.ascontiguousarray(unused)
        self.free_top[0] = unused.shape[0]

    def values(self, particle: int) -> tuple[NDArray[np.float64], tuple[int, int]]:
        """Particle ``particle``'s dense cell values ``[y, x]`` (-1 unknown) and origin cell."""
        table = self.tables[particle]
        ph, pw = table.shape
        p = k.PATCH
        out = np.full((ph * p, pw * p), -1.0)
        for py, px in zip(*np.nonzero(table >= 0), strict=True):
            pid = table[py, px]
            v = self.visits[pid].reshape(p, p).astype(np.float64)
            n = self.hits[pid].reshape(p, p)
            block = np.where(v > 0, n / np.maximum(v, 1.0), -1.0)
            out[py * p : (py + 1) * p, px * p : (px + 1) * p] = block
        return out, (self.cx0, self.cy0)
