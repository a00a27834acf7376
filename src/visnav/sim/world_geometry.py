"""Ground truth from a world's geometry: obstacle distance and a 2D occupancy grid.

Both work on the collision shapes of a :class:`~visnav.description.worldmodel.WorldDescription`
analytically (boxes, cylinders and spheres exactly, in any orientation; meshes through
the convex pieces the simulator collides with, :attr:`~visnav.description.worldmodel.Mesh.pieces`:
occupancy exactly, distance as the largest distance to a piece's face planes, which is
exact inside and never larger than the true distance outside) and are vectorised with
numpy. They are the reference that acceptance metrics compare maps and flights against.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from visnav.description.errors import WorldError
from visnav.description.mesh_convex import halfspaces
from visnav.description.worldmodel import Box, Cylinder, Mesh, Sphere

if TYPE_CHECKING:
    import numpy.typing as npt

    from visnav.description.worldmodel import Shape, WorldDescription

__all__ = [
    "mesh_halfspaces",
    "obstacle_distance",
    "shape_aabb",
    "shape_signed_distance",
    "true_occupancy_grid",
]

_CHUNK = 8192


def _box_frame(shape: Shape) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Centre (world) and half extents of a box or of a mesh's bounding box."""
    rot = shape.rotation
    if isinstance(shape, Box):
        return np.asarray(shape.pos, dtype=np.float64), 0.5 * np.asarray(shape.size)
    if not isinstance(shape, Mesh):
        msg = f"{type(shape).__name__} '{shape.name}' has no box frame"
        raise TypeError(msg)
    lo = np.asarray(shape.bounds[0])
    hi = np.asarray(shape.bounds[1])
    centre = np.asarray(shape.pos) + rot @ (0.5 * (lo + hi))
    return centre, np.maximum(0.5 * (hi - lo), 1e-9)


def shape_aabb(shape: Shape) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Tight world axis-aligned bounding box of a shape (mesh: of its bounding box).

    Args:
        shape: Any shape.

    Returns:
        ``(lo, hi)``, each of shape ``(3,)``.
    """
    pos = np.asarray(shape.pos, dtype=np.float64)
    if isinstance(shape, Sphere):
        return pos - shape.radius, pos + shape.radius
    rot = shape.rotation
    if isinstance(shape, Cylinder):
        axis = rot[:, 2]
        extent = shape.radius * np.sqrt(
            np.clip(1.0 - axis**2, 0.0, 1.0)
        ) + 0.5 * shape.length * np.abs(axis)
        return pos - extent, pos + extent
    centre, half = _box_frame(shape)
    extent = np.abs(rot) @ half
    return centre - extent, centre + extent


def _box_sdf(
    local: npt.NDArray[np.float64], half: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    q = np.abs(local) - half
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(q.max(axis=-1), 0.0)
    return np.asarray(outside + inside)


def mesh_halfspaces(shape: Mesh) -> list[npt.NDArray[np.float64]]:
    """World-frame half-spaces ``(K, 4)`` of each convex piece (``n . x + d <= 0`` inside)."""
    return [planes for planes, _, _ in _world_pieces(shape)]


def _world_pieces(
    shape: Mesh,
) -> list[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]]:
    """Each convex piece's world half-spaces and world bounding box (lo, hi)."""
    rot = shape.rotation
    pos = np.asarray(shape.pos, dtype=np.float64)
    out = []
    for points in shape.pieces.points:
        local = halfspaces(points)
        if local is None:
            continue
        normals = local[:, :3] @ rot.T
        world = points @ rot.T + pos
        planes = np.column_stack([normals, local[:, 3] - normals @ pos])
        out.append((planes, world.min(axis=0), world.max(axis=0)))
    return out


