"""Point clouds of the SLAM map: per-keyframe depth samples and voxel averaging."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.errors import SlamInputError
from visnav.slam.slam_map import Keyframe

__all__ = ["depth_samples", "voxel_average"]

FloatArray = NDArray[np.float64]


def depth_samples(
    depth_m: NDArray[np.float32],
    colour: NDArray[np.uint8] | None,
    cam: CameraIntrinsics,
    *,
    stride: int,
    max_depth: float,
) -> tuple[NDArray[np.float32], NDArray[np.uint8]]:
    """Back-project every ``stride``-th pixel with depth: camera-frame points and colours.

    Pixels without colour get grey (200).
    """
    s = max(int(stride), 1)
    d = depth_m[::s, ::s]
    vs, us = np.nonzero(np.isfinite(d) & (d <= max_depth))
    z = d[vs, us].astype(np.float32)
    u = (us * s).astype(np.float32)
    v = (vs * s).astype(np.float32)
    pts = np.stack([(u - cam.cx) * z / cam.fx, (v - cam.cy) * z / cam.fy, z], axis=1)
    rgb = (
        colour[::s, ::s][vs, us].astype(np.uint8)
        if colour is not None
        else np.full((len(z), 3), 200, dtype=np.uint8)
    )
    return pts.astype(np.float32), rgb


def voxel_average(
    keyframes: list[Keyframe], voxel_size: float
) -> tuple[NDArray[np.float32], NDArray[np.uint8]]:
    """Keyframe depth samples in the world frame, one averaged point per occupied voxel.

    Raises:
        SlamInputError: ``voxel_size`` is not positive.
    """
    if not voxel_size > 0:
        text = f"voxel_size {voxel_size} must be positive (metres)"
        raise SlamInputError(text)
    pts_list: list[FloatArray] = []
    rgb_list: list[NDArray[np.uint8]] = []
    for kf in keyframes:
        if kf.bad or kf.cloud is None:
            continue
        p, c = kf.cloud
        t = kf.t_wc
        pts_list.append(p.astype(np.float64) @ t[:3, :3].T + t[:3, 3])
        rgb_list.append(c)
    if not pts_list:
        return np.zeros((0, 3), dtype=np.float32), np.zeros((0, 3), dtype=np.uint8)
    pts = np.concatenate(pts_list)
    rgb = np.concatenate(rgb_list).astype(np.float64)
    keys = np.floor(pts / voxel_size).astype(np.int64)
    _, inv, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    out_p = np.zeros((len(counts), 3))
    out_c = np.zeros((len(counts), 3))
    for axis in range(3):
        out_p[:, axis] = np.bincount(inv, weights=pts[:, axis], minlength=len(counts))
        out_c[:, axis] = np.bincount(inv, weights=rgb[:, axis], minlength=len(counts))
    out_p /= counts[:, None]
    out_c /= counts[:, None]
    return out_p.astype(np.float32), np.clip(np.rint(out_c), 0, 255).astype(np.uint8)
