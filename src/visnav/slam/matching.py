"""Descriptor matching: guided by projection, and brute force with a ratio test.

:func:`search_by_projection` projects map points with a pose guess and, for each,
compares descriptors only with the keypoints within ``radius`` pixels (found with
a grid over the image); depth, when the keypoint has it, must agree with the projected
depth. Each keypoint keeps at most one map point (the closest in descriptor distance).

The candidate search, Hamming distances, ratio test and the one-point-per-keypoint rule
run in one compiled pass (:func:`_match_projected`, numba): the numpy version it replaced
(kept in tests/slam/_projection_reference.py as the reference the tests compare with)
built and sorted arrays of every candidate pair and cost the car's SLAM worker ~6 ms a frame.
Both give the same matches (ties broken the same way: the lower keypoint index, then
the lower map point index).
"""

from __future__ import annotations

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.features import DescArray, Frame
from visnav.slam.geometry import project

__all__ = [
    "TH_HIGH",
    "TH_LOW",
    "match_descriptors",
    "search_by_projection",
]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

TH_LOW = 50
"""Strict Hamming threshold (ORB-SLAM's TH_LOW)."""
TH_HIGH = 100
"""Loose Hamming threshold (ORB-SLAM's TH_HIGH)."""


@numba.njit(cache=True)
def _popcount64(x: np.uint64) -> int:  # pragma: no cover - compiled
    x = x - ((x >> np.uint64(1)) & np.uint64(0x5555555555555555))
    x = (x & np.uint64(0x3333333333333333)) + ((x >> np.uint64(2)) & np.uint64(0x3333333333333333))
    x = (x + (x >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return int((x * np.uint64(0x0101010101010101)) >> np.uint64(56))


@numba.njit(cache=True)
def _match_projected(
    puv: FloatArray,
    pz: FloatArray,
    point_desc: NDArray[np.uint64],
    kp_uv: FloatArray,
    kp_depth: FloatArray,
    kp_inv_sigma2: FloatArray,
    kp_desc: NDArray[np.uint64],
    sorted_kp: IntArray,
    cell_start: IntArray,
    cell_end: IntArray,
    grid: tuple[int, int],
    cell: float,
    radius: float,
    max_distance: int,
    ratio: float,
    depth_tolerance: float,
) -> tuple[IntArray, IntArray]:  # pragma: no cover - compiled; tests compare with numpy
    """Best keypoint per projected point, then the best point per keypoint (see module)."""
    gw, gh = grid
    n_kp = kp_uv.shape[0]
    kp_best_d = np.full(n_kp, np.iinfo(np.int64).max, dtype=np.int64)
    kp_best_p = np.full(n_kp, -1, dtype=np.int64)
    words = point_desc.shape[1]
    for p in range(puv.shape[0]):
        bx = int(np.floor(puv[p, 0] / cell - 0.5))
        by = int(np.floor(puv[p, 1] / cell - 0.5))
        best_d = np.iinfo(np.int64).max
        best_k = -1
        second_d = np.iinfo(np.int64).max
        for dx in range(2):
            for dy in range(2):
                cx, cy = bx + dx, by + dy
                if cx < 0 or cy < 0 or cx >= gw or cy >= gh:
                    continue
                c = cy * gw + cx
                for s in range(cell_start[c], cell_end[c]):
                    k = sorted_kp[s]
                    du = kp_uv[k, 0] - puv[p, 0]
                    dv = kp_uv[k, 1] - puv[p, 1]
                    r = radius * np.sqrt(1.0 / kp_inv_sigma2[k])
                    if not du * du + dv * dv <= r * r:
                        continue
                    if abs(kp_depth[k] - pz[p]) > depth_tolerance * pz[p] + 0.02:
                        continue  # (NaN depth: never "bad")
                    d = 0
                    for i in range(words):
                        d += _popcount64(point_desc[p, i] ^ kp_desc[k, i])
                    if d < best_d or (d == best_d and k < best_k):
                        if best_k >= 0:
                            second_d = best_d
                        best_d, best_k = d, k
                    elif d < second_d:
                        second_d = d
        if best_k < 0 or best_d > max_distance:
            continue
        if ratio < 1.0 and not best_d < ratio * (
            second_d if second_d < np.iinfo(np.int64).max else np.iinfo(np.int32).max
        ):
            continue
        if best_d < kp_best_d[best_k] or (best_d == kp_best_d[best_k] and p < kp_best_p[best_k]):
            kp_best_d[best_k] = best_d
            kp_best_p[best_k] = p
    keypoints = np.flatnonzero(kp_best_p >= 0)
    return kp_best_p[keypoints], keypoints


def search_by_projection(
    frame: Frame,
    cam: CameraIntrinsics,
    t_cw: FloatArray,
    points_w: FloatArray,
    descriptors: DescArray,
    *,
    radius: float = 15.0,
    max_distance: int = TH_HIGH,
    ratio: float = 0.9,
    depth_tolerance: float = 0.1,
    available: NDArray[np.bool_] | None = None,
) -> tuple[IntArray, IntArray]:
    """Match map points to a frame's keypoints by projecting them with ``t_cw``.

    Args:
        frame: the keypoints.
        cam: intrinsics.
        t_cw: pose guess (world -> camera).
        points_w: (M, 3) map points.
        descriptors: (M, 32) their descriptors.
        radius: search radius in pixels at octave 0 (scaled by the keypoint's octave).
        max_distance: largest accepted Hamming distance.
        ratio: best / second-best distance ratio test (1 disables it).
        depth_tolerance: relative depth disagreement allowed when the keypoint has depth.
        available: (N,) keypoints that may be matched (default all).

    Returns:
        ``(point_index, keypoint_index)`` arrays of the matches, by keypoint index.
    """
    empty = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    if len(points_w) == 0 or len(frame) == 0:
        return empty
    uv, z = project(cam, t_cw, points_w)
    inside = (
        (z > 0.05)
        & (uv[:, 0] >= 0)
        & (uv[:, 0] < cam.width)
        & (uv[:, 1] >= 0)
        & (uv[:, 1] < cam.height)
    )
    pidx = np.flatnonzero(inside)
    if len(pidx) == 0:
        return empty
    cell = max(float(radius) * 2.0, 8.0)
    gw = int(np.ceil(cam.width / cell)) + 1
    gh = int(np.ceil(cam.height / cell)) + 1
    kidx = np.flatnonzero(np.ones(len(frame), dtype=bool) if available is None else available)
    kcell = (frame.uv[kidx, 1] // cell).astype(np.int64) * gw + (frame.uv[kidx, 0] // cell).astype(
        np.int64
    )
    order = np.argsort(kcell, kind="stable")
    cells = np.arange(gw * gh)
    sorted_cells = kcell[order]
    found: tuple[IntArray, IntArray] = _match_projected(
        np.ascontiguousarray(uv[pidx]),
        np.ascontiguousarray(z[pidx]),
        np.ascontiguousarray(descriptors[pidx]).view(np.uint64),
        np.ascontiguousarray(frame.uv, dtype=np.float64),
        np.ascontiguousarray(frame.depth, dtype=np.float64),
        np.ascontiguousarray(frame.inv_sigma2, dtype=np.float64),
        np.ascontiguousarray(frame.descriptors).view(np.uint64),
        kidx[order],
        np.searchsorted(sorted_cells, cells, side="left"),
        np.searchsorted(sorted_cells, cells, side="right"),
        (gw, gh),
        cell,
        float(radius),
        int(max_distance),
        float(ratio),
        float(depth_tolerance),
    )
    mp, kp = found
    return pidx[mp], kp


def match_descriptors(
    query: DescArray,
    train: DescArray,
    *,
    ratio: float = 0.75,
    max_distance: int = TH_HIGH,
) -> tuple[IntArray, IntArray]:
    """Brute-force matches with Lowe's ratio test and mutual uniqueness.

    Returns:
        ``(query_index, train_index)`` arrays.
    """
    empty = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    if len(query) < 1 or len(train) < 2:
        return empty
    matcher = cv2.BFMatcher(cv2.NORM_HAMMING)
    knn = matcher.knnMatch(query, train, k=2)
    qi: list[int] = []
    ti: list[int] = []
    di: list[float] = []
    for pair in knn:
        if len(pair) < 2:
            continue
        m, n = pair
        if m.distance <= max_distance and m.distance < ratio * n.distance:
            qi.append(m.queryIdx)
            ti.append(m.trainIdx)
            di.append(m.distance)
    if not qi:
        return empty
    q = np.asarray(qi, dtype=np.int64)
    t = np.asarray(ti, dtype=np.int64)
    d = np.asarray(di)
    o = np.lexsort((q, d, t))
    q, t = q[o], t[o]
    first = np.ones(len(t), dtype=bool)
    first[1:] = t[1:] != t[:-1]
    return q[first], t[first]
