"""gmapping's Rao-Blackwellised particle filter (OpenSLAM GMapping's ``GridSlamProcessor``).

Every scan moves each particle by the odometry increment with gmapping's motion noise
(``srr``, ``srt``, ``str``, ``stt``). A scan is *processed* when the robot has moved
``linearUpdate`` / turned ``angularUpdate`` since the last processed one, or after
``temporalUpdate`` seconds (the first scan always is). Processing:

1. improved proposal: each particle's pose is scan-matched in its own map
   (hill climbing, :func:`~visnav.mapping.gmapping._scan_kernels.optimize`) and kept when the
   score exceeds ``minimumScore``;
2. the weight (a log) grows by the scan's log likelihood at that pose;
3. weights are normalised with gain ``1 / (ogain * N)`` and ``Neff = 1 / sum(w^2)``;
   when ``Neff < resampleThreshold * N`` the particles are resampled (systematic, one
   uniform draw) and their weights reset;
4. each particle adds the scan's endpoints to its map (copy-on-write patches).

Each processed scan also adds one node per particle to a trajectory tree (parent, pose,
scan), so :meth:`GmappingFilter.build_map` can replay the best particle's path with
free-space ray tracing, as slam_gmapping's ``updateMap`` does.

Randomness: one ``numpy.random.Generator(PCG64(seed))``; the same scans and seed give
the same particles and map, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.gmapping import _kernels as k
from visnav.mapping.gmapping import _scan_kernels as sk
from visnav.mapping.gmapping.maps import ParticleMaps
from visnav.mapping.gmapping.params import GmappingError, GmappingParams

__all__ = ["GmappingFilter", "GridMap", "LaserGeometry"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class LaserGeometry:
    """The laser as the filter sees it, in the robot's base frame.

    Attributes:
        x: Laser origin x in the base frame (m).
        y: Laser origin y (m).
        angles: (B,) beam directions in the base frame (rad), in scan order.
        max_range: gmapping's ``maxRange``: beams beyond it are no returns (m).
        usable_range: gmapping's ``maxUrange``: beams are used (or clipped) to it (m).
    """

    x: float
    y: float
    angles: F64
    max_range: float
    usable_range: float


@dataclass(frozen=True)
class GridMap:
    """The map of one particle as gmapping publishes it.

    Attributes:
        data: (H, W) int8 ``[y, x]``: 100 occupied, 0 free, -1 unknown.
        values: (H, W) float64 hit ratios (-1 unknown).
        origin: World ``(x, y)`` of cell ``(0, 0)``'s corner (m).
        resolution: Cell size (m).
    """

    data: NDArray[np.int8]
    values: F64
    origin: tuple[float, float]
    resolution: float


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def _relative(new: F64, old: F64) -> F64:
    """gmapping's ``absoluteDifference``: ``new`` in ``old``'s frame."""
    dx, dy = new[0] - old[0], new[1] - old[1]
    c, s = math.cos(old[2]), math.sin(old[2])
    return np.array([c * dx + s * dy, -s * dx + c * dy, _wrap(new[2] - old[2])])


class GmappingFilter:
    """gmapping's filter on one laser (module docstring).

    Args:
        params: The filter's parameters.
        laser: The laser's geometry in the base frame.
        initial_pose: ``(x, y, theta)`` of every particle at the start (slam_gmapping: the
            odometry pose of the first scan, so ``map -> odom`` starts as identity).
    """

    def __init__(
        self,
        params: GmappingParams,
        laser: LaserGeometry,
        *,
        initial_pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        if laser.usable_range <= 0 or laser.max_range <= 0:
            msg = (
                f"gmapping: maxRange {laser.max_range} / maxUrange {laser.usable_range} m; "
                "expected > 0. Fix: set maxRange and maxUrange, or send scans with range_max"
            )
            raise GmappingError(msg)
        self.params = params
        self.laser = laser
        self._laser = np.array([laser.x, laser.y, 0.0])
        self._angles = np.ascontiguousarray(laser.angles, dtype=np.float64)
        n = params.particles
        self.rng = np.random.Generator(np.random.PCG64(params.seed))
        self.poses = np.tile(np.asarray(initial_pose, dtype=np.float64), (n, 1))
        self.weights = np.zeros(n)  # log weights since the last resampling
        self.weight_sums = np.zeros(n)  # accumulated log weights (best particle)
        self.normalized = np.full(n, 1.0 / n)
        self.neff = float(n)
        self.maps = ParticleMaps(
            n, params.delta, (params.xmin, params.ymin, params.xmax, params.ymax)
        )
        self.count = 0  # processed scans
        self.readings_seen = 0
        self.resamples = 0
        self.last_scores = np.zeros(n)
        self._odom: F64 | None = None
        self._linear = 0.0
        self._angular = 0.0
        self._last_time = -math.inf
        # trajectory tree: one node per particle and processed scan (capacity doubles)
        self._nodes = 0
        self._node_parent = np.empty(64 * n, np.int64)
        self._node_pose = np.empty((64 * n, 3))
        self._node_reading = np.empty(64 * n, np.int64)
        self._particle_node = np.full(n, -1, np.int64)
        self._readings = np.empty((64, self._angles.shape[0]))

    # ---------------------------------------------------------------- motion
    def _draw_motion(self, new: F64, old: F64) -> None:
        """gmapping's ``MotionModel::drawFromMotion`` for every particle."""
        p = self.params
        d = _relative(new, old)
        noise = self.rng.standard_normal((self.poses.shape[0], 3))
        sxy = 0.3 * p.srr
        ax, ay, at = abs(d[0]), abs(d[1]), abs(d[2])
        sig = np.array(
            [
                p.srr * ax + p.str * at + sxy * ay,
                p.srr * ay + p.str * at + sxy * ax,
                p.stt * at + p.srt * math.hypot(d[0], d[1]),
            ]
        )
        moves = d[None, :] + noise * sig[None, :]
        th = self.poses[:, 2]
        c, s = np.cos(th), np.sin(th)
        self.poses[:, 0] += c * moves[:, 0] - s * moves[:, 1]
        self.poses[:, 1] += s * moves[:, 0] + c * moves[:, 1]
        self.poses[:, 2] = np.arctan2(np.sin(th + moves[:, 2]), np.cos(th + moves[:, 2]))

    # ---------------------------------------------------------------- scans
    def process_scan(
        self, odom_pose: tuple[float, float, float], ranges: NDArray[np.floating], time_s: float
    ) -> bool:
        """Feed one scan with its odometry pose; True when it was processed (module docstring).

        Args:
            odom_pose: ``(x, y, theta)`` of the base in the odometry frame at the scan.
            ranges: (B,) ranges in scan order; inf / NaN: no return.
            time_s: The scan's time (s), for ``temporalUpdate``.

        Raises:
            GmappingError: ``ranges`` does not have one range per beam.
        """
        r = np.asarray(ranges, dtype=np.float64)
        if r.shape != self._angles.shape:
            msg = (
                f"gmapping: scan has {r.size} ranges, the laser {self._angles.size} beams; "
                "expected the same laser on every scan. Fix: one gmapping node per laser"
            )
            raise GmappingError(msg)
        r = np.where(np.isnan(r), np.inf, r)
        odom = np.asarray(odom_pose, dtype=np.float64)
        if self._odom is None:
            self._odom = odom.copy()
        self._draw_motion(odom, self._odom)
        move = odom - self._odom
        self._linear += math.hypot(move[0], move[1])
        self._angular += abs(_wrap(move[2]))
        self._odom = odom.copy()
        self.readings_seen += 1
        p = self.params
        due = (
            self.count == 0
            or self._linear >= p.linearUpdate
            or self._angular >= p.angularUpdate
            or (p.temporalUpdate >= 0.0 and time_s - self._last_time > p.temporalUpdate)
        )
        if not due:
            return False
        self._last_time = time_s
        if self.count > 0:
            self._scan_match(r)
            self._normalize()
            self._resample()
        self._register(r)
        self._normalize()
        self._linear = 0.0
        self._angular = 0.0
        self.count += 1
        return True

    def _scan_match(self, ranges: F64) -> None:
        p, m, lz = self.params, self.maps, self.laser
        out = np.empty_like(self.poses)
        scores = np.empty(self.poses.shape[0])
        like = np.empty(self.poses.shape[0])
        sk.scan_match_all(
            m.tables, m.accx, m.accy, m.hits, m.visits, self.poses, ranges, self._angles,
            self._laser, lz.usable_range, p.sigma, p.lsigma, p.delta, m.cx0, m.cy0,
            p.kernelSize, p.lskip, p.lstep, p.astep, p.iterations, p.minimumScore,
            out, scores, like,
        )  # fmt: skip
        self.poses = out
        self.last_scores = scores
        self.weights += like
        self.weight_sums += like

    def _normalize(self) -> None:
        """gmapping's ``normalize``: smoothed weights and the effective sample size."""
        n = self.weights.shape[0]
        gain = 1.0 / (self.params.ogain * n)
        w = np.exp(gain * (self.weights - self.weights.max()))
        w /= w.sum()
        self.normalized = w
        self.neff = float(1.0 / np.sum(w * w))

    def _resample(self) -> None:
        n = self.weights.shape[0]
        if self.neff >= self.params.resampleThreshold * n:
            return
        cum = np.cumsum(self.normalized)
        targets = (self.rng.random() + np.arange(n)) * (cum[-1] / n)
        idx = np.minimum(np.searchsorted(cum, targets, side="right"), n - 1).astype(np.int64)
        self.poses = self.poses[idx].copy()
        self.weight_sums = self.weight_sums[idx].copy()
        self.weights = np.zeros(n)
        self._particle_node = self._particle_node[idx].copy()
        self.maps.resample(idx)
        self.resamples += 1

    def _register(self, ranges: F64) -> None:
        lz = self.laser
        self.maps.register(
            self.poses, ranges, self._angles, self._laser, min(lz.max_range, lz.usable_range)
        )
        n = self.poses.shape[0]
        step = self.count
        if step == self._readings.shape[0]:
            self._readings = np.concatenate([self._readings, np.empty_like(self._readings)])
        self._readings[step] = ranges
        first = self._nodes
        if first + n > self._node_parent.shape[0]:
            self._node_parent = np.concatenate([self._node_parent, self._node_parent])
            self._node_pose = np.concatenate([self._node_pose, self._node_pose])
            self._node_reading = np.concatenate([self._node_reading, self._node_reading])
        self._node_parent[first : first + n] = self._particle_node
        self._node_pose[first : first + n] = self.poses
        self._node_reading[first : first + n] = step
        self._nodes = first + n
        self._particle_node = np.arange(first, first + n, dtype=np.int64)

    # ---------------------------------------------------------------- outputs
    @property
    def best_index(self) -> int:
        """The particle with the highest accumulated log weight (gmapping's best particle)."""
        return int(np.argmax(self.weight_sums))

    @property
    def best_pose(self) -> tuple[float, float, float]:
        """The best particle's base pose in the map frame."""
        x, y, t = self.poses[self.best_index]
        return float(x), float(y), float(t)

    def entropy(self) -> float:
        """Entropy of the normalised particle weights (nats)."""
        w = self.normalized[self.normalized > 0]
        return float(-np.sum(w * np.log(w)))

    def map_to_odom(self) -> tuple[float, float, float]:
        """``map -> odom`` from the best particle and the last odometry pose."""
        if self._odom is None:
            return 0.0, 0.0, 0.0
        bx, by, bt = self.best_pose
        ox, oy, ot = (float(v) for v in self._odom)
        t = _wrap(bt - ot)
        c, s = math.cos(t), math.sin(t)
        return bx - (c * ox - s * oy), by - (s * ox + c * oy), t

    def trajectory(self, particle: int | None = None) -> F64:
        """(K, 3) poses of a particle's processed scans, oldest first (default: best)."""
        nodes = self._path_nodes(self.best_index if particle is None else particle)
        out: F64 = self._node_pose[nodes].copy()
        return out

    def _path_nodes(self, particle: int) -> NDArray[np.int64]:
        node = int(self._particle_node[particle])
        path: list[int] = []
        while node >= 0:
            path.append(node)
            node = int(self._node_parent[node])
        return np.asarray(path[::-1], dtype=np.int64)

    def build_map(self, particle: int | None = None) -> GridMap:
        """slam_gmapping's ``updateMap``: replay a particle's path with free-space tracing.

        The grid covers ``xmin..xmax`` x ``ymin..ymax`` and grows to every cell a replayed
        beam reaches. A cell is occupied when its hit ratio exceeds ``occ_thresh``, free
        when it was seen below it, unknown when never seen.
        """
        p, lz = self.params, self.laser
        nodes = self._path_nodes(self.best_index if particle is None else particle)
        poses = np.ascontiguousarray(self._node_pose[nodes])
        ids = np.ascontiguousarray(self._node_reading[nodes])
        d = p.delta
        gx0, gy0 = math.floor(p.xmin / d), math.floor(p.ymin / d)
        gx1, gy1 = math.ceil(p.xmax / d) - 1, math.ceil(p.ymax / d) - 1
        if nodes.size:
            reach = min(lz.usable_range, lz.max_range)
            ox = poses[:, 0] + np.cos(poses[:, 2]) * lz.x - np.sin(poses[:, 2]) * lz.y
            oy = poses[:, 1] + np.sin(poses[:, 2]) * lz.x + np.cos(poses[:, 2]) * lz.y
            gx0 = min(gx0, math.floor((ox.min() - reach) / d))
            gy0 = min(gy0, math.floor((oy.min() - reach) / d))
            gx1 = max(gx1, math.floor((ox.max() + reach) / d))
            gy1 = max(gy1, math.floor((oy.max() + reach) / d))
        hits = np.zeros((gy1 - gy0 + 1, gx1 - gx0 + 1), np.int32)
        visits = np.zeros_like(hits)
        k.replay_scans(
            hits, visits, poses, self._readings, ids, self._angles, self._laser,
            lz.max_range, lz.usable_range, d, gx0, gy0,
        )  # fmt: skip
        values = np.where(visits > 0, hits / np.maximum(visits, 1), -1.0)
        data = np.where(values > p.occ_thresh, 100, np.where(values >= 0, 0, -1)).astype(np.int8)
        return GridMap(data=data, values=values, origin=(gx0 * d, gy0 * d), resolution=d)
