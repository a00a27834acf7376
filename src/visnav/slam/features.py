"""ORB features of one RGB-D frame and descriptor distances.

:class:`OrbExtractor` wraps OpenCV's ORB (FAST corners on an image pyramid with
rotated BRIEF descriptors) and spreads the keypoints over the image: it detects
more corners than needed and keeps the strongest per grid cell, so textured
corners do not take the whole budget (ORB-SLAM distributes with a quadtree for
the same reason). :class:`Frame` holds a frame's keypoints, descriptors and the
depth sampled at each keypoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics

__all__ = [
    "Frame",
    "OrbExtractor",
    "hamming",
    "hamming_matrix",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
DescArray = NDArray[np.uint8]

_POPCOUNT = np.array([bin(i).count("1") for i in range(256)], dtype=np.uint8)


def hamming(a: DescArray, b: DescArray) -> NDArray[np.int32]:
    """Row-wise Hamming distances of two (N, 32) uint8 descriptor arrays."""
    x = np.bitwise_xor(a, b)
    if hasattr(np, "bitwise_count"):
        counts = np.bitwise_count(x.view(np.uint64) if x.shape[1] % 8 == 0 else x)
        out: NDArray[np.int32] = counts.sum(axis=1, dtype=np.int32)
        return out
    fallback: NDArray[np.int32] = _POPCOUNT[x].sum(axis=1, dtype=np.int32)  # pragma: no cover
    return fallback  # pragma: no cover - numpy < 2


def hamming_matrix(a: DescArray, b: DescArray) -> NDArray[np.int32]:
    """All (len(a), len(b)) Hamming distances (for small sets)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros((len(a), len(b)), dtype=np.int32)
    x = np.bitwise_xor(a[:, None, :], b[None, :, :])
    if hasattr(np, "bitwise_count"):
        out: NDArray[np.int32] = np.bitwise_count(x).sum(axis=2, dtype=np.int32)
        return out
    fallback: NDArray[np.int32] = _POPCOUNT[x].sum(axis=2, dtype=np.int32)  # pragma: no cover
    return fallback  # pragma: no cover - numpy < 2


@dataclass
class Frame:
    """Keypoints of one RGB-D frame.

    Attributes:
        stamp_ns: capture time.
        uv: (N, 2) keypoint pixels.
        octave: (N,) pyramid level of each keypoint.
        descriptors: (N, 32) ORB descriptors.
        depth: (N,) metres at each keypoint (NaN: none).
        u_right: (N,) virtual right-image u, ``u - bf / depth`` (NaN: no depth).
        points_c: (N, 3) back-projected points in the camera frame (NaN: no depth).
        inv_sigma2: (N,) ``1 / scale(octave)^2``.
        map_points: (N,) map point id matched to each keypoint (-1: none).
        t_cw: world -> camera pose once tracked.
    """

    stamp_ns: int
    uv: FloatArray
    octave: IntArray
    descriptors: DescArray
    depth: FloatArray
    u_right: FloatArray
    points_c: FloatArray
    inv_sigma2: FloatArray
    map_points: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    t_cw: FloatArray | None = None

    def __post_init__(self) -> None:
        if len(self.map_points) != len(self.uv):
            self.map_points = np.full(len(self.uv), -1, dtype=np.int64)

    def __len__(self) -> int:
        return len(self.uv)


