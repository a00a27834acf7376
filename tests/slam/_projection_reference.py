"""The numpy search by projection that :func:`visnav.slam.matching.search_by_projection`
replaced: the reference its tests compare with (same arguments, same matches)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.features import DescArray, Frame, hamming
from visnav.slam.geometry import project
from visnav.slam.matching import TH_HIGH

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


def _ragged_expand(starts: IntArray, counts: IntArray) -> tuple[IntArray, IntArray]:
    """Return (owner, index) listing ``range(starts[i], starts[i] + counts[i])`` for all i."""
    total = int(counts.sum())
    owner = np.repeat(np.arange(len(counts)), counts)
    if total == 0:
        return owner, np.zeros(0, dtype=np.int64)
    offsets = np.cumsum(counts) - counts
    idx = np.arange(total) - np.repeat(offsets, counts) + np.repeat(starts, counts)
    return owner, idx


def search_by_projection_numpy(
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
    """Match map points to a frame's keypoints by projecting them with ``t_cw`` (numpy).

    The reference implementation of :func:`search_by_projection` (same arguments, same
    result), kept for the tests.

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
        ``(point_index, keypoint_index)`` arrays of the matches.
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
    kp_ok = np.ones(len(frame), dtype=bool) if available is None else available
    kidx = np.flatnonzero(kp_ok)
    kcx = (frame.uv[kidx, 0] // cell).astype(np.int64)
    kcy = (frame.uv[kidx, 1] // cell).astype(np.int64)
    kcell = kcy * gw + kcx
    order = np.argsort(kcell, kind="stable")
    sorted_cells = kcell[order]
    sorted_kp = kidx[order]
    n_cells = gw * gh
    cell_start = np.searchsorted(sorted_cells, np.arange(n_cells), side="left")
    cell_end = np.searchsorted(sorted_cells, np.arange(n_cells), side="right")
    puv = uv[pidx]
    # the 2x2 block of cells around each projection covers a disc of radius cell/2
    bx = np.floor(puv[:, 0] / cell - 0.5).astype(np.int64)
    by = np.floor(puv[:, 1] / cell - 0.5).astype(np.int64)
    owners: list[IntArray] = []
    cands: list[IntArray] = []
    for dx in (0, 1):
        for dy in (0, 1):
            cx = bx + dx
            cy = by + dy
            valid = (cx >= 0) & (cy >= 0) & (cx < gw) & (cy < gh)
            c = np.where(valid, cy * gw + cx, 0)
            starts = cell_start[c]
            counts = np.where(valid, cell_end[c] - starts, 0)
            o, i = _ragged_expand(starts, counts)
            owners.append(o)
            cands.append(sorted_kp[i])
    owner = np.concatenate(owners)
    kp = np.concatenate(cands)
    if len(owner) == 0:
        return empty
    d_uv = frame.uv[kp] - puv[owner]
    r = radius * np.sqrt(1.0 / frame.inv_sigma2[kp])
    keep = np.einsum("ij,ij->i", d_uv, d_uv) <= r * r
    kd = frame.depth[kp]
    pz = z[pidx][owner]
    with np.errstate(invalid="ignore"):
        depth_bad = np.abs(kd - pz) > depth_tolerance * pz + 0.02
    keep &= ~depth_bad
    owner = owner[keep]
    kp = kp[keep]
    if len(owner) == 0:
        return empty
    dist = hamming(descriptors[pidx[owner]], frame.descriptors[kp])
    # best and second best per map point
    o = np.lexsort((kp, dist, owner))
    owner, kp, dist = owner[o], kp[o], dist[o]
    first = np.ones(len(owner), dtype=bool)
    first[1:] = owner[1:] != owner[:-1]
    best_pos = np.flatnonzero(first)
    second_pos = best_pos + 1
    has_second = second_pos < len(owner)
    has_second[has_second] &= owner[second_pos[has_second]] == owner[best_pos[has_second]]
    best_d = dist[best_pos]
    second_d = np.full(len(best_pos), np.iinfo(np.int32).max, dtype=np.int64)
    second_d[has_second] = dist[second_pos[has_second]]
    ok = best_d <= max_distance
    if ratio < 1.0:
        ok &= best_d < ratio * second_d
    best_pos = best_pos[ok]
    mp = pidx[owner[best_pos]]
    kpm = kp[best_pos]
    dm = dist[best_pos]
    # one map point per keypoint: keep the smallest distance
    o = np.lexsort((mp, dm, kpm))
    mp, kpm = mp[o], kpm[o]
    first = np.ones(len(kpm), dtype=bool)
    first[1:] = kpm[1:] != kpm[:-1]
    return mp[first], kpm[first]
