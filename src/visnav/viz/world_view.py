"""The world's geometry in its colours, as Gazebo's window shows it (no MuJoCo needed).

:func:`world_archetypes` turns a :class:`~visnav.description.worldmodel.WorldDescription`
(built-in office / forest, YAML worlds, SDF worlds like ``turtlebot3_world``) into Rerun
archetypes by entity: boxes, cylinders, spheres and the ground in batches (one entity per
kind), meshes one entity each with their parts' colours. A shape's colour is its ``rgba``,
else its material's ``rgba`` times the material texture's mean colour (the viewer draws no
textures); the ground is drawn over the shapes' extent plus 2 m, not its whole
(often 100 m) plane. :func:`log_world` logs them static: the world does not move.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.description.worldmodel import (
    Box,
    Cylinder,
    Material,
    Mesh,
    Shape,
    Sphere,
    Texture,
    WorldDescription,
)
from visnav.tf.transforms import matrix_to_quaternion
from visnav.viz._rerun import rr

__all__ = ["log_world", "shape_color", "world_archetypes"]

_DEFAULT_RGBA = (0.7, 0.7, 0.7, 1.0)
_GROUND_MARGIN_M = 2.0


def _u8(rgba: tuple[float, ...]) -> tuple[int, int, int, int]:
    r, g, b, a = (round(255 * min(1.0, max(0.0, float(v)))) for v in rgba)
    return r, g, b, a


def shape_color(
    rgba: tuple[float, float, float, float] | None,
    material: str | None,
    materials: dict[str, Material],
    textures: dict[str, Texture],
) -> tuple[int, int, int, int]:
    """A shape's display colour (RGBA 0..255): its rgba, else material x texture mean."""
    if rgba is not None:
        return _u8(rgba)
    mat = materials.get(material or "")
    if mat is None:
        return _u8(_DEFAULT_RGBA)
    color = np.asarray(mat.rgba, dtype=np.float64)
    tex = textures.get(mat.texture or "")
    if tex is not None and tex.kind != "file":
        color[:3] *= (np.asarray(tex.rgb1) + np.asarray(tex.rgb2)) / 2.0
    return _u8(tuple(color))


def _quat(shape: Shape) -> NDArray[np.float64]:
    return matrix_to_quaternion(shape.rotation)


def _mesh_archetypes(shape: Mesh, color: tuple[int, int, int, int] | None) -> Iterator[Any]:
    rot, pos = shape.rotation, np.asarray(shape.pos, dtype=np.float64)
    for part in shape.mesh_data.parts:
        verts = (part.vertices @ rot.T + pos).astype(np.float32)
        rgba = color if color is not None else _u8(part.rgba or _DEFAULT_RGBA)
        yield rr.Mesh3D(
            vertex_positions=verts,
            triangle_indices=part.faces.astype(np.uint32),
            albedo_factor=rgba,
        )


def _ground_extent(world: WorldDescription) -> tuple[tuple[float, float], tuple[float, float]]:
    """The ground's drawn rectangle: its size, cut to the world's shapes plus a margin.

    Gazebo's window looks at the world from nearby; a viewer frames its whole scene, so a
    100 m ground plane around a 5 m arena (turtlebot3_world) would shrink the arena to a
    dot. The ground is drawn over the shapes' extent plus :data:`_GROUND_MARGIN_M`.
    """
    assert world.ground is not None
    sx, sy = world.ground.size[0] / 2.0, world.ground.size[1] / 2.0
    points: list[NDArray[np.float64]] = []
    for shape in world.shapes:
        pos = np.asarray(shape.pos, dtype=np.float64)
        if isinstance(shape, Mesh):
            lo, hi = (np.asarray(b, dtype=np.float64) for b in shape.bounds)
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                for z in (lo[2], hi[2])])  # fmt: skip
            points.append(corners @ shape.rotation.T + pos)
        else:
            points.append(pos.reshape(1, 3))
    if not points:
        return (-sx, -sy), (sx, sy)
    xy = np.concatenate(points)[:, :2]
    lo_xy = np.maximum(xy.min(axis=0) - _GROUND_MARGIN_M, (-sx, -sy))
    hi_xy = np.minimum(xy.max(axis=0) + _GROUND_MARGIN_M, (sx, sy))
    if np.any(hi_xy <= lo_xy):
        return (-sx, -sy), (sx, sy)
    return (float(lo_xy[0]), float(lo_xy[1])), (float(hi_xy[0]), float(hi_xy[1]))


