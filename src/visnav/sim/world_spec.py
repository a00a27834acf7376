"""A :class:`~visnav.description.worldmodel.WorldDescription` as a ``mujoco.MjSpec``.

Meshes become coloured visual parts and convex collision pieces (:mod:`visnav.sim.mesh_geoms`).
"""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING

from visnav.description.worldmodel import (
    Box,
    Cylinder,
    Material,
    Mesh,
    Shape,
    Sphere,
    Texture,
    WorldDescription,
    rpy_to_quat_wxyz,
)
from visnav.sim.textures import noise_image

if TYPE_CHECKING:
    import mujoco

__all__ = ["COLLISION_ONLY_GROUP", "MESH_VISUAL_GROUP", "WORLD_PREFIX", "build_world_spec"]

_LOG = logging.getLogger("visnav.sim.world_spec")

WORLD_PREFIX = "world/"
"""Prefix of every name the world puts into the MuJoCo spec."""

COLLISION_ONLY_GROUP = 3
"""MuJoCo geom group of collision-only shapes (not drawn by visnav cameras)."""

MESH_VISUAL_GROUP = 1
"""Group of the visual geoms of a mesh that also collides (rays skip it, as robot visuals)."""

MESH_RAY_GROUP = 4
"""Group of a colliding world mesh's ray geom: its triangles, merged into one mesh, without
contacts or mass and not drawn. Rays hit it as Gazebo's rays hit the mesh itself: one
bounding-volume hierarchy per mesh, where the convex pieces cost a test each per ray."""

MESH_PIECE_GROUP = 5
"""Group of a world mesh's convex collision pieces (contacts only; rays skip them)."""

DEFAULT_MESH_RGBA = (0.7, 0.7, 0.7, 1.0)
"""Colour of a mesh part that has none (Gazebo's default material is grey)."""


def _texrepeat(shape: Shape, material: Material) -> tuple[float, float]:
    """MuJoCo ``texrepeat`` (relative to object size) so one repeat covers ``tile`` m."""
    if material.tile is None:
        return material.texrepeat
    tile = material.tile
    if isinstance(shape, Cylinder):
        return (2.0 * math.pi * shape.radius / tile, shape.length / tile)
    if isinstance(shape, Sphere):
        return (2.0 * math.pi * shape.radius / tile, math.pi * shape.radius / tile)
    if isinstance(shape, Box):
        sx, sy, sz = shape.size
    else:
        lo, hi = shape.bounds
        sx, sy, sz = (h - low for low, h in zip(lo, hi, strict=True))
    # MuJoCo maps a 2D texture on each box face with u, v along the face's axes
    # (x, z on y faces; y, z on x faces; x, y on z faces); match the largest face.
    faces = {(sx, sz): sx * sz, (sy, sz): sy * sz, (sx, sy): sx * sy}
    u, v = max(faces, key=lambda k: faces[k])
    return (max(u, 1e-6) / tile, max(v, 1e-6) / tile)


def _add_texture(spec: mujoco.MjSpec, tex: Texture) -> None:
    import mujoco  # noqa: PLC0415

    name = WORLD_PREFIX + tex.name
    kind_2d = mujoco.mjtTexture.mjTEXTURE_2D
    if tex.kind == "file":
        spec.add_texture(name=name, type=kind_2d, file=tex.file)
        return
    if tex.kind == "noise":
        image = noise_image(
            tex.width, tex.height, seed=tex.seed, rgb1=tex.rgb1, rgb2=tex.rgb2, scale=tex.scale
        )
        t = spec.add_texture(
            name=name, type=kind_2d, width=tex.width, height=tex.height, nchannel=3
        )
        t.data = image.tobytes()
        return
    builtin = {
        "checker": mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        "gradient": mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        "flat": mujoco.mjtBuiltin.mjBUILTIN_FLAT,
    }[tex.kind]
    mark = {
        "none": mujoco.mjtMark.mjMARK_NONE,
        "edge": mujoco.mjtMark.mjMARK_EDGE,
        "cross": mujoco.mjtMark.mjMARK_CROSS,
        "random": mujoco.mjtMark.mjMARK_RANDOM,
    }[tex.mark]
    spec.add_texture(
        name=name,
        type=kind_2d,
        builtin=builtin,
        width=tex.width,
        height=tex.height,
        rgb1=list(tex.rgb1),
        rgb2=list(tex.rgb2),
        mark=mark,
        markrgb=list(tex.markrgb),
        random=tex.random,
    )


class _MaterialCache:
    """Creates one MuJoCo material per (visnav material, texrepeat) pair on demand."""

    def __init__(self, spec: mujoco.MjSpec, materials: tuple[Material, ...]) -> None:
        self.spec = spec
        self.by_name = {m.name: m for m in materials}
        self.made: dict[tuple[str, float, float, bool], str] = {}

    def get(self, name: str, texrepeat: tuple[float, float], *, uniform: bool) -> str:
        import mujoco  # noqa: PLC0415

        mat = self.by_name[name]
        key = (name, round(texrepeat[0], 4), round(texrepeat[1], 4), uniform)
        if key in self.made:
            return self.made[key]
        mj_name = f"{WORLD_PREFIX}{name}#{len(self.made)}"
        m = self.spec.add_material(
            name=mj_name,
            rgba=list(mat.rgba),
            texrepeat=[key[1], key[2]],
            texuniform=uniform,
            specular=mat.specular,
            shininess=mat.shininess,
            reflectance=mat.reflectance,
            emission=mat.emission,
        )
        if mat.texture is not None:
            m.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = WORLD_PREFIX + mat.texture
        self.made[key] = mj_name
        return mj_name


