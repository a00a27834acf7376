"""Meshes as MuJoCo geoms: coloured visual parts and convex collision pieces.

MuJoCo reads neither Collada nor materials, and collides with a mesh's convex hull; so
meshes go into the spec as vertex data (:mod:`visnav.description.mesh_files`):

* :func:`add_visual_parts`: one visual geom per coloured part (MuJoCo renders and ray
  casts the actual triangles);
* :func:`add_collision_pieces`: one collision geom per convex piece
  (:mod:`visnav.description.mesh_convex`), or per part (its hull) for robots;
* :func:`add_ray_geom`: every part's triangles as one geom without contacts, for ray
  casting against the mesh itself.

Visual meshes use MuJoCo's shell inertia so flat parts (decals, planes) compile.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import NDArray

    from visnav.description.mesh_files import MeshPart

__all__ = ["add_collision_pieces", "add_mesh_asset", "add_ray_geom", "add_visual_parts"]


def add_mesh_asset(
    spec: mujoco.MjSpec,
    name: str,
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64] | None = None,
) -> str:
    """Add a mesh asset from vertex (and face) data; without faces MuJoCo uses the hull."""
    mesh = spec.add_mesh(name=name)
    mesh.uservert = np.asarray(vertices, dtype=np.float32).ravel().tolist()
    if faces is not None:
        mesh.userface = np.asarray(faces, dtype=np.int32).ravel().tolist()
    mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    return name


def add_visual_parts(
    spec: mujoco.MjSpec,
    body: Any,
    parts: Sequence[MeshPart],
    *,
    name: str,
    pos: Sequence[float],
    quat: Sequence[float],
    rgba: Sequence[float] | None,
    default_rgba: Sequence[float],
    group: int,
) -> list[Any]:
    """One visual-only geom per part; ``rgba`` (if given) overrides the parts' colours."""
    geoms = []
    for i, part in enumerate(parts):
        mesh = add_mesh_asset(spec, f"{name}#v{i}", part.vertices, part.faces)
        colour = rgba if rgba is not None else (part.rgba or default_rgba)
        geom = body.add_geom(
            name=f"{name}#v{i}" if i or len(parts) > 1 else name,
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=mesh,
            pos=list(pos),
            quat=list(quat),
            rgba=list(colour),
            group=group,
            contype=0,
            conaffinity=0,
        )
        geom.density = 0.0
        geoms.append(geom)
    return geoms


def add_collision_pieces(
    spec: mujoco.MjSpec,
    body: Any,
    pieces: Sequence[NDArray[np.float64]],
    *,
    name: str,
    pos: Sequence[float],
    quat: Sequence[float],
    group: int,
) -> list[Any]:
    """One collision geom per convex piece (MuJoCo takes the hull of its points)."""
    geoms = []
    for j, points in enumerate(pieces):
        mesh = add_mesh_asset(spec, f"{name}#c{j}", points)
        geom = body.add_geom(
            name=f"{name}#c{j}",
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=mesh,
            pos=list(pos),
            quat=list(quat),
            group=group,
            rgba=[0.5, 0.5, 0.5, 1.0],
        )
        geom.density = 0.0
        geoms.append(geom)
    return geoms


def add_ray_geom(
    spec: mujoco.MjSpec,
    body: Any,
    parts: Sequence[MeshPart],
    *,
    name: str,
    pos: Sequence[float],
    quat: Sequence[float],
    group: int,
) -> Any:
    """All parts' triangles as one geom without contacts or mass, for rays only."""
    offsets = np.cumsum([0] + [len(part.vertices) for part in parts[:-1]])
    vertices = np.concatenate([part.vertices for part in parts])
    faces = np.concatenate(
        [part.faces + offset for part, offset in zip(parts, offsets, strict=True)]
    )
    mesh = add_mesh_asset(spec, f"{name}#r", vertices, faces)
    geom = body.add_geom(
        name=f"{name}#r",
        type=mujoco.mjtGeom.mjGEOM_MESH,
        meshname=mesh,
        pos=list(pos),
        quat=list(quat),
        group=group,
        contype=0,
        conaffinity=0,
        rgba=[0.5, 0.5, 0.5, 1.0],
    )
    geom.density = 0.0
    return geom
