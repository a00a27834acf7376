"""The data model of a visnav world: static shapes, textures, materials, lights, physics.

Everything here is a frozen dataclass validated on construction, so a
:class:`WorldDescription` built from YAML, from SDF, by a generator or by hand
obeys the same rules. Conventions:

* lengths in metres, angles in radians;
* ``pos`` is the centre of a shape in the world frame (z up, REP 103);
* ``rpy`` is roll, pitch, yaw about the fixed x, y, z axes, as in URDF and SDF
  (``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``);
* box ``size`` is the full extent along the shape's local x, y, z (as in SDF),
  not MuJoCo's half sizes; a cylinder's axis is its local z (as in SDF and MuJoCo);
* colours are RGB(A) in [0, 1].

MuJoCo quaternions are w, x, y, z; :func:`rpy_to_quat_wxyz` says so in its name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from visnav.description.errors import WorldError
from visnav.description.mesh_convex import ConvexPieces, convex_pieces
from visnav.description.mesh_files import MeshData, MeshPart, load_mesh
from visnav.description.rigid import rpy_to_matrix

if TYPE_CHECKING:
    from collections.abc import Mapping

    import numpy.typing as npt

__all__ = [
    "Box",
    "Cylinder",
    "Ground",
    "Headlight",
    "Light",
    "Material",
    "Mesh",
    "Physics",
    "Shape",
    "Sphere",
    "Texture",
    "WorldDescription",
    "rpy_to_quat_wxyz",
]

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]
RGB = tuple[float, float, float]
RGBA = tuple[float, float, float, float]

TextureKind = Literal["checker", "gradient", "flat", "noise", "file"]
MarkKind = Literal["none", "edge", "cross", "random"]
LightKind = Literal["directional", "point", "spot"]
Integrator = Literal["euler", "implicit", "implicitfast", "rk4"]

TEXTURE_KINDS: tuple[str, ...] = ("checker", "gradient", "flat", "noise", "file")
MARK_KINDS: tuple[str, ...] = ("none", "edge", "cross", "random")
LIGHT_KINDS: tuple[str, ...] = ("directional", "point", "spot")
INTEGRATORS: tuple[str, ...] = ("euler", "implicit", "implicitfast", "rk4")


def _finite(name: str, values: tuple[float, ...]) -> None:
    if not all(math.isfinite(v) for v in values):
        msg = f"{name}: expected finite numbers, got {list(values)}"
        raise WorldError(msg)


def _positive(name: str, values: tuple[float, ...]) -> None:
    _finite(name, values)
    if not all(v > 0.0 for v in values):
        msg = f"{name}: expected sizes > 0 m, got {list(values)}; sizes are full lengths in metres"
        raise WorldError(msg)


def _unit_interval(name: str, values: tuple[float, ...]) -> None:
    _finite(name, values)
    if not all(0.0 <= v <= 1.0 for v in values):
        msg = f"{name}: expected colour components in [0, 1], got {list(values)}"
        raise WorldError(msg)


def rpy_to_quat_wxyz(rpy: tuple[float, float, float]) -> tuple[float, float, float, float]:
    """Quaternion of fixed-axis roll, pitch, yaw in MuJoCo's order **w, x, y, z**.

    Args:
        rpy: Roll, pitch, yaw in radians.

    Returns:
        ``(w, x, y, z)`` unit quaternion.
    """
    r, p, y = (0.5 * a for a in rpy)
    cr, sr = math.cos(r), math.sin(r)
    cp, sp = math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


@dataclass(frozen=True, kw_only=True)
class Texture:
    """A procedural (or file) 2D texture.

    Attributes:
        name: Unique texture name.
        kind: ``checker`` / ``gradient`` / ``flat`` (MuJoCo builtins), ``noise``
            (seeded blocky value noise, see :mod:`visnav.sim.textures`) or
            ``file`` (a PNG read by MuJoCo).
        rgb1: First colour.
        rgb2: Second colour.
        width: Width in pixels.
        height: Height in pixels.
        seed: Seed of a ``noise`` texture.
        scale: Coarsest noise cell in pixels (``noise`` only).
        mark: MuJoCo builtin marks (``edge``, ``cross``, ``random`` dots).
        markrgb: Colour of the marks.
        random: Probability of a random mark per pixel (``mark: random``).
        file: Absolute path of the image (``file`` only).
    """

    name: str
    kind: TextureKind
    rgb1: RGB = (0.8, 0.8, 0.8)
    rgb2: RGB = (0.3, 0.3, 0.3)
    width: int = 256
    height: int = 256
    seed: int = 0
    scale: int = 16
    mark: MarkKind = "none"
    markrgb: RGB = (1.0, 1.0, 1.0)
    random: float = 0.0
    file: str | None = None

    def __post_init__(self) -> None:
        where = f"texture '{self.name}'"
        if self.kind not in TEXTURE_KINDS:
            msg = f"{where}: unknown type {self.kind!r}; expected one of {list(TEXTURE_KINDS)}"
            raise WorldError(msg)
        if self.mark not in MARK_KINDS:
            msg = f"{where}: unknown mark {self.mark!r}; expected one of {list(MARK_KINDS)}"
            raise WorldError(msg)
        if self.width <= 0 or self.height <= 0 or self.width * self.height > 4096 * 4096:
            msg = (
                f"{where}: width x height must be positive and at most 4096 x 4096, "
                f"got {self.width} x {self.height}"
            )
            raise WorldError(msg)
        if self.scale <= 0:
            msg = f"{where}: scale (noise cell in pixels) must be > 0, got {self.scale}"
            raise WorldError(msg)
        _unit_interval(f"{where}.rgb1", self.rgb1)
        _unit_interval(f"{where}.rgb2", self.rgb2)
        _unit_interval(f"{where}.markrgb", self.markrgb)
        _unit_interval(f"{where}.random", (self.random,))
        if self.kind == "file" and not self.file:
            msg = f"{where}: type 'file' needs a 'file' (path of a PNG image)"
            raise WorldError(msg)


@dataclass(frozen=True, kw_only=True)
class Material:
    """Surface appearance of shapes.

    Attributes:
        name: Unique material name.
        texture: Name of a :class:`Texture`, or None for a plain colour.
        rgba: Colour (multiplies the texture).
        tile: Metres covered by one repetition of the texture. visnav then
            derives MuJoCo's ``texrepeat`` per shape from its size, so a texture
            keeps its scale on a 1 m box and on a 6 m wall. None uses
            ``texrepeat`` relative to each object's size (MuJoCo semantics).
        texrepeat: Repetitions per object when ``tile`` is None.
        specular: Specular intensity.
        shininess: Shininess.
        reflectance: Reflectance (0 keeps rendering cheap).
        emission: Emission.
    """

    name: str
    texture: str | None = None
    rgba: RGBA = (1.0, 1.0, 1.0, 1.0)
    tile: float | None = None
    texrepeat: Vec2 = (1.0, 1.0)
    specular: float = 0.2
    shininess: float = 0.2
    reflectance: float = 0.0
    emission: float = 0.0

    def __post_init__(self) -> None:
        where = f"material '{self.name}'"
        _unit_interval(f"{where}.rgba", self.rgba)
        if self.tile is not None:
            _positive(f"{where}.tile", (self.tile,))
        _positive(f"{where}.texrepeat", self.texrepeat)
        _unit_interval(
            f"{where} (specular, shininess, reflectance, emission)",
            (self.specular, self.shininess, self.reflectance, self.emission),
        )


@dataclass(frozen=True, kw_only=True)
class _ShapeBase:
    name: str
    pos: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)
    material: str | None = None
    rgba: RGBA | None = None
    visual: bool = True
    collision: bool = True

    def _check_common(self, kind: str) -> None:
        where = f"{kind} '{self.name}'"
        _finite(f"{where}.pos", self.pos)
        _finite(f"{where}.rpy", self.rpy)
        if self.rgba is not None:
            _unit_interval(f"{where}.rgba", self.rgba)
        if not (self.visual or self.collision):
            msg = f"{where}: a shape must be visual, collision or both (both are false)"
            raise WorldError(msg)

    @property
    def rotation(self) -> npt.NDArray[np.float64]:
        """World-from-shape rotation matrix (from ``rpy``)."""
        return rpy_to_matrix(self.rpy)


@dataclass(frozen=True, kw_only=True)
class Box(_ShapeBase):
    """A box; ``size`` is the full extent along local x, y, z (metres)."""

    size: Vec3

    def __post_init__(self) -> None:
        self._check_common("box")
        _positive(f"box '{self.name}'.size", self.size)


@dataclass(frozen=True, kw_only=True)
class Cylinder(_ShapeBase):
    """A capped cylinder along local z: ``radius`` and full ``length`` (metres)."""

    radius: float
    length: float

    def __post_init__(self) -> None:
        self._check_common("cylinder")
        _positive(f"cylinder '{self.name}' (radius, length)", (self.radius, self.length))


@dataclass(frozen=True, kw_only=True)
class Sphere(_ShapeBase):
    """A sphere of ``radius`` metres."""

    radius: float

    def __post_init__(self) -> None:
        self._check_common("sphere")
        _positive(f"sphere '{self.name}'.radius", (self.radius,))


@dataclass(frozen=True, kw_only=True)
class Mesh(_ShapeBase):
    """A mesh file (Collada, OBJ, STL or MSH, see :mod:`visnav.description.mesh_files`).

    ``bounds`` is the axis-aligned box of the scaled vertices in the mesh frame
    (min corner, max corner). ``parts`` are the file's triangles by colour, read
    when the world is loaded (empty: read from ``file`` on first use, see
    :attr:`mesh_data`); ``rgba`` None draws each part in its own colour.
    :attr:`pieces` are the convex pieces the simulator collides with and ground
    truth measures against (:mod:`visnav.description.mesh_convex`).
    """

    file: str
    scale: Vec3 = (1.0, 1.0, 1.0)
    bounds: tuple[Vec3, Vec3]
    parts: tuple[MeshPart, ...] = field(default=(), compare=False, repr=False)

    @cached_property
    def mesh_data(self) -> MeshData:
        """The scaled triangles (``parts``, or the file read now)."""
        if self.parts:
            return MeshData(file=self.file, parts=self.parts)
        return load_mesh(self.file, self.scale)

    @cached_property
    def pieces(self) -> ConvexPieces:
        """Convex pieces of the collision shape, in the mesh frame (computed once)."""
        data = self.mesh_data
        offsets = np.cumsum([0, *(len(p.vertices) for p in data.parts)])[:-1]
        faces = np.concatenate([p.faces + o for p, o in zip(data.parts, offsets, strict=True)])
        return convex_pieces(data.vertices, faces, name=f"mesh '{self.name}' ({self.file})")

    def __post_init__(self) -> None:
        self._check_common("mesh")
        _positive(f"mesh '{self.name}'.scale", self.scale)
        lo, hi = self.bounds
        _finite(f"mesh '{self.name}'.bounds", (*lo, *hi))
        if not all(h >= low for low, h in zip(lo, hi, strict=True)):
            msg = f"mesh '{self.name}': bounds min {lo} exceed max {hi}"
            raise WorldError(msg)


Shape = Box | Cylinder | Sphere | Mesh


@dataclass(frozen=True, kw_only=True)
class Ground:
    """An infinite collision plane at height ``z``, drawn over ``size`` (x, y) metres."""

    size: Vec2 = (100.0, 100.0)
    z: float = 0.0
    material: str | None = None
    rgba: RGBA | None = None

    def __post_init__(self) -> None:
        _positive("ground.size", self.size)
        _finite("ground.z", (self.z,))
        if self.rgba is not None:
            _unit_interval("ground.rgba", self.rgba)


@dataclass(frozen=True, kw_only=True)
class Light:
    """A light. Shadows are always off (``castshadow`` false) to keep rendering cheap.

    Attributes:
        name: Unique light name.
        kind: ``directional``, ``point`` or ``spot``.
        pos: Position (point and spot lights).
        dir: Direction the light points to (directional and spot lights).
        diffuse: Diffuse colour.
        ambient: Ambient colour.
        specular: Specular colour.
        attenuation: Constant, linear, quadratic attenuation.
        cutoff: Spot cone half-angle in degrees.
    """

    name: str
    kind: LightKind = "directional"
    pos: Vec3 = (0.0, 0.0, 10.0)
    dir: Vec3 = (0.0, 0.0, -1.0)
    diffuse: RGB = (0.5, 0.5, 0.5)
    ambient: RGB = (0.0, 0.0, 0.0)
    specular: RGB = (0.1, 0.1, 0.1)
    attenuation: Vec3 = (1.0, 0.0, 0.0)
    cutoff: float = 45.0

    def __post_init__(self) -> None:
        where = f"light '{self.name}'"
        if self.kind not in LIGHT_KINDS:
            msg = f"{where}: unknown type {self.kind!r}; expected one of {list(LIGHT_KINDS)}"
            raise WorldError(msg)
        _finite(f"{where}.pos", self.pos)
        _finite(f"{where}.dir", self.dir)
        if not any(self.dir):
            msg = f"{where}.dir: expected a non-zero direction, got {list(self.dir)}"
            raise WorldError(msg)
        for label, rgb in (("diffuse", self.diffuse), ("ambient", self.ambient)):
            _unit_interval(f"{where}.{label}", rgb)
        _unit_interval(f"{where}.specular", self.specular)
        _finite(f"{where}.attenuation", self.attenuation)


@dataclass(frozen=True, kw_only=True)
class Headlight:
    """MuJoCo's headlight (a light attached to every camera)."""

    active: bool = True
    ambient: RGB = (0.35, 0.35, 0.35)
    diffuse: RGB = (0.45, 0.45, 0.45)
    specular: RGB = (0.05, 0.05, 0.05)

    def __post_init__(self) -> None:
        for label, rgb in (
            ("ambient", self.ambient),
            ("diffuse", self.diffuse),
            ("specular", self.specular),
        ):
            _unit_interval(f"headlight.{label}", rgb)