class OrbExtractor:
    """ORB keypoints spread over a grid, with depth looked up per keypoint.

    Args:
        n_features: keypoints to keep.
        scale_factor: pyramid scale between levels.
        n_levels: pyramid levels.
        fast_threshold: FAST threshold; a second pass with a lower one fills cells
            of weak texture.
        grid_cell: cell side in pixels for spreading keypoints.
        min_depth: depths below this (m) are ignored.
        max_depth: depths above this (m) are ignored (RGB-D noise grows with depth).
    """

    def __init__(
        self,
        *,
        n_features: int = 1000,
        scale_factor: float = 1.2,
        n_levels: int = 8,
        fast_threshold: int = 20,
        grid_cell: int = 40,
        min_depth: float = 0.1,
        max_depth: float = 8.0,
    ) -> None:
        self.n_features = int(n_features)
        self.scale_factor = float(scale_factor)
        self.n_levels = int(n_levels)
        self.grid_cell = int(grid_cell)
        self.min_depth = float(min_depth)
        self.max_depth = float(max_depth)
        self._orb: Any = cv2.ORB.create(
            nfeatures=int(self.n_features * 2),
            scaleFactor=self.scale_factor,
            nlevels=self.n_levels,
            edgeThreshold=19,
            patchSize=31,
            fastThreshold=int(fast_threshold),
        )
        self._orb_low: Any = cv2.ORB.create(
            nfeatures=int(self.n_features * 2),
            scaleFactor=self.scale_factor,
            nlevels=self.n_levels,
            edgeThreshold=19,
            patchSize=31,
            fastThreshold=max(int(fast_threshold) // 3, 5),
        )
        self.scales = self.scale_factor ** np.arange(self.n_levels, dtype=np.float64)
        self.inv_level_sigma2 = 1.0 / (self.scales**2)

    def _select(self, kps: list[Any], width: int, height: int) -> list[Any]:
        if len(kps) <= self.n_features:
            return kps
        cell = self.grid_cell
        gw = (width + cell - 1) // cell
        gh = (height + cell - 1) // cell
        n_cells = gw * gh
        pts = np.array([k.pt for k in kps], dtype=np.float64)
        resp = np.array([k.response for k in kps], dtype=np.float64)
        cx = np.clip((pts[:, 0] // cell).astype(np.int64), 0, gw - 1)
        cy = np.clip((pts[:, 1] // cell).astype(np.int64), 0, gh - 1)
        cells = cy * gw + cx
        # rank inside each cell by response (stable: ties keep detection order)
        order = np.lexsort((-resp, cells))
        sorted_cells = cells[order]
        first = np.searchsorted(sorted_cells, sorted_cells, side="left")
        rank = np.empty(len(kps), dtype=np.int64)
        rank[order] = np.arange(len(kps)) - first
        # round-robin: all rank-0 keypoints first, then rank 1, ... (strongest first within)
        keep = np.lexsort((-resp, rank))[: self.n_features]
        del n_cells
        return [kps[i] for i in np.sort(keep)]

    def extract(
        self,
        gray: NDArray[np.uint8],
        depth_m: NDArray[np.float32] | None,
        cam: CameraIntrinsics,
        stamp_ns: int,
    ) -> Frame:
        """Detect, describe and attach depth; return a :class:`Frame`.

        Args:
            gray: (H, W) uint8 image.
            depth_m: (H, W) float32 metres (NaN: none), registered to ``gray``, or None.
            cam: intrinsics of the image.
            stamp_ns: capture time.
        """
        h, w = gray.shape[:2]
        kps = list(self._orb.detect(gray, None))
        if len(kps) < self.n_features // 2:
            kps = list(self._orb_low.detect(gray, None))
        kps = self._select(kps, w, h)
        kps, desc = self._orb.compute(gray, kps)
        if desc is None or len(kps) == 0:
            return _empty_frame(stamp_ns)
        uv = np.array([k.pt for k in kps], dtype=np.float64)
        octave = np.array([k.octave & 0xFF for k in kps], dtype=np.int64)
        octave = np.clip(octave, 0, self.n_levels - 1)
        if depth_m is not None:
            ui = np.clip(np.rint(uv[:, 0]).astype(np.int64), 0, w - 1)
            vi = np.clip(np.rint(uv[:, 1]).astype(np.int64), 0, h - 1)
            d = depth_m[vi, ui].astype(np.float64)
            d[~((d >= self.min_depth) & (d <= self.max_depth))] = np.nan
        else:
            d = np.full(len(uv), np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            u_right = uv[:, 0] - cam.bf / d
            pc = np.stack(
                [(uv[:, 0] - cam.cx) * d / cam.fx, (uv[:, 1] - cam.cy) * d / cam.fy, d], axis=1
            )
        return Frame(
            stamp_ns=stamp_ns,
            uv=uv,
            octave=octave,
            descriptors=np.ascontiguousarray(desc, dtype=np.uint8),
            depth=d,
            u_right=u_right,
            points_c=pc,
            inv_sigma2=self.inv_level_sigma2[octave],
        )


def _empty_frame(stamp_ns: int) -> Frame:
    return Frame(
        stamp_ns=stamp_ns,
        uv=np.zeros((0, 2)),
        octave=np.zeros(0, dtype=np.int64),
        descriptors=np.zeros((0, 32), dtype=np.uint8),
        depth=np.zeros(0),
        u_right=np.zeros(0),
        points_c=np.zeros((0, 3)),
        inv_sigma2=np.zeros(0),
    )
