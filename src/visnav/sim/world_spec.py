"""A :class:`~visnav.description.worldmodel.WorldDescription` as a ``mujoco.MjSpec``."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from visnav.description.worldmodel import (
    Box,
    Cylinder,
    Material,
    Shape,
    Sphere,
    Texture,
    WorldDescription,
    rpy_to_quat_wxyz,
)
from visnav.sim.textures import noise_image

if TYPE_CHECKING:
    import mujoco

__all__ = ["COLLISION_ONLY_GROUP", "WORLD_PREFIX", "build_world_spec"]

WORLD_PREFIX = "world/"
"""Prefix of every name the world puts into the MuJoCo spec."""

COLLISION_ONLY_GROUP = 3
"""MuJoCo geom group of collision-only shapes (not drawn by visnav cameras)."""


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


def _add_shape(spec: mujoco.MjSpec, shape: Shape, materials: _MaterialCache) -> None:
    import mujoco  # noqa: PLC0415

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
    elif isinstance(shape, Sphere):
        geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
        geom.size = [shape.radius, 0.0, 0.0]
    else:
        mesh_name = f"{WORLD_PREFIX}{shape.name}"
        spec.add_mesh(name=mesh_name, file=shape.file, scale=list(shape.scale))
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = mesh_name
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