def world_archetypes(world: WorldDescription, *, root: str = "world") -> list[tuple[str, Any]]:
    """The world's visual shapes as ``(entity path, archetype)`` pairs under ``root/scene``.

    Args:
        world: the world (see :func:`visnav.description.world.load_world`).
        root: the fixed frame's entity.
    """
    materials = {m.name: m for m in world.materials}
    textures = {t.name: t for t in world.textures}
    base = f"{root}/scene"
    out: list[tuple[str, Any]] = []
    boxes: list[tuple[Box, tuple[int, int, int, int]]] = []
    cylinders: list[tuple[Cylinder, tuple[int, int, int, int]]] = []
    spheres: list[tuple[Sphere, tuple[int, int, int, int]]] = []
    for shape in world.shapes:
        if not shape.visual:
            continue
        color = shape_color(shape.rgba, shape.material, materials, textures)
        if isinstance(shape, Box):
            boxes.append((shape, color))
        elif isinstance(shape, Cylinder):
            cylinders.append((shape, color))
        elif isinstance(shape, Sphere):
            spheres.append((shape, color))
        else:
            own = None if shape.rgba is None and shape.material is None else color
            name = rr.escape_entity_path_part(shape.name)
            out.extend(
                (f"{base}/meshes/{name}/{i}", arch)
                for i, arch in enumerate(_mesh_archetypes(shape, own))
            )
    fill = rr.components.FillMode.Solid
    if boxes:
        out.append(
            (
                f"{base}/boxes",
                rr.Boxes3D(
                    centers=[b.pos for b, _ in boxes],
                    half_sizes=[np.asarray(b.size) / 2.0 for b, _ in boxes],
                    quaternions=[rr.Quaternion(xyzw=_quat(b)) for b, _ in boxes],
                    colors=[c for _, c in boxes],
                    fill_mode=fill,
                ),
            )
        )
    if cylinders:
        out.append(
            (
                f"{base}/cylinders",
                rr.Cylinders3D(
                    lengths=[c.length for c, _ in cylinders],
                    radii=[c.radius for c, _ in cylinders],
                    centers=[c.pos for c, _ in cylinders],
                    quaternions=[rr.Quaternion(xyzw=_quat(c)) for c, _ in cylinders],
                    colors=[col for _, col in cylinders],
                    fill_mode=fill,
                ),
            )
        )
    if spheres:
        out.append(
            (
                f"{base}/spheres",
                rr.Ellipsoids3D(
                    centers=[s.pos for s, _ in spheres],
                    half_sizes=[(s.radius,) * 3 for s, _ in spheres],
                    colors=[c for _, c in spheres],
                    fill_mode=fill,
                ),
            )
        )
    ground = world.ground
    if ground is not None:
        color = shape_color(ground.rgba, ground.material, materials, textures)
        (x0, y0), (x1, y1) = _ground_extent(world)
        z = ground.z - 0.005  # just under the map, which RViz draws at z = 0
        verts = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], np.float32)
        out.append(
            (
                f"{base}/ground",
                rr.Mesh3D(
                    vertex_positions=verts,
                    triangle_indices=np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                    albedo_factor=color,
                ),
            )
        )
    return out


def log_world(recording: Any, world: WorldDescription, *, root: str = "world") -> list[str]:
    """Log the world's geometry static (it does not move); return the entity paths."""
    paths: list[str] = []
    for path, archetype in world_archetypes(world, root=root):
        recording.log(path, archetype, static=True)
        paths.append(path)
    return paths
