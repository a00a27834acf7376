"""Numpy geometry behind the viewer: cloud decimation, scans to points, colours, poses.

Plain functions with arrays in and out (no Rerun), so they are tested and timed on
their own. Transforms are ``T_a_b`` 4x4 matrices (points of ``b`` into ``a``);
quaternions are x, y, z, w as in ROS messages.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.msgs.pointcloud import cloud_to_structured
from visnav.msgs.types import ColorRGBA, LaserScan, PointCloud2, Pose
from visnav.tf.transforms import matrix_to_quaternion, pose_to_matrix
from visnav.viz.display import colormap_lut
from visnav.viz.errors import VizError

__all__ = [
    "cloud_points",
    "color_to_rgba8",
    "colorize",
    "decimate",
    "pack_rgba32",
    "pose_in",
    "pose_matrix",
    "scan_points",
    "transform_points32",
]

_XYZ = ("x", "y", "z")


def decimate(count: int, max_points: int | None) -> int:
    """Return the stride that keeps at most ``max_points`` of ``count`` points (1 = all).

    Raises:
        VizError: ``max_points`` below 1 (None keeps everything).
    """
    if max_points is None:
        return 1
    if max_points < 1:
        text = f"max_points is {max_points}: expected at least 1 (or None to keep every point)"
        raise VizError(text)
    return max(1, math.ceil(count / max_points))


def colorize(
    values: NDArray[Any], *, value_range: tuple[float, float] | None = None, colormap: str = "turbo"
) -> NDArray[np.uint8]:
    """Map values to (N, 3) uint8 RGB through a colour map (min .. max by default)."""
    data = np.asarray(values, dtype=np.float32).reshape(-1)
    lut = colormap_lut(colormap)
    if data.size == 0:
        return np.zeros((0, 3), dtype=np.uint8)
    if value_range is None:
        lo, hi = float(np.nanmin(data)), float(np.nanmax(data))
    else:
        lo, hi = value_range
    span = hi - lo if hi > lo else 1.0
    index = np.clip((data - np.float32(lo)) * np.float32(255.0 / span), 0, 255)
    out: NDArray[np.uint8] = lut[np.nan_to_num(index).astype(np.uint8)]
    return out


def pack_rgba32(rgb: NDArray[np.uint8]) -> NDArray[np.uint32]:
    """Pack (N, 3) uint8 RGB into (N,) uint32 ``0xRRGGBBAA`` (opaque), Rerun's colour form."""
    c = np.asarray(rgb, dtype=np.uint32)
    out: NDArray[np.uint32] = (c[:, 0] << 24) | (c[:, 1] << 16) | (c[:, 2] << 8) | np.uint32(0xFF)
    return out


def _rgb_field_to_rgba32(values: NDArray[Any]) -> NDArray[np.uint32]:
    """ROS ``rgb``/``rgba`` field values (bits 0x00RRGGBB) -> uint32 0xRRGGBBAA, opaque."""
    if values.dtype.kind not in "fiu" or values.dtype.itemsize != 4:
        text = f"the cloud's rgb field has dtype {values.dtype}: expected float32 or uint32"
        raise VizError(text)
    bits = np.ascontiguousarray(values).astype(values.dtype.newbyteorder("="), copy=False)
    out: NDArray[np.uint32] = (bits.view(np.uint32) << np.uint32(8)) | np.uint32(0xFF)
    return out