@dataclass(frozen=True, kw_only=True)
class Physics:
    """Fixed physics step, gravity and integrator."""

    timestep: float = 0.002
    gravity: Vec3 = (0.0, 0.0, -9.81)
    integrator: Integrator = "implicitfast"

    def __post_init__(self) -> None:
        _finite("physics.timestep", (self.timestep,))
        if not 0.0 < self.timestep <= 0.1:
            msg = f"physics.timestep: expected 0 < timestep <= 0.1 s, got {self.timestep}"
            raise WorldError(msg)
        _finite("physics.gravity", self.gravity)
        if self.integrator not in INTEGRATORS:
            msg = (
                f"physics.integrator: unknown {self.integrator!r}; "
                f"expected one of {list(INTEGRATORS)}"
            )
            raise WorldError(msg)


@dataclass(frozen=True, kw_only=True)
class WorldDescription:
    """A complete static world, ready for :func:`visnav.sim.world_spec.build_world_spec`.

    Attributes:
        name: World name.
        seed: Seed the world was generated with (textures, random layouts).
        source: Where it came from (a path, ``builtin:<name>`` or ``<dict>``).
        ground: The ground plane, or None.
        shapes: Static shapes.
        textures: Textures referenced by materials.
        materials: Materials referenced by shapes and the ground.
        lights: Lights (shadows off).
        headlight: The camera headlight.
        physics: Timestep, gravity and integrator.
        metadata: Free-form data (free space graph, room centres, start / goal).
        warnings: Unsupported input that was skipped (SDF), one line each.
    """

    name: str
    seed: int = 0
    source: str = "<dict>"
    ground: Ground | None = field(default_factory=Ground)
    shapes: tuple[Shape, ...] = ()
    textures: tuple[Texture, ...] = ()
    materials: tuple[Material, ...] = ()
    lights: tuple[Light, ...] = ()
    headlight: Headlight = field(default_factory=Headlight)
    physics: Physics = field(default_factory=Physics)
    metadata: Mapping[str, Any] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for label, items in (
            ("shape", self.shapes),
            ("texture", self.textures),
            ("material", self.materials),
            ("light", self.lights),
        ):
            seen: set[str] = set()
            for item in items:
                if item.name in seen:
                    msg = f"world '{self.name}': duplicate {label} name {item.name!r}; rename one"
                    raise WorldError(msg)
                seen.add(item.name)
        textures = {t.name for t in self.textures}
        for mat in self.materials:
            if mat.texture is not None and mat.texture not in textures:
                msg = (
                    f"world '{self.name}': material '{mat.name}' uses unknown texture "
                    f"{mat.texture!r}; defined textures: {sorted(textures)}"
                )
                raise WorldError(msg)
        materials = {m.name for m in self.materials}
        users: list[tuple[str, str | None]] = [(s.name, s.material) for s in self.shapes]
        if self.ground is not None:
            users.append(("ground", self.ground.material))
        for user, mat_name in users:
            if mat_name is not None and mat_name not in materials:
                msg = (
                    f"world '{self.name}': '{user}' uses unknown material {mat_name!r}; "
                    f"defined materials: {sorted(materials)}"
                )
                raise WorldError(msg)

    @property
    def collision_shapes(self) -> tuple[Shape, ...]:
        """The shapes that collide (the obstacles)."""
        return tuple(s for s in self.shapes if s.collision)

    def shape(self, name: str) -> Shape:
        """The shape called ``name``.

        Raises:
            WorldError: No shape has that name.
        """
        for s in self.shapes:
            if s.name == name:
                return s
        msg = f"world '{self.name}' has no shape {name!r}"
        raise WorldError(msg)

    def material(self, name: str) -> Material:
        """The material called ``name``.

        Raises:
            WorldError: No material has that name.
        """
        for m in self.materials:
            if m.name == name:
                return m
        msg = f"world '{self.name}' has no material {name!r}"
        raise WorldError(msg)