def _mesh_distance(shape: Mesh, pts: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    best = np.full(pts.shape[0], np.inf)
    for planes in mesh_halfspaces(shape):
        np.minimum(best, (pts @ planes[:, :3].T + planes[:, 3]).max(axis=1), out=best)
    return best


def _mesh_column_hits(
    shape: Mesh, start: npt.NDArray[np.float64], z0: float, z1: float
) -> npt.NDArray[np.bool_]:
    """Vertical segments from ``start`` (z = z0) to z1 against each convex piece."""
    hits = np.zeros(start.shape[0], dtype=bool)
    for planes, lo, hi in _world_pieces(shape):
        if hi[2] < z0 or lo[2] > z1:
            continue
        near = np.flatnonzero(
            (start[:, 0] >= lo[0])
            & (start[:, 0] <= hi[0])
            & (start[:, 1] >= lo[1])
            & (start[:, 1] <= hi[1])
        )
        if near.size == 0:
            continue
        a = start[near] @ planes[:, :3].T + planes[:, 3]  # (n, K) at t = 0
        b = planes[:, 2] * (z1 - z0)  # growth per unit t
        with np.errstate(divide="ignore", invalid="ignore"):
            limit = -a / b
        upper = np.where(b > 0, limit, np.inf).min(axis=1)
        lower = np.where(b < 0, limit, -np.inf).max(axis=1)
        flat_ok = np.all((b != 0) | (a <= 1e-12), axis=1)
        hits[near] |= flat_ok & (np.maximum(lower, 0.0) <= np.minimum(upper, 1.0))
    return hits


def shape_signed_distance(shape: Shape, points: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Signed distance from points to one shape's surface (negative inside).

    Args:
        shape: A shape (a mesh: a lower bound from its convex pieces, see the module doc).
        points: ``(N, 3)`` world points.

    Returns:
        ``(N,)`` distances in metres.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if isinstance(shape, Mesh):
        return _mesh_distance(shape, pts)
    if isinstance(shape, Sphere):
        return np.asarray(np.linalg.norm(pts - np.asarray(shape.pos), axis=1) - shape.radius)
    rot = shape.rotation
    if isinstance(shape, Cylinder):
        local = (pts - np.asarray(shape.pos)) @ rot
        radial = np.hypot(local[:, 0], local[:, 1]) - shape.radius
        axial = np.abs(local[:, 2]) - 0.5 * shape.length
        d = np.stack([radial, axial], axis=1)
        return np.asarray(
            np.minimum(d.max(axis=1), 0.0) + np.linalg.norm(np.maximum(d, 0.0), axis=1)
        )
    centre, half = _box_frame(shape)
    return _box_sdf((pts - centre) @ rot, half)


def obstacle_distance(
    world: WorldDescription,
    points: npt.ArrayLike,
    *,
    include_ground: bool = False,
) -> npt.NDArray[np.float64]:
    """Exact signed distance from 3D points to the nearest obstacle surface.

    Obstacles are the world's collision shapes (boxes, cylinders, spheres exact;
    meshes by their convex pieces, so the result never exceeds the true distance).
    A point inside an obstacle gets a negative value (minus its depth).

    Args:
        world: The world.
        points: ``(..., 3)`` points in the world frame.
        include_ground: Also count the ground plane as an obstacle.

    Returns:
        Distances with the shape of ``points`` minus its last axis; ``inf``
        where the world has no obstacles.

    Raises:
        WorldError: ``points`` does not end in an axis of length 3.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim == 0 or pts.shape[-1] != 3:
        msg = f"obstacle_distance: points must have shape (..., 3), got {pts.shape}"
        raise WorldError(msg)
    out_shape = pts.shape[:-1]
    flat = pts.reshape(-1, 3)
    best = np.full(flat.shape[0], np.inf)
    shapes = world.collision_shapes
    for start in range(0, flat.shape[0], _CHUNK):
        chunk = flat[start : start + _CHUNK]
        view = best[start : start + _CHUNK]
        for shape in shapes:
            np.minimum(view, shape_signed_distance(shape, chunk), out=view)
        if include_ground and world.ground is not None:
            np.minimum(view, chunk[:, 2] - world.ground.z, out=view)
    return best.reshape(out_shape)


def _slab(
    p0: npt.NDArray[np.float64], d: npt.NDArray[np.float64], half: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Parameter interval [t0, t1] where p0 + t d lies in the box |x| <= half (per row)."""
    t0 = np.full(p0.shape[0], -np.inf)
    t1 = np.full(p0.shape[0], np.inf)
    for axis in range(half.shape[0]):
        if abs(d[axis]) < 1e-12:
            outside = np.abs(p0[:, axis]) > half[axis]
            t0[outside] = np.inf
            continue
        a = (-half[axis] - p0[:, axis]) / d[axis]
        b = (half[axis] - p0[:, axis]) / d[axis]
        t0 = np.maximum(t0, np.minimum(a, b))
        t1 = np.minimum(t1, np.maximum(a, b))
    return t0, t1


def _column_hits(
    shape: Shape, xy: npt.NDArray[np.float64], z0: float, z1: float
) -> npt.NDArray[np.bool_]:
    """Whether the vertical segment (x, y, z0)-(x, y, z1) meets the shape, per row of xy."""
    n = xy.shape[0]
    start = np.column_stack([xy, np.full(n, z0)])
    if isinstance(shape, Mesh):
        return _mesh_column_hits(shape, start, z0, z1)
    if isinstance(shape, Sphere):
        c = np.asarray(shape.pos)
        dz = np.clip(c[2], z0, z1) - c[2]
        d2 = (xy[:, 0] - c[0]) ** 2 + (xy[:, 1] - c[1]) ** 2 + dz**2
        return np.asarray(d2 <= shape.radius**2)
    rot = shape.rotation
    d = rot.T @ np.array([0.0, 0.0, z1 - z0])
    if isinstance(shape, Cylinder):
        p0 = (start - np.asarray(shape.pos)) @ rot
        t0, t1 = _slab(p0[:, 2:], d[2:], np.array([0.5 * shape.length]))
        a = d[0] ** 2 + d[1] ** 2
        c = p0[:, 0] ** 2 + p0[:, 1] ** 2 - shape.radius**2
        if a < 1e-12:
            t0 = np.where(c <= 0.0, t0, np.inf)
        else:
            b = 2.0 * (p0[:, 0] * d[0] + p0[:, 1] * d[1])
            disc = b * b - 4.0 * a * c
            root = np.sqrt(np.maximum(disc, 0.0))
            t0 = np.where(disc >= 0.0, np.maximum(t0, (-b - root) / (2.0 * a)), np.inf)
            t1 = np.minimum(t1, (-b + root) / (2.0 * a))
    else:
        centre, half = _box_frame(shape)
        p0 = (start - centre) @ rot
        t0, t1 = _slab(p0, d, half)
    return np.asarray(np.maximum(t0, 0.0) <= np.minimum(t1, 1.0))


def _default_bounds(world: WorldDescription) -> tuple[float, float, float, float]:
    if world.ground is not None:
        sx, sy = world.ground.size
        return (-0.5 * sx, -0.5 * sy, 0.5 * sx, 0.5 * sy)
    shapes = world.collision_shapes
    if not shapes:
        msg = f"world '{world.name}' has neither ground nor obstacles; pass bounds= explicitly"
        raise WorldError(msg)
    boxes = [shape_aabb(s) for s in shapes]
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


def true_occupancy_grid(
    world: WorldDescription,
    resolution: float,
    z_range: tuple[float, float] = (0.05, 2.0),
    *,
    bounds: tuple[float, float, float, float] | None = None,
) -> tuple[npt.NDArray[np.bool_], tuple[float, float]]:
    """Ground-truth 2D occupancy of the collision geometry within a height band.

    A cell is occupied when the vertical segment through its centre, from
    ``z_range[0]`` to ``z_range[1]``, touches a collision shape (exactly for
    boxes, cylinders, spheres and meshes' convex collision pieces, in any
    orientation). The ground plane is not an obstacle.

    The layout follows ``nav_msgs/OccupancyGrid``: ``grid[iy, ix]`` is the cell
    whose lower-left corner is ``origin + (ix, iy) * resolution``; for a message
    use ``np.where(grid, 100, 0).astype(np.int8).ravel()``.

    Args:
        world: The world.
        resolution: Cell size in metres (> 0).
        z_range: ``(z_min, z_max)`` of the band, z_min <= z_max.
        bounds: ``(x_min, y_min, x_max, y_max)``; defaults to the ground's
            extent, else to the obstacles' extent.

    Returns:
        ``(grid, origin)``: a boolean ``(ny, nx)`` array and the ``(x, y)`` of
        the grid's lower-left corner.

    Raises:
        WorldError: Non-positive resolution, inverted ranges, empty bounds.
    """
    if not (math.isfinite(resolution) and resolution > 0.0):
        msg = f"true_occupancy_grid: resolution must be > 0 m, got {resolution}"
        raise WorldError(msg)
    z0, z1 = float(z_range[0]), float(z_range[1])
    if not z0 <= z1:
        msg = f"true_occupancy_grid: z_range must be (z_min, z_max), z_min <= z_max; got {z_range}"
        raise WorldError(msg)
    x_min, y_min, x_max, y_max = bounds if bounds is not None else _default_bounds(world)
    if not (x_max > x_min and y_max > y_min):
        msg = f"true_occupancy_grid: empty bounds {(x_min, y_min, x_max, y_max)}"
        raise WorldError(msg)
    nx = math.ceil((x_max - x_min) / resolution - 1e-9)
    ny = math.ceil((y_max - y_min) / resolution - 1e-9)
    grid = np.zeros((ny, nx), dtype=bool)
    for shape in world.collision_shapes:
        lo, hi = shape_aabb(shape)
        if hi[2] < z0 or lo[2] > z1:
            continue
        ix0 = max(0, math.floor((lo[0] - x_min) / resolution - 0.5))
        ix1 = min(nx - 1, math.ceil((hi[0] - x_min) / resolution - 0.5))
        iy0 = max(0, math.floor((lo[1] - y_min) / resolution - 0.5))
        iy1 = min(ny - 1, math.ceil((hi[1] - y_min) / resolution - 0.5))
        if ix0 > ix1 or iy0 > iy1:
            continue
        ix = np.arange(ix0, ix1 + 1)
        iy = np.arange(iy0, iy1 + 1)
        gx, gy = np.meshgrid(x_min + (ix + 0.5) * resolution, y_min + (iy + 0.5) * resolution)
        hits = _column_hits(shape, np.column_stack([gx.ravel(), gy.ravel()]), z0, z1)
        grid[iy0 : iy1 + 1, ix0 : ix1 + 1] |= hits.reshape(gx.shape)
    return grid, (float(x_min), float(y_min))