def cloud_points(
    msg: PointCloud2, *, max_points: int | None = 50_000
) -> tuple[NDArray[np.float32], NDArray[np.uint32] | None]:
    """Return a cloud's points (decimated by a constant stride) and their colours.

    Colours follow RViz's choice of colour transformer: the ``rgb``/``rgba`` field
    when there is one, else ``intensity`` through the turbo map, else none (the
    caller colours by height or uses a flat colour). Points with NaN or infinite x, y
    or z are dropped after decimation, so an organised cloud keeps its even spacing.

    Args:
        msg: the ``sensor_msgs/PointCloud2``.
        max_points: keep at most this many (every k-th point); None keeps all.

    Returns:
        ``(xyz, rgba)``: (N, 3) float32 and (N,) uint32 ``0xRRGGBBAA`` or None.

    Raises:
        MessageError: an inconsistent cloud.
        VizError: a cloud without x, y, z, or a bad ``max_points``.
    """
    points = cloud_to_structured(msg)
    names = points.dtype.names or ()
    missing = [n for n in _XYZ if n not in names]
    if missing:
        text = (
            f"PointCloud2 (frame {msg.header.frame_id!r}) has no field(s) {missing}: "
            f"it has {list(names)}; the viewer needs x, y and z"
        )
        raise VizError(text)
    stride = decimate(points.shape[0], max_points)
    if stride > 1:
        points = points[::stride]
    xyz = np.empty((points.shape[0], 3), dtype=np.float32)
    for i, name in enumerate(_XYZ):
        xyz[:, i] = points[name]
    total = xyz[:, 0] + xyz[:, 1]
    total += xyz[:, 2]
    valid = np.isfinite(total)  # NaN or inf in any coordinate (faster than all(axis=1))
    all_valid = bool(valid.all())
    if not all_valid:
        xyz = xyz[valid]
    colors: NDArray[np.uint32] | None = None
    color_field = next((n for n in ("rgb", "rgba") if n in names), None)
    if color_field is not None:
        raw = points[color_field]
        colors = _rgb_field_to_rgba32(raw if all_valid else raw[valid])
    elif "intensity" in names:
        raw = points["intensity"]
        colors = pack_rgba32(colorize(raw if all_valid else raw[valid]))
    return xyz, colors


def scan_points(msg: LaserScan) -> tuple[NDArray[np.float32], NDArray[np.float32] | None]:
    """Return a LaserScan's valid returns as (N, 3) float32 points in the scan frame.

    A return is valid when ``range_min <= r <= range_max`` and finite (RViz's rule).

    Returns:
        ``(xyz, intensities)``: intensities (N,) when the scan has one per range, else None.
    """
    ranges = np.asarray(msg.ranges, dtype=np.float32)
    angles = np.float32(msg.angle_min) + np.arange(ranges.size, dtype=np.float32) * np.float32(
        msg.angle_increment
    )
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(ranges) & (ranges >= msg.range_min) & (ranges <= msg.range_max)
    r, a = ranges[valid], angles[valid]
    xyz = np.zeros((r.size, 3), dtype=np.float32)
    xyz[:, 0] = r * np.cos(a)
    xyz[:, 1] = r * np.sin(a)
    intensities = np.asarray(msg.intensities, dtype=np.float32)
    return xyz, (intensities[valid] if intensities.size == ranges.size else None)


def transform_points32(matrix: NDArray[np.float64], points: NDArray[Any]) -> NDArray[np.float32]:
    """Apply a 4x4 transform to (N, 3) points; float32 out (identity returns a float32 copy)."""
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    rot = matrix[:3, :3].astype(np.float32)
    trans = matrix[:3, 3].astype(np.float32)
    out: NDArray[np.float32] = pts @ rot.T
    out += trans
    return out


def pose_matrix(pose: Pose) -> NDArray[np.float64]:
    """Return the 4x4 matrix of a Pose; an all-zero quaternion counts as identity (as RViz)."""
    q = pose.orientation
    if q.x == 0.0 and q.y == 0.0 and q.z == 0.0 and q.w == 0.0:
        out = np.eye(4)
        out[:3, 3] = (pose.position.x, pose.position.y, pose.position.z)
        return out
    return pose_to_matrix(pose)


def pose_in(
    matrix: NDArray[np.float64], pose: Pose
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return ``matrix @ pose`` as (translation (3,), quaternion x, y, z, w (4,))."""
    composed = matrix @ pose_matrix(pose)
    return composed[:3, 3].copy(), matrix_to_quaternion(composed[:3, :3])


def color_to_rgba8(color: ColorRGBA) -> tuple[int, int, int, int]:
    """Return a ``std_msgs/ColorRGBA`` (floats 0..1) as 8-bit RGBA."""
    channels = (color.r, color.g, color.b, color.a)
    r, g, b, a = (round(min(max(float(c), 0.0), 1.0) * 255.0) for c in channels)
    return r, g, b, a
