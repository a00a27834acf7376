"""The SLAM map: keyframes, map points, observations and the covisibility graph.

Map points live in growable numpy arrays (position, descriptor, viewing
direction, counters) so tracking can project thousands of them at once; their
observations (keyframe -> keypoint index) are small dicts. A keyframe keeps its
frame's keypoints and, per keypoint, the map point it observes (-1: none).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from visnav.slam.features import DescArray, Frame, hamming_matrix
from visnav.slam.geometry import inverse

__all__ = [
    "Keyframe",
    "SlamMap",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass
class Keyframe:
    """A keyframe: a frame kept in the map with its pose and observations.

    Attributes:
        id: index in :attr:`SlamMap.keyframes`.
        frame: keypoints, descriptors, depth; ``frame.map_points`` are its observations.
        t_cw: world -> camera pose.
        parent: spanning-tree parent keyframe id (-1 for the first).
        connections: covisibility weights (other keyframe id -> shared map points).
        loop_edges: keyframe ids this one closed a loop with.
        bow: the bag-of-words vector (None before the vocabulary exists).
        cloud: sub-sampled camera-frame points and colours for the dense cloud.
        odom_pose: ``T_odom_camera`` from the robot's odometry at the keyframe's time
            (None without odometry): local bundle adjustment links consecutive
            keyframes by the odometry's motion between them.
    """

    id: int
    frame: Frame
    t_cw: FloatArray
    parent: int = -1
    connections: dict[int, int] = field(default_factory=dict)
    loop_edges: set[int] = field(default_factory=set)
    bow: NDArray[np.float32] | None = None
    cloud: tuple[NDArray[np.float32], NDArray[np.uint8]] | None = None
    bad: bool = False
    odom_pose: FloatArray | None = None

    @property
    def t_wc(self) -> FloatArray:
        """Camera pose in the world (map) frame."""
        return inverse(self.t_cw)

    @property
    def stamp_ns(self) -> int:
        """Capture time of the keyframe."""
        return self.frame.stamp_ns

    def best_covisibles(self, n: int, *, min_weight: int = 1) -> list[int]:
        """Return up to ``n`` neighbour ids by decreasing shared points (ties: lower id)."""
        items = [(w, k) for k, w in self.connections.items() if w >= min_weight]
        items.sort(key=lambda wk: (-wk[0], wk[1]))
        return [k for _, k in items[:n]]


class SlamMap:
    """Keyframes and map points with their observations."""

    def __init__(self) -> None:
        self.keyframes: list[Keyframe] = []
        self._n = 0
        cap = 1024
        self.positions = np.zeros((cap, 3))
        self.descriptors = np.zeros((cap, 32), dtype=np.uint8)
        self.normals = np.zeros((cap, 3))
        self.ref_kf = np.zeros(cap, dtype=np.int64)
        self.first_kf = np.zeros(cap, dtype=np.int64)
        self.visible = np.zeros(cap, dtype=np.int64)
        self.found = np.zeros(cap, dtype=np.int64)
        self.bad = np.zeros(cap, dtype=bool)
        self.observations: list[dict[int, int]] = []

    # ----------------------------------------------------------------- points

    @property
    def n_points(self) -> int:
        """Number of map points ever created (including bad ones)."""
        return self._n

    def good_points(self) -> IntArray:
        """Ids of the map points not culled."""
        return np.flatnonzero(~self.bad[: self._n])

    def _grow(self, extra: int) -> None:
        need = self._n + extra
        cap = len(self.positions)
        if need <= cap:
            return
        new = max(need, cap * 2)
        for name in (
            "positions",
            "descriptors",
            "normals",
            "ref_kf",
            "first_kf",
            "visible",
            "found",
            "bad",
        ):
            old = getattr(self, name)
            arr = np.zeros((new, *old.shape[1:]), dtype=old.dtype)
            arr[:cap] = old
            setattr(self, name, arr)

    def add_points(
        self, positions: FloatArray, descriptors: DescArray, kf: Keyframe, kp_indices: IntArray
    ) -> IntArray:
        """Create map points observed by ``kf`` at ``kp_indices``; return their ids."""
        m = len(positions)
        self._grow(m)
        ids = np.arange(self._n, self._n + m, dtype=np.int64)
        self.positions[ids] = positions
        self.descriptors[ids] = descriptors
        centre = kf.t_wc[:3, 3]
        d = positions - centre
        self.normals[ids] = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
        self.ref_kf[ids] = kf.id
        self.first_kf[ids] = kf.id
        self.visible[ids] = 1
        self.found[ids] = 1
        self.bad[ids] = False
        self._n += m
        for kp in kp_indices.tolist():
            self.observations.append({kf.id: int(kp)})
        kf.frame.map_points[kp_indices] = ids
        return ids

    def add_observation(self, point: int, kf: Keyframe, kp: int) -> None:
        """Record that keypoint ``kp`` of ``kf`` observes ``point``."""
        self.observations[point][kf.id] = kp
        kf.frame.map_points[kp] = point

    def erase_observation(self, point: int, kf_id: int) -> None:
        """Remove one observation; a point left with none is culled."""
        obs = self.observations[point]
        kp = obs.pop(kf_id, None)
        if kp is not None:
            kf = self.keyframes[kf_id]
            if kf.frame.map_points[kp] == point:
                kf.frame.map_points[kp] = -1
        if not obs:
            self.bad[point] = True
        elif self.ref_kf[point] == kf_id:
            self.ref_kf[point] = min(obs)

    def cull_point(self, point: int) -> None:
        """Mark a point bad and remove it from all keyframes."""
        for kf_id, kp in self.observations[point].items():
            kf = self.keyframes[kf_id]
            if kf.frame.map_points[kp] == point:
                kf.frame.map_points[kp] = -1
        self.observations[point] = {}
        self.bad[point] = True

    def replace_point(self, old: int, new: int) -> None:
        """Merge point ``old`` into ``new`` (observations move; ``old`` becomes bad)."""
        if old == new or self.bad[old] or self.bad[new]:
            return
        for kf_id, kp in list(self.observations[old].items()):
            kf = self.keyframes[kf_id]
            if kf_id in self.observations[new]:
                if kf.frame.map_points[kp] == old:
                    kf.frame.map_points[kp] = -1
            else:
                self.observations[new][kf_id] = kp
                kf.frame.map_points[kp] = new
        self.visible[new] += self.visible[old]
        self.found[new] += self.found[old]
        self.observations[old] = {}
        self.bad[old] = True

    def update_point_descriptors(self, points: IntArray) -> None:
        """Set each point's descriptor to its most representative observation's.

        The medoid: the observed descriptor with the smallest median Hamming distance
        to the others (ORB-SLAM's distinctive descriptor).
        """
        for p in points.tolist():
            obs = self.observations[p]
            if len(obs) < 3 or self.bad[p]:
                continue
            descs = np.stack(
                [self.keyframes[k].frame.descriptors[i] for k, i in sorted(obs.items())]
            )
            dmat = hamming_matrix(descs, descs)
            self.descriptors[p] = descs[int(np.argmin(np.median(dmat, axis=1)))]

    def observation_arrays(self, points: IntArray) -> tuple[IntArray, IntArray, IntArray]:
        """Flatten the observations of ``points``: ``(point, keyframe, keypoint)`` arrays."""
        p_list: list[int] = []
        k_list: list[int] = []
        i_list: list[int] = []
        for p in points.tolist():
            obs = self.observations[p]
            p_list.extend([p] * len(obs))
            k_list.extend(obs.keys())
            i_list.extend(obs.values())
        return (
            np.asarray(p_list, dtype=np.int64),
            np.asarray(k_list, dtype=np.int64),
            np.asarray(i_list, dtype=np.int64),
        )

    def camera_centres(self) -> FloatArray:
        """(K, 3) camera centres of all keyframes in the world frame."""
        if not self.keyframes:
            return np.zeros((0, 3))
        poses = np.stack([kf.t_cw for kf in self.keyframes])
        centres: FloatArray = -np.einsum("kji,kj->ki", poses[:, :3, :3], poses[:, :3, 3])
        return centres

    def update_point_normals(self, points: IntArray) -> None:
        """Recompute the mean viewing direction of points from their observations."""
        pts = points[~self.bad[points]] if len(points) else points
        if len(pts) == 0:
            return
        pp, kk, _ = self.observation_arrays(pts)
        if len(pp) == 0:
            return
        d = self.positions[pp] - self.camera_centres()[kk]
        d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
        uniq, inv = np.unique(pp, return_inverse=True)
        sums = np.zeros((len(uniq), 3))
        for axis in range(3):
            sums[:, axis] = np.bincount(inv.reshape(-1), weights=d[:, axis], minlength=len(uniq))
        norms = np.maximum(np.linalg.norm(sums, axis=1, keepdims=True), 1e-9)
        self.normals[uniq] = sums / norms

    # -------------------------------------------------------------- keyframes

    def add_keyframe(self, frame: Frame, t_cw: FloatArray, *, parent: int) -> Keyframe:
        """Append a keyframe (its map point observations are added by the caller)."""
        kf = Keyframe(id=len(self.keyframes), frame=frame, t_cw=t_cw.copy(), parent=parent)
        self.keyframes.append(kf)
        return kf

    def keyframe_points(self, kf: Keyframe) -> tuple[IntArray, IntArray]:
        """Return ``(keypoint_index, point_id)`` of a keyframe's good observations."""
        mp = kf.frame.map_points
        kp = np.flatnonzero(mp >= 0)
        pts = mp[kp]
        good = ~self.bad[pts]
        return kp[good], pts[good]

    def update_connections(self, kf: Keyframe) -> None:
        """Recompute ``kf``'s covisibility weights and mirror them on its neighbours."""
        _, pts = self.keyframe_points(kf)
        counts: dict[int, int] = {}
        for p in pts.tolist():
            for other in self.observations[p]:
                if other != kf.id:
                    counts[other] = counts.get(other, 0) + 1
        for other in list(kf.connections):
            if other not in counts:
                self.keyframes[other].connections.pop(kf.id, None)
        kf.connections = counts
        for other, w in counts.items():
            self.keyframes[other].connections[kf.id] = w

    def local_points(self, kf_ids: list[int]) -> IntArray:
        """Unique good map point ids observed by the given keyframes."""
        if not kf_ids:
            return np.zeros(0, dtype=np.int64)
        arrays = [self.keyframes[k].frame.map_points for k in kf_ids]
        pts = np.unique(np.concatenate(arrays))
        pts = pts[pts >= 0]
        return pts[~self.bad[pts]]

    def point_cloud(self, *, min_observations: int = 2) -> FloatArray:
        """Return (N, 3) positions of good points with enough observations."""
        ids = self.good_points()
        keep = [p for p in ids.tolist() if len(self.observations[p]) >= min_observations]
        out: FloatArray = self.positions[np.asarray(keep, dtype=np.int64)].copy()
        return out
