"""Convex pieces of a static mesh, so that MuJoCo collides with its true shape.

MuJoCo collides with the convex hull of a mesh geom. A world mesh that is not convex
(turtlebot3_world's wall is a hexagonal ring) would become a solid block, so
:func:`convex_pieces` splits it:

1. into connected components (vertices merged by position);
2. a component whose surface lies on its convex hull is one piece (its hull);
3. any other component becomes one piece per planar face group (adjacent coplanar
   triangles; a group that is not a convex polygon is split into its triangles): the
   group and points moved *into* the solid along the face normal from its centroid and
   corners, each by the local thickness along that ray (at most ``max_depth``; ``thin``
   for an open mesh). The pieces fill a shell under the surface whose outside is the
   mesh itself.

A mesh that would need more than ``max_pieces`` pieces falls back to one hull per
component (with a warning): collisions then see those hulls.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["ConvexPieces", "convex_pieces", "halfspaces", "thickened"]

_EPS = 1e-9


@dataclass(frozen=True, eq=False)
class ConvexPieces:
    """Point sets whose convex hulls together make up a mesh's collision shape."""

    points: tuple[NDArray[np.float64], ...]
    warning: str | None = None


def _hull_equations(points: NDArray[np.float64]) -> NDArray[np.float64] | None:
    from scipy.spatial import ConvexHull, QhullError  # noqa: PLC0415

    if len(points) < 4:
        return None
    try:
        return np.asarray(ConvexHull(points).equations)
    except (QhullError, ValueError):
        return None


