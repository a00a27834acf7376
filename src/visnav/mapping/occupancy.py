"""Log-odds occupancy grid mapping from laser scans with known poses.

Each scan is ray traced in the map frame from the sensor origin: the cells a beam
passes through are observed free, the cell where a beam ends with a return is
observed occupied (a cell seen both ways in one scan counts as occupied), and each
observed cell is updated once per scan (OctoMap's rule)::

    L += log(p_hit / (1 - p_hit))    occupied
    L += log(p_miss / (1 - p_miss))  free
    L  = clip(L, logit(clamp_min), logit(clamp_max))

Beams with a return are those with ``range_min <= r < range_max``; with
``free_on_max_range`` a +inf or ``>= range_max`` reading clears along its ray up to
``min(range_max, max_free_range)`` without marking; NaN readings are ignored.
``max_usable_range`` is gmapping's ``maxUrange``: every beam is cropped to it, so a
return beyond it only clears space up to it; with ``far_clear_ratio`` r > 0 such a return
(and a no-return beam) clears up to r times its range instead (at least up to
``max_usable_range``), since the space well short of a far return is free even where the
return is too imprecise to place a wall. An RGB-D camera's depth error grows with
the square of the range (4 cm at 5 m for a Kinect v1, whose specified range ends at
4 m): walls mapped from far returns come out thick and a few cells off.

The published ``nav_msgs/OccupancyGrid`` follows map_server's trinary convention:
100 when ``p >= occupied_thresh`` (0.65), 0 when ``p <= free_thresh`` (0.196), -1
otherwise and for never-observed cells; with ``trinary=False`` observed cells carry
``round(100 p)``. Defaults are OctoMap's sensor model (0.7 / 0.4, clamped to
0.12 / 0.97).

The grid either has fixed bounds (rays leaving it are cut) or grows
(``grow=True``): when a scan reaches beyond it, it is enlarged to cover the scan plus
``grow_margin`` metres, keeping what was mapped.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from visnav.mapping._raytrace import trace_scan_cells
from visnav.mapping.errors import MappingError
from visnav.mapping.observation import ScanCache
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, LaserScan, MapMetaData, OccupancyGrid, Point, Pose, Quaternion

__all__ = ["OccupancyMapper", "logit"]


def logit(p: float) -> float:
    """``log(p / (1 - p))``."""
    return math.log(p / (1.0 - p))


class OccupancyMapper:
    """A growing or fixed log-odds occupancy grid.

    Args:
        resolution: metres per cell (0.05).
        width: initial width in metres (20).
        height: initial height in metres (20).
        origin_x: initial lower-left corner x (-10).
        origin_y: initial lower-left corner y (-10).
        grow: enlarge the grid when scans reach beyond it (True).
        grow_margin: metres added around a scan that does not fit (2.0).
        prob_hit: occupancy probability of a return (0.7).
        prob_miss: occupancy probability of a traversed cell (0.4).
        clamp_min: lowest probability kept (0.12).
        clamp_max: highest probability kept (0.97).
        occupied_thresh: published as occupied at or above (0.65).
        free_thresh: published as free at or below (0.196).
        free_on_max_range: clear along no-return beams (True).
        max_free_range: farthest clearing of a no-return beam, metres (5.0).
        max_usable_range: beams are cropped to this range, metres (inf: not cropped).
        far_clear_ratio: a return beyond ``max_usable_range`` clears this share of its
            range (0: up to ``max_usable_range`` only).

    Raises:
        MappingError: probabilities outside (0, 1) or in the wrong order, a bad size.
    """

    def __init__(
        self,
        *,
        resolution: float = 0.05,
        width: float = 20.0,
        height: float = 20.0,
        origin_x: float = -10.0,
        origin_y: float = -10.0,
        grow: bool = True,
        grow_margin: float = 2.0,
        prob_hit: float = 0.7,
        prob_miss: float = 0.4,
        clamp_min: float = 0.12,
        clamp_max: float = 0.97,
        occupied_thresh: float = 0.65,
        free_thresh: float = 0.196,
        free_on_max_range: bool = True,
        max_free_range: float = 5.0,
        max_usable_range: float = math.inf,
        far_clear_ratio: float = 0.0,
    ) -> None:
        for name, p in (
            ("prob_hit", prob_hit),
            ("prob_miss", prob_miss),
            ("clamp_min", clamp_min),
            ("clamp_max", clamp_max),
            ("occupied_thresh", occupied_thresh),
            ("free_thresh", free_thresh),
        ):
            if not 0.0 < p < 1.0:
                msg = f"occupancy mapper: {name} is {p}; expected a probability in (0, 1)"
                raise MappingError(msg)
        if not (
            prob_miss < 0.5 < prob_hit and clamp_min < clamp_max and free_thresh < occupied_thresh
        ):
            msg = (
                f"occupancy mapper: expected prob_miss < 0.5 < prob_hit ({prob_miss}, {prob_hit}), "
                f"clamp_min < clamp_max ({clamp_min}, {clamp_max}) and free_thresh < "
                f"occupied_thresh ({free_thresh}, {occupied_thresh})"
            )
            raise MappingError(msg)
        if not 0.0 <= far_clear_ratio < 1.0:
            msg = (
                f"occupancy mapper: far_clear_ratio is {far_clear_ratio}; expected a share in "
                "[0, 1) of a far return's range (0: clear only up to max_usable_range)"
            )
            raise MappingError(msg)
        if not max_usable_range > 0:
            msg = (
                f"occupancy mapper: max_usable_range is {max_usable_range}; expected a "
                "positive range in metres (inf: beams are not cropped)"
            )
            raise MappingError(msg)
        if not (resolution > 0 and width > 0 and height > 0):
            msg = (
                f"occupancy mapper: resolution {resolution}, size {width} x {height} m; "
                "expected positive values"
            )
            raise MappingError(msg)
        self.resolution = float(resolution)
        self.origin_x = float(origin_x)
        self.origin_y = float(origin_y)
        nx, ny = round(width / resolution), round(height / resolution)
        self.logodds: NDArray[np.float32] = np.zeros((ny, nx), np.float32)
        self.known: NDArray[np.bool_] = np.zeros((ny, nx), np.bool_)
        self._stamp: NDArray[np.int32] = np.zeros((ny, nx), np.int32)
        self._stamp_value = 2
        self.grow = grow
        self.grow_margin = float(grow_margin)
        self.l_hit = logit(prob_hit)
        self.l_miss = logit(prob_miss)
        self.l_min = logit(clamp_min)
        self.l_max = logit(clamp_max)
        self.occupied_thresh = occupied_thresh
        self.free_thresh = free_thresh
        self.free_on_max_range = free_on_max_range
        self.max_free_range = float(max_free_range)
        self.max_usable_range = float(max_usable_range)
        self.far_clear_ratio = float(far_clear_ratio)
        self.scans = 0
        self._cache = ScanCache()

    @property
    def size_x(self) -> int:
        """Cells along x."""
        return int(self.logodds.shape[1])

    @property
    def size_y(self) -> int:
        """Cells along y."""
        return int(self.logodds.shape[0])

    # ------------------------------------------------------------------ input
    def integrate_scan(self, msg: LaserScan, T_map_scan: NDArray[np.float64]) -> None:  # noqa: N803
        """Add one scan taken at the pose ``T_map_scan`` (4x4, the scan frame in the map)."""
        ranges = np.asarray(msg.ranges, dtype=np.float64)
        n = ranges.size
        c = self._cache
        key = (float(msg.angle_min), float(msg.angle_increment), n)
        if c.key != key:
            a = key[0] + np.arange(n) * key[1]
            c.key, c.cos, c.sin = key, np.cos(a), np.sin(a)
        rmin, rmax = float(msg.range_min), float(msg.range_max)
        usable = self.max_usable_range
        with np.errstate(invalid="ignore"):
            hit = (ranges >= rmin) & (ranges < min(rmax, usable))
            cropped = (ranges >= usable) & (ranges < rmax)
            nohit = (np.isposinf(ranges) | (ranges >= rmax)) & self.free_on_max_range
        use = hit | nohit | cropped
        free_len = min(rmax, self.max_free_range)
        if self.far_clear_ratio > 0:
            far = np.maximum(usable, self.far_clear_ratio * np.where(cropped, ranges, 0.0))
            clear = np.where(cropped, far, free_len)
        else:
            clear = np.where(cropped, usable, min(free_len, usable))
        r = np.where(hit, ranges, clear)[use]
        local = np.stack([r * c.cos[use], r * c.sin[use], np.zeros_like(r)], axis=1)
        world = local @ T_map_scan[:3, :3].T + T_map_scan[:3, 3]
        self.integrate_points(T_map_scan[:2, 3], world[:, :2], hit[use])

    def integrate_points(
        self, origin: NDArray[np.float64], ends: NDArray[np.float64], hits: NDArray[np.bool_]
    ) -> None:
        """Ray trace from ``origin`` (2,) to each of ``ends`` (N, 2); ``hits`` marks returns."""
        ends = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
        ox, oy = float(origin[0]), float(origin[1])
        if self.grow:
            self._fit(np.vstack([ends, [[ox, oy]]]))
        res = self.resolution
        cx = np.floor((ends[:, 0] - self.origin_x) / res).astype(np.int64)
        cy = np.floor((ends[:, 1] - self.origin_y) / res).astype(np.int64)
        x0 = math.floor((ox - self.origin_x) / res)
        y0 = math.floor((oy - self.origin_y) / res)
        self._stamp_value += 2
        if self._stamp_value > 2**30:
            self._stamp.fill(0)
            self._stamp_value = 2
        free, occ = trace_scan_cells(
            self._stamp,
            self._stamp_value,
            x0,
            y0,
            np.stack([cx, cy], axis=1),
            np.asarray(hits, dtype=np.bool_),
        )
        flat_stamp = self._stamp.reshape(-1)
        free = free[flat_stamp[free] == self._stamp_value]
        lo = self.logodds.reshape(-1)
        kn = self.known.reshape(-1)
        lo[free] = np.maximum(lo[free] + self.l_miss, self.l_min)
        lo[occ] = np.minimum(lo[occ] + self.l_hit, self.l_max)
        kn[free] = True
        kn[occ] = True
        self.scans += 1

    def clear(self) -> None:
        """Forget every observation (the extent stays; :attr:`scans` restarts at 0)."""
        self.logodds.fill(0.0)
        self.known.fill(False)
        self._stamp.fill(0)
        self._stamp_value = 2
        self.scans = 0

    def _fit(self, pts: NDArray[np.float64]) -> None:
        finite = pts[np.isfinite(pts).all(axis=1)]
        if len(finite) == 0:
            return
        res = self.resolution
        lo_x, lo_y = finite.min(axis=0)
        hi_x, hi_y = finite.max(axis=0)
        x_end = self.origin_x + self.size_x * res
        y_end = self.origin_y + self.size_y * res
        if lo_x >= self.origin_x and lo_y >= self.origin_y and hi_x < x_end and hi_y < y_end:
            return
        m = self.grow_margin
        new_ox = self.origin_x - res * math.ceil(max(0.0, self.origin_x - (lo_x - m)) / res)
        new_oy = self.origin_y - res * math.ceil(max(0.0, self.origin_y - (lo_y - m)) / res)
        new_xe = x_end + res * math.ceil(max(0.0, hi_x + m - x_end) / res)
        new_ye = y_end + res * math.ceil(max(0.0, hi_y + m - y_end) / res)
        nx = round((new_xe - new_ox) / res)
        ny = round((new_ye - new_oy) / res)
        dx = round((self.origin_x - new_ox) / res)
        dy = round((self.origin_y - new_oy) / res)
        lo = np.zeros((ny, nx), np.float32)
        kn = np.zeros((ny, nx), np.bool_)
        lo[dy : dy + self.size_y, dx : dx + self.size_x] = self.logodds
        kn[dy : dy + self.size_y, dx : dx + self.size_x] = self.known
        self.logodds, self.known = lo, kn
        self._stamp = np.zeros((ny, nx), np.int32)
        self._stamp_value = 2
        self.origin_x, self.origin_y = new_ox, new_oy

    # ------------------------------------------------------------------ output
    def probabilities(self) -> NDArray[np.float64]:
        """Occupancy probability per cell (0.5 where never observed)."""
        return 1.0 - 1.0 / (1.0 + np.exp(self.logodds.astype(np.float64)))

    def occupancy_values(self, *, trinary: bool = True) -> NDArray[np.int8]:
        """The OccupancyGrid data array (H, W): -1 / 0 / 100 (or 0..100)."""
        p = self.probabilities()
        if trinary:
            out = np.full(p.shape, -1, np.int8)
            out[p >= self.occupied_thresh] = 100
            out[p <= self.free_thresh] = 0
        else:
            out = np.rint(p * 100).astype(np.int8)
        out[~self.known] = -1
        return out

    def to_occupancy_grid(
        self, frame_id: str = "map", stamp_ns: int = 0, *, trinary: bool = True
    ) -> OccupancyGrid:
        """The map as ``nav_msgs/OccupancyGrid``."""
        stamp = ns_to_time(stamp_ns)
        info = MapMetaData(
            map_load_time=stamp,
            resolution=self.resolution,
            width=self.size_x,
            height=self.size_y,
            origin=Pose(
                position=Point(x=self.origin_x, y=self.origin_y, z=0.0),
                orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        data = self.occupancy_values(trinary=trinary).reshape(-1)
        return OccupancyGrid(header=Header(stamp=stamp, frame_id=frame_id), info=info, data=data)
