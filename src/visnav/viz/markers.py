"""``visualization_msgs/Marker`` as Rerun archetypes, in the fixed frame.

Types and what they become (sizes as RViz reads ``scale``):

===================  =============================================================
ARROW                ``Arrows3D``: from ``points[0]`` to ``points[1]`` (shaft diameter
                     ``scale.x``), or along the pose's x axis, ``scale.x`` long and
                     ``scale.y`` thick
CUBE / CUBE_LIST     ``Boxes3D`` (``scale`` = edge lengths), solid
SPHERE / SPHERE_LIST ``Ellipsoids3D`` (``scale`` = diameters), solid
CYLINDER             ``Cylinders3D`` along the pose's z axis (``scale.x`` diameter,
                     ``scale.z`` height), solid
LINE_STRIP / LIST    ``LineStrips3D`` (``scale.x`` line width)
POINTS               ``Points3D`` (``scale.x`` point size)
TEXT_VIEW_FACING     a ``Points3D`` label at the pose
TRIANGLE_LIST        ``Mesh3D``
MESH_RESOURCE        not shown (Rerun cannot fetch ``package://`` meshes here)
===================  =============================================================

Per-point ``colors`` are used when there is one per point, else ``color``. A marker
with an all-zero quaternion is taken as unrotated (as RViz does, with a warning).
Differences from RViz: ``lifetime`` and ``frame_locked`` are ignored (a marker stays
until deleted or replaced, at the pose of its stamp).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.tf.transforms import matrix_to_quaternion
from visnav.viz._rerun import rr
from visnav.viz.geometry import color_to_rgba8, pose_matrix, transform_points32

__all__ = [
    "ADD",
    "ARROW",
    "CUBE",
    "CUBE_LIST",
    "CYLINDER",
    "DELETE",
    "DELETEALL",
    "LINE_LIST",
    "LINE_STRIP",
    "MESH_RESOURCE",
    "POINTS",
    "SPHERE",
    "SPHERE_LIST",
    "TEXT_VIEW_FACING",
    "TRIANGLE_LIST",
    "marker_archetypes",
    "marker_type_name",
]

ARROW, CUBE, SPHERE, CYLINDER = 0, 1, 2, 3
LINE_STRIP, LINE_LIST, CUBE_LIST, SPHERE_LIST = 4, 5, 6, 7
POINTS, TEXT_VIEW_FACING, MESH_RESOURCE, TRIANGLE_LIST = 8, 9, 10, 11
ADD, DELETE, DELETEALL = 0, 2, 3

_TYPE_NAMES = {
    ARROW: "ARROW",
    CUBE: "CUBE",
    SPHERE: "SPHERE",
    CYLINDER: "CYLINDER",
    LINE_STRIP: "LINE_STRIP",
    LINE_LIST: "LINE_LIST",
    CUBE_LIST: "CUBE_LIST",
    SPHERE_LIST: "SPHERE_LIST",
    POINTS: "POINTS",
    TEXT_VIEW_FACING: "TEXT_VIEW_FACING",
    MESH_RESOURCE: "MESH_RESOURCE",
    TRIANGLE_LIST: "TRIANGLE_LIST",
}


def _points(marker: Any) -> NDArray[np.float32]:
    pts = marker.points
    if not pts:
        return np.zeros((0, 3), dtype=np.float32)
    return np.array([(p.x, p.y, p.z) for p in pts], dtype=np.float32)


def _colors(marker: Any, count: int) -> NDArray[np.uint8]:
    """Per-point RGBA if the marker has one colour per point, else its colour once."""
    if count and len(marker.colors) == count:
        return np.array([color_to_rgba8(c) for c in marker.colors], dtype=np.uint8)
    return np.array([color_to_rgba8(marker.color)], dtype=np.uint8)


def _half(marker: Any) -> NDArray[np.float32]:
    s = marker.scale
    return np.array([[s.x / 2.0, s.y / 2.0, s.z / 2.0]], dtype=np.float32)


def marker_archetypes(marker: Any, t_fixed_frame: NDArray[np.float64]) -> list[Any]:
    """Return the archetypes that draw ``marker`` in the fixed frame (empty: not drawable).

    Args:
        marker: a ``visualization_msgs/Marker`` with action ADD/MODIFY.
        t_fixed_frame: ``T_fixed_frame`` for the marker's ``header.frame_id`` at its stamp.

    Returns:
        Rerun archetypes to log on the marker's entity.
    """
    world = t_fixed_frame @ pose_matrix(marker.pose)
    center = world[:3, 3].astype(np.float32).reshape(1, 3)
    quat = matrix_to_quaternion(world[:3, :3]).reshape(1, 4)
    kind = int(marker.type)
    local = _points(marker)
    pts = transform_points32(world, local) if local.size else local
    colors = _colors(marker, len(local))
    label = [marker.text] if marker.text and kind != TEXT_VIEW_FACING else None
    s = marker.scale
    if kind == ARROW:
        if len(pts) >= 2:
            origin, vector, radius = pts[:1], pts[1:2] - pts[:1], s.x / 2.0
        else:
            origin = center
            vector = (world[:3, 0] * s.x).astype(np.float32).reshape(1, 3)
            radius = s.y / 2.0
        return [rr.Arrows3D(origins=origin, vectors=vector, radii=radius, colors=colors[:1])]
    if kind in (CUBE, SPHERE, CYLINDER):
        rgba = colors[:1]
        if kind == CUBE:
            box = rr.Boxes3D(
                centers=center,
                half_sizes=_half(marker),
                quaternions=quat,
                colors=rgba,
                fill_mode="solid",
                labels=label,
            )
            return [box]
        if kind == SPHERE:
            sphere = rr.Ellipsoids3D(
                centers=center,
                half_sizes=_half(marker),
                quaternions=quat,
                colors=rgba,
                fill_mode="solid",
                labels=label,
            )
            return [sphere]
        cylinder = rr.Cylinders3D(
            lengths=[s.z],
            radii=[s.x / 2.0],
            centers=center,
            quaternions=quat,
            colors=rgba,
            fill_mode="solid",
            labels=label,
        )
        return [cylinder]
    if kind in (LINE_STRIP, LINE_LIST):
        if len(pts) < 2:
            return []
        if kind == LINE_STRIP:
            return [rr.LineStrips3D([pts], radii=s.x / 2.0, colors=colors[:1])]
        n = len(pts) // 2
        segments = pts[: 2 * n].reshape(n, 2, 3)
        seg_colors = colors[0 : 2 * n : 2] if len(colors) == len(pts) else colors[:1]
        return [rr.LineStrips3D(segments, radii=s.x / 2.0, colors=seg_colors)]
    if kind == CUBE_LIST:
        return [
            rr.Boxes3D(
                centers=pts,
                half_sizes=_half(marker),
                quaternions=quat,
                colors=colors,
                fill_mode="solid",
            )
        ]
    if kind == SPHERE_LIST:
        return [
            rr.Ellipsoids3D(centers=pts, half_sizes=_half(marker), colors=colors, fill_mode="solid")
        ]
    if kind == POINTS:
        return [rr.Points3D(pts, radii=s.x / 2.0, colors=colors)]
    if kind == TEXT_VIEW_FACING:
        text = rr.Points3D(
            center, labels=[marker.text], colors=colors[:1], radii=0.001, show_labels=True
        )
        return [text]
    if kind == TRIANGLE_LIST:
        n = len(pts) // 3
        if n == 0:
            return []
        mesh_kwargs: dict[str, Any] = {
            "vertex_positions": pts[: 3 * n],
            "triangle_indices": np.arange(3 * n, dtype=np.uint32).reshape(n, 3),
        }
        if len(colors) == len(pts):
            mesh_kwargs["vertex_colors"] = colors[: 3 * n]
        else:
            mesh_kwargs["albedo_factor"] = colors[0]
        return [rr.Mesh3D(**mesh_kwargs)]
    return []


def marker_type_name(kind: int) -> str:
    """The constant name of a marker type (``"ARROW"``), or ``"type <n>"``."""
    return _TYPE_NAMES.get(kind, f"type {kind}")