def halfspaces(points: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Outward unit-normal half-spaces ``(K, 4)`` (``n . x + d <= 0`` inside) of a hull."""
    return _hull_equations(np.asarray(points, dtype=np.float64))


def _is_convex(vertices: NDArray[np.float64], triangles: NDArray[np.float64], tol: float) -> bool:
    """Whether every vertex and triangle centroid lies on the hull's surface."""
    equations = _hull_equations(vertices)
    if equations is None:
        return False
    points = np.concatenate([vertices, triangles.mean(axis=1)])
    distance = points @ equations[:, :3].T + equations[:, 3]
    return bool(np.all(distance.max(axis=1) >= -tol))


def _ray_depths(
    origins: NDArray[np.float64], directions: NDArray[np.float64], triangles: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Distance along each ray to the nearest triangle hit (inf if none); Moller-Trumbore."""
    out = np.full(len(origins), np.inf)
    a = triangles[:, 0]
    e1 = triangles[:, 1] - a
    e2 = triangles[:, 2] - a
    chunk = max(1, 2_000_000 // max(len(triangles), 1))
    for start in range(0, len(origins), chunk):
        o = origins[start : start + chunk, None, :]
        d = directions[start : start + chunk, None, :]
        p = np.cross(d, e2[None])
        det = np.einsum("gtk,tk->gt", p, e1)
        ok = np.abs(det) > _EPS
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o - a[None]
        u = np.einsum("gtk,gtk->gt", s, p) * inv
        q = np.cross(s, e1[None])
        v = np.einsum("gtk,gtk->gt", d, q) * inv
        t = np.einsum("tk,gtk->gt", e2, q) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
        out[start : start + chunk] = np.where(hit, t, np.inf).min(axis=1)
    return out


@dataclass(frozen=True, eq=False)
class _Component:
    """One connected part of a mesh (vertices merged by position)."""

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    normals: NDArray[np.float64]  # unit face normals
    areas: NDArray[np.float64]
    watertight: bool


def _merged(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], tol: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices merged by position (to ``tol``), degenerate faces dropped."""
    keys = np.round(vertices / max(tol, 1e-12)).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    merged = inverse.reshape(-1)[faces]
    keep = (merged[:, 0] != merged[:, 1]) & (merged[:, 1] != merged[:, 2])
    keep &= merged[:, 0] != merged[:, 2]
    return vertices[first], merged[keep]


def _edges(faces: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Sorted undirected edges (3 per face) and the face of each."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return edges, np.repeat(np.arange(len(faces)), 3)


def _label(n: int, pairs: NDArray[np.int64]) -> NDArray[np.int64]:
    from scipy.sparse import coo_matrix  # noqa: PLC0415
    from scipy.sparse.csgraph import connected_components  # noqa: PLC0415

    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return np.asarray(connected_components(graph, directed=False)[1], dtype=np.int64)


def _adjacent_faces(faces: NDArray[np.int64]) -> tuple[NDArray[np.int64], bool]:
    """Pairs of faces sharing an edge, and whether every edge has exactly two faces."""
    edges, owner = _edges(faces)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, owner = edges[order], owner[order]
    same = np.all(edges[1:] == edges[:-1], axis=1)
    pairs = np.column_stack([owner[:-1][same], owner[1:][same]])
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return pairs, bool(len(counts) and np.all(counts == 2))


def _components(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> list[_Component]:
    vertex_label = _label(len(vertices), np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]]))
    face_label = vertex_label[faces[:, 0]]
    out: list[_Component] = []
    for label in np.unique(face_label):
        sub = faces[face_label == label]
        used, local = np.unique(sub, return_inverse=True)
        sub = local.reshape(-1, 3)
        verts = vertices[used]
        cross = np.cross(verts[sub[:, 1]] - verts[sub[:, 0]], verts[sub[:, 2]] - verts[sub[:, 0]])
        norm = np.linalg.norm(cross, axis=1)
        ok = norm > 1e-15
        if not ok.any():
            continue
        sub, cross, norm = sub[ok], cross[ok], norm[ok]
        _, watertight = _adjacent_faces(sub)
        out.append(
            _Component(
                vertices=verts,
                faces=sub,
                normals=cross / norm[:, None],
                areas=0.5 * norm,
                watertight=watertight,
            )
        )
    return out


def _groups(component: _Component, tol: float) -> list[NDArray[np.int64]]:
    """Planar face groups: adjacent faces with the same plane."""
    pairs, _ = _adjacent_faces(component.faces)
    n = component.normals
    offsets = np.einsum("ij,ij->i", n, component.vertices[component.faces[:, 0]])
    if len(pairs):
        a, b = pairs[:, 0], pairs[:, 1]
        coplanar = (np.einsum("ij,ij->i", n[a], n[b]) > 1.0 - 1e-6) & (
            np.abs(offsets[a] - offsets[b]) <= tol
        )
        pairs = pairs[coplanar]
    labels = _label(len(component.faces), pairs)
    order = np.argsort(labels, kind="stable")
    splits = np.flatnonzero(np.diff(labels[order])) + 1
    return [np.asarray(g, dtype=np.int64) for g in np.split(order, splits)]


def _polygon_is_convex(component: _Component, group: NDArray[np.int64]) -> bool:
    if len(group) == 1:
        return True
    from scipy.spatial import ConvexHull, QhullError  # noqa: PLC0415

    points = component.vertices[np.unique(component.faces[group])]
    normal = component.normals[group[0]]
    axis_u = np.cross(normal, [1.0, 0.0, 0.0])
    if np.linalg.norm(axis_u) < 0.1:
        axis_u = np.cross(normal, [0.0, 1.0, 0.0])
    axis_u /= np.linalg.norm(axis_u)
    axis_v = np.cross(normal, axis_u)
    flat = np.column_stack([points @ axis_u, points @ axis_v])
    try:
        hull_area = float(ConvexHull(flat).volume)
    except (QhullError, ValueError):
        return False
    area = float(component.areas[group].sum())
    return hull_area <= area * (1.0 + 1e-6) + 1e-12


def _component_pieces(
    component: _Component, *, max_depth: float, thin: float, tol: float, max_pieces: int
) -> list[NDArray[np.float64]] | None:
    """The pieces of one connected component, or None when they would be too many."""
    vertices, faces = component.vertices, component.faces
    triangles = vertices[faces]
    if _is_convex(vertices, triangles, tol):
        return [vertices]
    planar = _groups(component, tol)
    if len(planar) > max_pieces:
        return None
    groups: list[NDArray[np.int64]] = []
    for group in planar:
        if _polygon_is_convex(component, group):
            groups.append(group)
        else:
            groups.extend(np.array([i]) for i in group)
    if len(groups) > max_pieces:
        return None
    normals = component.normals
    group_normals = np.array([normals[g[0]] for g in groups])
    corners = [vertices[np.unique(faces[g])] for g in groups]
    # the inner side of each piece: points moved into the solid from the group's centroid
    # and from its corners (inset 2 % towards the centroid), each as deep as the nearest
    # surface along that ray (at most max_depth): the piece does not poke out through a
    # neighbouring face at an acute or reflex corner
    starts, owner = [], []
    for k, points in enumerate(corners):
        centre = points.mean(axis=0)
        starts.append(np.vstack([centre, points + 0.02 * (centre - points)]))
        owner.append(np.full(len(points) + 1, k))
    origin = np.concatenate(starts)
    group_of = np.concatenate(owner)
    direction = -group_normals[group_of]
    if component.watertight:
        depth = _ray_depths(origin + direction * 1e-6, direction, triangles)
        depth = np.where(np.isfinite(depth), np.minimum(depth, max_depth), thin)
    else:
        depth = np.full(len(origin), thin)
    inner = origin + direction * np.maximum(depth, 1e-3)[:, None]
    return [np.concatenate([points, inner[group_of == k]]) for k, points in enumerate(corners)]


def convex_pieces(
    vertices: NDArray[np.float64],
    faces: NDArray[np.int64],
    *,
    max_pieces: int = 400,
    max_depth: float = 0.3,
    thin: float = 0.02,
    name: str = "mesh",
) -> ConvexPieces:
    """Split a static mesh into convex pieces (see the module docstring).

    Args:
        vertices: ``(N, 3)`` positions in metres.
        faces: ``(M, 3)`` vertex indices.
        max_pieces: Above this many pieces, fall back to one hull per component.
        max_depth: Largest depth of a piece below its face, metres.
        thin: Depth of the pieces of an open (not watertight) mesh, metres.
        name: The mesh, for the warning.

    Returns:
        The pieces' point sets (each with at least 4 points not in one plane, or the
        flat points of a degenerate component) and a warning when the fallback was used.
    """
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    extent = float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.0
    tol = 1e-4 * extent + 1e-7
    merged, merged_faces = _merged(vertices, faces, 1e-6 * extent + 1e-9)
    components = _components(merged, merged_faces) if len(merged_faces) else []
    pieces: list[NDArray[np.float64]] = []
    for component in components:
        more = _component_pieces(
            component, max_depth=max_depth, thin=thin, tol=tol, max_pieces=max_pieces
        )
        pieces.extend(more or [])
        if more is None or len(pieces) > max_pieces:
            hulls = [np.asarray(c.vertices, dtype=np.float64) for c in components]
            warning = (
                f"{name}: collision shape needs more than {max_pieces} convex pieces; "
                f"its {len(hulls)} connected parts collide as their convex hulls"
            )
            return ConvexPieces(points=tuple(thickened(h, thin) for h in hulls), warning=warning)
    return ConvexPieces(points=tuple(thickened(p, thin) for p in pieces))


def thickened(points: NDArray[np.float64], thin: float) -> NDArray[np.float64]:
    """A flat point set gets a second layer ``thin`` below its plane (MuJoCo needs volume)."""
    if _hull_equations(points) is not None:
        return points
    centred = points - points.mean(axis=0)
    if len(points) < 3:
        down = points + np.array([0.0, 0.0, -thin])
        return np.concatenate([points, down, points + np.array([thin, thin, 0.0])])
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    normal = vt[-1]
    if normal[2] < 0:
        normal = -normal
    return np.concatenate([points, points - normal * thin])
