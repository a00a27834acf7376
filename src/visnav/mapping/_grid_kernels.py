"""numba kernels of :mod:`visnav.mapping.grid_map` (flat C-order voxel buffers).

A voxel ``(ix, iy, iz)`` of a map with ``dims = (nx, ny, nz)`` lives at the flat
address ``(ix * ny + iy) * nz + iz`` (ego-planner's ``toAddress``). Positions map
to voxels by ``floor((p - origin) / resolution)``. Every kernel takes the buffers
and the geometry explicitly; none keeps state between calls.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "clear_and_inflate",
    "depth_to_points",
    "inflate_at",
    "mark_occupied",
    "process_cache",
    "query_inflate",
    "query_occupancy",
    "raycast_points",
]

_EDGE = 1e-4  # ego-planner's isInMap keeps 1e-4 m off the map faces


@numba.njit(cache=True)
def _in_map(x: float, y: float, z: float, lo: np.ndarray, hi: np.ndarray) -> bool:
    return bool(
        lo[0] + _EDGE <= x <= hi[0] - _EDGE
        and lo[1] + _EDGE <= y <= hi[1] - _EDGE
        and lo[2] + _EDGE <= z <= hi[2] - _EDGE
    )


@numba.njit(cache=True)
def _clamp_index(i: int, n: int) -> int:
    return min(max(i, 0), n - 1)


@numba.njit(cache=True)
def _address(ix: int, iy: int, iz: int, dims: np.ndarray) -> int:
    return int((ix * dims[1] + iy) * dims[2] + iz)


@numba.njit(cache=True)
def _touch(
    ix: int,
    iy: int,
    iz: int,
    hit: bool,
    dims: np.ndarray,
    cnt_all: np.ndarray,
    cnt_hit: np.ndarray,
    cache: np.ndarray,
    n_cache: int,
) -> tuple[int, int]:
    """Count a hit or a miss in a voxel; returns (address or -1, new cache length)."""
    if ix < 0 or iy < 0 or iz < 0 or ix >= dims[0] or iy >= dims[1] or iz >= dims[2]:
        return -1, n_cache
    adr = _address(ix, iy, iz, dims)
    cnt_all[adr] += 1
    if cnt_all[adr] == 1:
        cache[n_cache] = adr
        n_cache += 1
    if hit:
        cnt_hit[adr] += 1
    return adr, n_cache


@numba.njit(cache=True)
def _closest_point_in_map(
    px: float, py: float, pz: float, cam: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[float, float, float]:
    """Where the ray camera -> p leaves the map box (just inside it)."""
    diff = (px - cam[0], py - cam[1], pz - cam[2])
    min_t = 1e6
    for i in range(3):
        if abs(diff[i]) > 0.0:
            t1 = (hi[i] - cam[i]) / diff[i]
            if 0.0 < t1 < min_t:
                min_t = t1
            t2 = (lo[i] - cam[i]) / diff[i]
            if 0.0 < t2 < min_t:
                min_t = t2
    s = min_t - 1e-3
    return cam[0] + s * diff[0], cam[1] + s * diff[1], cam[2] + s * diff[2]


@numba.njit(cache=True)
def _dda_axis(s: float, i: int, d: float) -> tuple[int, float, float]:
    """Step, first crossing and crossing spacing (in ray parameter) along one axis."""
    if d > 0.0:
        return 1, (i + 1 - s) / d, 1.0 / d
    if d < 0.0:
        return -1, (i - s) / d, -1.0 / d
    return 0, np.inf, np.inf


@numba.njit(cache=True)
def depth_to_points(
    depth: np.ndarray,
    scale: float,
    intrinsics: np.ndarray,
    rotation: np.ndarray,
    translation: np.ndarray,
    use_filter: bool,
    margin: int,
    skip: int,
    min_dist: float,
    max_dist: float,
    max_ray_length: float,
) -> np.ndarray:
    """Back-project a depth image into world points (ego-planner's projectDepthImage).

    With the filter: pixels every ``skip`` inside a ``margin`` border; a pixel
    without a return (0, NaN, inf) or beyond ``max_dist`` becomes a point at
    ``max_ray_length + 0.1`` (a free ray), one nearer than ``min_dist`` is
    dropped. Without it every valid pixel is used as is.

    Args:
        depth: ``(H, W)`` raw depth (uint16 or float32).
        scale: Metres per raw unit (0.001 for 16UC1 millimetres, 1 for 32FC1).
        intrinsics: ``fx, fy, cx, cy``.
        rotation: ``R_world_camera`` (optical frame).
        translation: Camera position in the world.
        use_filter: Apply the depth filter.
        margin: Border skipped by the filter (pixels).
        skip: Pixel stride of the filter.
        min_dist: Nearest accepted depth (m).
        max_dist: Farthest depth taken as an obstacle (m).
        max_ray_length: Longest ray (m).

    Returns:
        ``(M, 3)`` world points.
    """
    rows, cols = depth.shape
    fx, fy, cx, cy = intrinsics[0], intrinsics[1], intrinsics[2], intrinsics[3]
    if not use_filter:
        margin = 0
        skip = 1
    n_v = max(0, (rows - 2 * margin + skip - 1) // skip)
    n_u = max(0, (cols - 2 * margin + skip - 1) // skip)
    out = np.empty((n_v * n_u, 3))
    count = 0
    free_depth = max_ray_length + 0.1
    for a in range(n_v):
        v = margin + a * skip
        for b in range(n_u):
            u = margin + b * skip
            d = float(depth[v, u]) * scale
            valid = d > 0.0 and math.isfinite(d)
            if use_filter:
                if not valid or d > max_dist:
                    d = free_depth
                elif d < min_dist:
                    continue
            elif not valid:
                continue
            xc = (u - cx) * d / fx
            yc = (v - cy) * d / fy
            for k in range(3):
                out[count, k] = (
                    rotation[k, 0] * xc + rotation[k, 1] * yc + rotation[k, 2] * d + translation[k]
                )
            count += 1
    return out[:count]


@numba.njit(cache=True)
def raycast_points(
    points: np.ndarray,
    cam: np.ndarray,
    origin: np.ndarray,
    resolution: float,
    dims: np.ndarray,
    max_ray_length: float,
    ground_height: float,
    cnt_all: np.ndarray,
    cnt_hit: np.ndarray,
    flag_end: np.ndarray,
    flag_traverse: np.ndarray,
    cache: np.ndarray,
    raycast_num: int,
) -> tuple[int, np.ndarray, np.ndarray]:
    """Count hits and misses of the rays camera -> points (ego-planner's raycastProcess).

    A point inside the map and within ``max_ray_length`` is a hit; farther points
    are pulled back to ``max_ray_length`` and points outside the map to the map
    face, both as misses. Each ray then walks from its end voxel towards the
    camera (the camera voxel excluded), counting a miss per voxel, and stops at
    the first voxel another ray of this update already walked through.

    Returns:
        ``(cache length, bbox_min index, bbox_max index)``: the touched voxels are
        ``cache[:n]``; the box bounds the updated region (camera included).
    """
    inv = 1.0 / resolution
    hi = origin + dims * resolution
    n_cache = 0
    bmin = np.array([hi[0], hi[1], hi[2]])
    bmax = np.array([origin[0], origin[1], origin[2]])
    for i in range(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        if not (math.isfinite(px) and math.isfinite(py) and math.isfinite(pz)):
            continue
        hit = True
        if not _in_map(px, py, pz, origin, hi):
            px, py, pz = _closest_point_in_map(px, py, pz, cam, origin, hi)
            hit = False
        length = math.sqrt((px - cam[0]) ** 2 + (py - cam[1]) ** 2 + (pz - cam[2]) ** 2)
        if length > max_ray_length:
            f = max_ray_length / length
            px = cam[0] + (px - cam[0]) * f
            py = cam[1] + (py - cam[1]) * f
            pz = cam[2] + (pz - cam[2]) * f
            hit = False
        bmin[0] = min(bmin[0], px)
        bmin[1] = min(bmin[1], py)
        bmin[2] = min(bmin[2], pz)
        bmax[0] = max(bmax[0], px)
        bmax[1] = max(bmax[1], py)
        bmax[2] = max(bmax[2], pz)
        # continuous voxel coordinates of the ray end and of the camera
        sx, sy, sz = (px - origin[0]) * inv, (py - origin[1]) * inv, (pz - origin[2]) * inv
        ex, ey, ez = (
            (cam[0] - origin[0]) * inv,
            (cam[1] - origin[1]) * inv,
            (cam[2] - origin[2]) * inv,
        )
        ix, iy, iz = math.floor(sx), math.floor(sy), math.floor(sz)
        adr, n_cache = _touch(ix, iy, iz, hit, dims, cnt_all, cnt_hit, cache, n_cache)
        if adr >= 0:
            if flag_end[adr] == raycast_num:
                continue
            flag_end[adr] = raycast_num
        jx, jy, jz = math.floor(ex), math.floor(ey), math.floor(ez)
        stx, tmx, tdx = _dda_axis(sx, ix, ex - sx)
        sty, tmy, tdy = _dda_axis(sy, iy, ey - sy)
        stz, tmz, tdz = _dda_axis(sz, iz, ez - sz)
        n_steps = abs(jx - ix) + abs(jy - iy) + abs(jz - iz)
        for _ in range(n_steps + 1):
            # the end voxel (already counted above) is walked too, as in ego-planner
            if ix == jx and iy == jy and iz == jz:
                break
            adr, n_cache = _touch(ix, iy, iz, False, dims, cnt_all, cnt_hit, cache, n_cache)
            if adr >= 0:
                if flag_traverse[adr] == raycast_num:
                    break
                flag_traverse[adr] = raycast_num
            if tmx < tmy and tmx < tmz:
                ix += stx
                tmx += tdx
            elif tmy < tmz:
                iy += sty
                tmy += tdy
            else:
                iz += stz
                tmz += tdz
    for k in range(3):
        bmin[k] = min(bmin[k], cam[k])
        bmax[k] = max(bmax[k], cam[k])
    bmax[2] = max(bmax[2], ground_height)
    lo = np.empty(3, np.int64)
    up = np.empty(3, np.int64)
    for k in range(3):
        lo[k] = _clamp_index(math.floor((bmin[k] - origin[k]) * inv), dims[k])
        up[k] = _clamp_index(math.floor((bmax[k] - origin[k]) * inv), dims[k])
    return n_cache, lo, up


@numba.njit(cache=True)
def process_cache(
    cache: np.ndarray,
    n_cache: int,
    occ: np.ndarray,
    cnt_all: np.ndarray,
    cnt_hit: np.ndarray,
    dims: np.ndarray,
    local_min: np.ndarray,
    local_max: np.ndarray,
    log_hit: float,
    log_miss: float,
    clamp_min: float,
    clamp_max: float,
) -> None:
    """Apply one log-odds update per touched voxel (majority of hits over misses).

    A voxel outside the local update box ``[local_min, local_max]`` first drops
    to ``clamp_min`` (ego-planner forgets it before updating).
    """
    nyz = dims[1] * dims[2]
    for c in range(n_cache):
        adr = cache[c]
        hits = cnt_hit[adr]
        misses = cnt_all[adr] - hits
        cnt_hit[adr] = 0
        cnt_all[adr] = 0
        update = log_hit if hits >= misses else log_miss
        if update >= 0.0 and occ[adr] >= clamp_max:
            continue
        if update <= 0.0 and occ[adr] <= clamp_min:
            occ[adr] = clamp_min
            continue
        ix = adr // nyz
        iy = (adr // dims[2]) % dims[1]
        iz = adr % dims[2]
        inside = (
            local_min[0] <= ix <= local_max[0]
            and local_min[1] <= iy <= local_max[1]
            and local_min[2] <= iz <= local_max[2]
        )
        if not inside:
            occ[adr] = clamp_min
        occ[adr] = min(max(occ[adr] + update, clamp_min), clamp_max)


@numba.njit(cache=True)
def clear_and_inflate(
    occ: np.ndarray,
    inflate: np.ndarray,
    dims: np.ndarray,
    bound_min: np.ndarray,
    bound_max: np.ndarray,
    margin: int,
    unknown_value: float,
    occupied_log: float,
    inf_step: int,
    ceil_id: int,
    ground_id: int,
) -> None:
    """Forget the shell beyond the local box, then re-inflate it (clearAndInflateLocalMap).

    Voxels in the ``5``-voxel shell just outside ``bound +- margin`` become
    unknown. Inside ``[bound_min, bound_max]`` the inflated buffer is rebuilt from
    every occupied voxel within ``inf_step`` of the box (a cube of half-width
    ``inf_step``); the layers ``ceil_id`` and ``ground_id`` (when >= 0) are marked
    across the box as the virtual ceiling and ground.
    """
    shell = 5
    cut_lo = np.empty(3, np.int64)
    cut_hi = np.empty(3, np.int64)
    out_lo = np.empty(3, np.int64)
    out_hi = np.empty(3, np.int64)
    for k in range(3):
        cut_lo[k] = _clamp_index(bound_min[k] - margin, dims[k])
        cut_hi[k] = _clamp_index(bound_max[k] + margin, dims[k])
        out_lo[k] = _clamp_index(cut_lo[k] - shell, dims[k])
        out_hi[k] = _clamp_index(cut_hi[k] + shell, dims[k])
    # the shell, slab by slab (a box covering the whole map has none)
    for axis in range(3):
        for side in range(2):
            lo = out_lo.copy()
            hi = out_hi.copy()
            if side == 0:
                hi[axis] = cut_lo[axis] - 1
            else:
                lo[axis] = cut_hi[axis] + 1
            for x in range(lo[0], hi[0] + 1):
                for y in range(lo[1], hi[1] + 1):
                    for z in range(lo[2], hi[2] + 1):
                        occ[_address(x, y, z, dims)] = unknown_value
    for x in range(bound_min[0], bound_max[0] + 1):
        for y in range(bound_min[1], bound_max[1] + 1):
            base = _address(x, y, 0, dims)
            for z in range(bound_min[2], bound_max[2] + 1):
                inflate[base + z] = 0
    src_lo = np.empty(3, np.int64)
    src_hi = np.empty(3, np.int64)
    for k in range(3):
        src_lo[k] = _clamp_index(bound_min[k] - inf_step, dims[k])
        src_hi[k] = _clamp_index(bound_max[k] + inf_step, dims[k])
    for x in range(src_lo[0], src_hi[0] + 1):
        for y in range(src_lo[1], src_hi[1] + 1):
            base = _address(x, y, 0, dims)
            for z in range(src_lo[2], src_hi[2] + 1):
                if occ[base + z] > occupied_log:
                    for a in range(max(x - inf_step, 0), min(x + inf_step, dims[0] - 1) + 1):
                        for b in range(max(y - inf_step, 0), min(y + inf_step, dims[1] - 1) + 1):
                            row = _address(a, b, 0, dims)
                            lo_z = max(z - inf_step, 0)
                            hi_z = min(z + inf_step, dims[2] - 1)
                            for c in range(lo_z, hi_z + 1):
                                inflate[row + c] = 1
    for layer in (ceil_id, ground_id):
        if 0 <= layer < dims[2]:
            for x in range(bound_min[0], bound_max[0] + 1):
                for y in range(bound_min[1], bound_max[1] + 1):
                    inflate[_address(x, y, layer, dims)] = 1


@numba.njit(cache=True)
def inflate_at(
    x: float,
    y: float,
    z: float,
    inflate: np.ndarray,
    origin: np.ndarray,
    res: float,
    dims: np.ndarray,
) -> bool:
    """Inflated occupancy of one point (True outside the map), without allocating."""
    inv = 1.0 / res
    edge = _EDGE * inv
    fx = (x - origin[0]) * inv
    fy = (y - origin[1]) * inv
    fz = (z - origin[2]) * inv
    if not (
        edge <= fx <= dims[0] - edge
        and edge <= fy <= dims[1] - edge
        and edge <= fz <= dims[2] - edge
    ):
        return True
    ix = min(math.floor(fx), dims[0] - 1)
    iy = min(math.floor(fy), dims[1] - 1)
    iz = min(math.floor(fz), dims[2] - 1)
    return bool(inflate[_address(ix, iy, iz, dims)] != 0)


@numba.njit(cache=True)
def query_inflate(
    points: np.ndarray, inflate: np.ndarray, origin: np.ndarray, resolution: float, dims: np.ndarray
) -> np.ndarray:
    """Inflated occupancy of points: True when inflated or outside the map (ego-planner's -1)."""
    inv = 1.0 / resolution
    hi = origin + dims * resolution
    out = np.empty(points.shape[0], np.bool_)
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        if not _in_map(x, y, z, origin, hi):
            out[i] = True
            continue
        ix = math.floor((x - origin[0]) * inv)
        iy = math.floor((y - origin[1]) * inv)
        iz = math.floor((z - origin[2]) * inv)
        out[i] = inflate[_address(ix, iy, iz, dims)] != 0
    return out


@numba.njit(cache=True)
def query_occupancy(
    points: np.ndarray,
    occ: np.ndarray,
    origin: np.ndarray,
    resolution: float,
    dims: np.ndarray,
    occupied_log: float,
) -> np.ndarray:
    """Raw occupancy of points: 1 occupied, 0 free or unknown, -1 outside the map."""
    inv = 1.0 / resolution
    hi = origin + dims * resolution
    out = np.empty(points.shape[0], np.int8)
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        if not _in_map(x, y, z, origin, hi):
            out[i] = -1
            continue
        ix = math.floor((x - origin[0]) * inv)
        iy = math.floor((y - origin[1]) * inv)
        iz = math.floor((z - origin[2]) * inv)
        out[i] = 1 if occ[_address(ix, iy, iz, dims)] > occupied_log else 0
    return out


@numba.njit(cache=True)
def mark_occupied(
    points: np.ndarray,
    occ: np.ndarray,
    origin: np.ndarray,
    resolution: float,
    dims: np.ndarray,
    value: float,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Set the log-odds of the voxels holding ``points`` to ``value``.

    Returns:
        ``(bbox_min index, bbox_max index, points inside the map)``.
    """
    inv = 1.0 / resolution
    hi = origin + dims * resolution
    lo = np.full(3, np.iinfo(np.int64).max)
    up = np.full(3, -1, np.int64)
    count = 0
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        if not _in_map(x, y, z, origin, hi):
            continue
        idx = (
            math.floor((x - origin[0]) * inv),
            math.floor((y - origin[1]) * inv),
            math.floor((z - origin[2]) * inv),
        )
        occ[_address(idx[0], idx[1], idx[2], dims)] = value
        for k in range(3):
            lo[k] = min(lo[k], idx[k])
            up[k] = max(up[k], idx[k])
        count += 1
    return lo, up, count