def _add_mesh(spec: mujoco.MjSpec, shape: Mesh, materials: _MaterialCache) -> None:
    """A mesh: visual parts (own colours unless ``rgba``) and convex collision pieces."""
    from visnav.sim.mesh_geoms import (  # noqa: PLC0415
        add_collision_pieces,
        add_ray_geom,
        add_visual_parts,
    )

    name = WORLD_PREFIX + shape.name
    pos, quat = list(shape.pos), list(rpy_to_quat_wxyz(shape.rpy))
    if shape.visual:
        geoms = add_visual_parts(
            spec,
            spec.worldbody,
            shape.mesh_data.parts,
            name=name,
            pos=pos,
            quat=quat,
            rgba=shape.rgba,
            default_rgba=DEFAULT_MESH_RGBA,
            group=MESH_VISUAL_GROUP if shape.collision else 0,
        )
        if shape.material is not None:
            repeat = _texrepeat(shape, materials.by_name[shape.material])
            for geom in geoms:
                geom.material = materials.get(shape.material, repeat, uniform=False)
    if shape.collision:
        pieces = shape.pieces
        if pieces.warning is not None:
            _LOG.warning("%s", pieces.warning)
        add_collision_pieces(
            spec,
            spec.worldbody,
            pieces.points,
            name=name,
            pos=pos,
            quat=quat,
            group=MESH_PIECE_GROUP,
        )
        add_ray_geom(
            spec, spec.worldbody, shape.mesh_data.parts, name=name, pos=pos, quat=quat,
            group=MESH_RAY_GROUP,
        )  # fmt: skip


def _add_shape(spec: mujoco.MjSpec, shape: Shape, materials: _MaterialCache) -> None:
    import mujoco  # noqa: PLC0415

    if isinstance(shape, Mesh):
        _add_mesh(spec, shape, materials)
        return
    geom = spec.worldbody.add_geom(
        name=WORLD_PREFIX + shape.name,
        pos=list(shape.pos),
        quat=list(rpy_to_quat_wxyz(shape.rpy)),
    )
    if isinstance(shape, Box):
        geom.type = mujoco.mjtGeom.mjGEOM_BOX
        geom.size = [0.5 * s for s in shape.size]
    elif isinstance(shape, Cylinder):
        geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
        geom.size = [shape.radius, 0.5 * shape.length, 0.0]
    else:
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = [shape.radius, 0.0, 0.0]
    if shape.material is not None:
        geom.material = materials.get(
            shape.material, _texrepeat(shape, materials.by_name[shape.material]), uniform=False
        )
    elif shape.rgba is not None:
        geom.rgba = list(shape.rgba)
    if not shape.collision:
        geom.contype = 0
        geom.conaffinity = 0
    if not shape.visual:
        geom.group = COLLISION_ONLY_GROUP


def build_world_spec(world: WorldDescription) -> mujoco.MjSpec:
    """Build a MuJoCo spec holding the world (robots are attached to it afterwards).

    Every name is prefixed with :data:`WORLD_PREFIX`. Lights never cast
    shadows; the headlight is set from ``world.headlight``.

    Args:
        world: The world to build.

    Returns:
        A new, uncompiled ``mujoco.MjSpec``.
    """
    import mujoco  # noqa: PLC0415

    spec = mujoco.MjSpec()
    spec.modelname = world.name
    spec.option.timestep = world.physics.timestep
    spec.option.gravity = list(world.physics.gravity)
    spec.option.integrator = {
        "euler": mujoco.mjtIntegrator.mjINT_EULER,
        "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
        "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    }[world.physics.integrator]
    head = spec.visual.headlight
    head.active = int(world.headlight.active)
    head.ambient = list(world.headlight.ambient)
    head.diffuse = list(world.headlight.diffuse)
    head.specular = list(world.headlight.specular)

    for tex in world.textures:
        _add_texture(spec, tex)
    materials = _MaterialCache(spec, world.materials)

    if world.ground is not None:
        g = world.ground
        geom = spec.worldbody.add_geom(
            name=WORLD_PREFIX + "ground",
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            size=[0.5 * g.size[0], 0.5 * g.size[1], 1.0],
            pos=[0.0, 0.0, g.z],
        )
        if g.material is not None:
            mat = materials.by_name[g.material]
            repeat = (1.0 / mat.tile, 1.0 / mat.tile) if mat.tile else mat.texrepeat
            geom.material = materials.get(g.material, repeat, uniform=mat.tile is not None)
        elif g.rgba is not None:
            geom.rgba = list(g.rgba)

    for shape in world.shapes:
        _add_shape(spec, shape, materials)

    light_types = {
        "directional": mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        "point": mujoco.mjtLightType.mjLIGHT_POINT,
        "spot": mujoco.mjtLightType.mjLIGHT_SPOT,
    }
    for light in world.lights:
        spec.worldbody.add_light(
            name=WORLD_PREFIX + light.name,
            type=light_types[light.kind],
            pos=list(light.pos),
            dir=list(light.dir),
            diffuse=list(light.diffuse),
            ambient=list(light.ambient),
            specular=list(light.specular),
            attenuation=list(light.attenuation),
            cutoff=light.cutoff,
            castshadow=False,
        )
    return spec
