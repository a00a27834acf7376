"""A subset of SDF worlds, for users coming from Gazebo.

Supported (everything else produces a :class:`~visnav.description.errors.WorldWarning`
naming the element and its line, and is skipped):

* ``<sdf><world>`` (or a bare ``<sdf><model>``);
* ``<include><uri>model://ground_plane</uri></include>`` (a 100 x 100 m ground)
  and ``<include><uri>model://sun</uri></include>`` (Gazebo's sun: a directional
  light pointing along (-0.5, 0.1, -0.9));
* ``<model>`` with ``<pose>``, ``<static>``, ``<link>`` (``<pose>``), and per link
  ``<visual>`` / ``<collision>`` (``<pose>``, ``<geometry>`` with ``<box><size>``,
  ``<cylinder><radius><length>``, ``<sphere><radius>``, ``<plane>`` (becomes the
  ground) and ``<mesh><uri><scale>`` for ``file://`` or relative paths),
  ``<material>`` with ``<diffuse>`` or ``<ambient>``, or a
  ``<script><name>Gazebo/Colour</name>`` of the common Gazebo colours;
* ``<light>`` (directional, point, spot) with ``<pose>``, ``<diffuse>``,
  ``<specular>``, ``<direction>``, ``<attenuation>``, ``<spot><outer_angle>``;
* ``<physics><max_step_size>`` and ``<gravity>``; ``<scene><ambient>``.

A visual and a collision of one link with the same geometry and pose become one
shape; other visuals are visual-only and other collisions collision-only.
Models that are not ``<static>`` are placed as static geometry (with a warning):
visnav worlds hold no free bodies. ``<pose relative_to=...>`` other than the
parent frame is not supported. Shadows are always off.
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from xml.parsers import expat

import numpy as np

from visnav.description.errors import WorldError, WorldWarning
from visnav.description.rigid import rpy_to_matrix
from visnav.description.world_yaml import mesh_bounds
from visnav.description.worldmodel import (
    Box,
    Cylinder,
    Ground,
    Headlight,
    Light,
    Mesh,
    Physics,
    Sphere,
    WorldDescription,
)
from visnav.textfile import read_text

if TYPE_CHECKING:
    import numpy.typing as npt

    from visnav.description.worldmodel import Shape

__all__ = ["load_sdf_world", "parse_sdf_world"]

# Gazebo's classic material scripts (gazebo/media/materials/scripts/gazebo.material),
# diffuse colours rounded.
_GAZEBO_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "Gazebo/Grey": (0.7, 0.7, 0.7, 1.0),
    "Gazebo/DarkGrey": (0.35, 0.35, 0.35, 1.0),
    "Gazebo/White": (1.0, 1.0, 1.0, 1.0),
    "Gazebo/FlatBlack": (0.1, 0.1, 0.1, 1.0),
    "Gazebo/Black": (0.0, 0.0, 0.0, 1.0),
    "Gazebo/Red": (1.0, 0.0, 0.0, 1.0),
    "Gazebo/Green": (0.0, 1.0, 0.0, 1.0),
    "Gazebo/Blue": (0.0, 0.0, 1.0, 1.0),
    "Gazebo/Yellow": (1.0, 1.0, 0.0, 1.0),
    "Gazebo/Orange": (1.0, 0.5, 0.0, 1.0),
    "Gazebo/Purple": (1.0, 0.0, 1.0, 1.0),
    "Gazebo/Turquoise": (0.0, 1.0, 1.0, 1.0),
    "Gazebo/Wood": (0.6, 0.45, 0.3, 1.0),
    "Gazebo/Bricks": (0.6, 0.3, 0.25, 1.0),
}
_DEFAULT_RGBA = (0.7, 0.7, 0.7, 1.0)

_Pose = tuple["npt.NDArray[np.float64]", "npt.NDArray[np.float64]"]  # (rotation 3x3, translation 3)


@dataclass
class _Parsed:
    shapes: list[Shape]
    lights: list[Light]
    ground: Ground | None
    physics: dict[str, Any]
    headlight: dict[str, Any]


class _SdfReader:
    def __init__(self, source: str, base_dir: Path | None) -> None:
        self.source = source
        self.base_dir = base_dir
        self.lines: dict[int, int] = {}
        self.warnings: list[str] = []

    def where(self, element: ET.Element) -> str:
        line = self.lines.get(id(element))
        return f"{self.source}:{line}" if line is not None else self.source

    def warn(self, element: ET.Element, text: str) -> None:
        message = f"{self.where(element)}: <{element.tag}>: {text}"
        self.warnings.append(message)
        warnings.warn(message, WorldWarning, stacklevel=4)

    def error(self, element: ET.Element, text: str) -> WorldError:
        return WorldError(f"{self.where(element)}: <{element.tag}>: {text}")

    def parse(self, text: str) -> ET.Element:
        builder = ET.TreeBuilder()
        parser = expat.ParserCreate()

        def start(tag: str, attrs: dict[str, str]) -> None:
            self.lines[id(builder.start(tag, attrs))] = parser.CurrentLineNumber

        parser.StartElementHandler = start
        parser.EndElementHandler = builder.end
        parser.CharacterDataHandler = builder.data
        try:
            parser.Parse(text, True)
        except expat.ExpatError as exc:
            msg = (
                f"{self.source}:{exc.lineno}: malformed SDF (XML): "
                f"{expat.errors.messages[exc.code]} at column {exc.offset + 1}; fix the XML syntax"
            )
            raise WorldError(msg) from None
        root: ET.Element = builder.close()
        return root

    # values ---------------------------------------------------------------

    def floats(self, element: ET.Element, n: int) -> tuple[float, ...]:
        text = (element.text or "").split()
        try:
            values = tuple(float(v) for v in text)
        except ValueError:
            raise self.error(element, f"expected {n} numbers, got {element.text!r}") from None
        if len(values) != n or not all(math.isfinite(v) for v in values):
            raise self.error(element, f"expected {n} finite numbers, got {element.text!r}")
        return values

    def child_floats(
        self, parent: ET.Element, tag: str, n: int, default: tuple[float, ...] | None = None
    ) -> tuple[float, ...]:
        element = parent.find(tag)
        if element is None:
            if default is None:
                raise self.error(parent, f"missing <{tag}>")
            return default
        return self.floats(element, n)

    def boolean(self, element: ET.Element | None, default: bool) -> bool:
        if element is None:
            return default
        text = (element.text or "").strip().lower()
        if text in ("1", "true"):
            return True
        if text in ("0", "false"):
            return False
        raise self.error(element, f"expected true/false/1/0, got {element.text!r}")

    def pose(self, parent: ET.Element) -> _Pose:
        element = parent.find("pose")
        if element is None:
            return np.eye(3), np.zeros(3)
        relative = element.get("relative_to")
        if relative:
            self.warn(
                element, f"relative_to={relative!r} is not supported; read as the parent frame"
            )
        x, y, z, r, p, yaw = self.floats(element, 6)
        return rpy_to_matrix((r, p, yaw)), np.array([x, y, z])

    def colour(self, element: ET.Element) -> tuple[float, float, float, float]:
        values = (element.text or "").split()
        try:
            rgba = [float(v) for v in values]
        except ValueError:
            raise self.error(element, f"expected r g b [a], got {element.text!r}") from None
        if len(rgba) == 3:
            rgba.append(1.0)
        if len(rgba) != 4:
            raise self.error(element, f"expected r g b [a], got {element.text!r}")
        r, g, b, a = (min(max(v, 0.0), 1.0) for v in rgba)
        return (r, g, b, a)


def _compose(a: _Pose, b: _Pose) -> _Pose:
    return a[0] @ b[0], a[0] @ b[1] + a[1]


def _rpy(rot: npt.NDArray[np.float64]) -> tuple[float, float, float]:
    """Fixed-axis roll, pitch, yaw of a rotation matrix (inverse of rpy_to_matrix)."""
    pitch = math.asin(max(-1.0, min(1.0, -rot[2, 0])))
    if abs(rot[2, 0]) < 1.0 - 1e-9:
        roll = math.atan2(rot[2, 1], rot[2, 2])
        yaw = math.atan2(rot[1, 0], rot[0, 0])
    else:
        roll = 0.0
        yaw = math.atan2(-rot[0, 1], rot[1, 1])
    return (roll, pitch, yaw)


class _WorldParser:
    def __init__(self, reader: _SdfReader) -> None:
        self.r = reader
        self.out = _Parsed(shapes=[], lights=[], ground=None, physics={}, headlight={})

    def world(self, world: ET.Element) -> None:
        handlers = {
            "include": self.include,
            "model": self.model,
            "light": self.light,
            "physics": self.physics,
            "gravity": self.gravity,
            "scene": self.scene,
        }
        for child in world:
            handler = handlers.get(child.tag)
            if handler is None:
                self.r.warn(child, "not supported by visnav worlds; skipped")
            else:
                handler(child)

    def include(self, element: ET.Element) -> None:
        uri = (element.findtext("uri") or "").strip()
        if uri == "model://ground_plane":
            self.out.ground = Ground(size=(100.0, 100.0), rgba=(0.8, 0.8, 0.8, 1.0))
        elif uri == "model://sun":
            self.out.lights.append(
                Light(
                    name=f"sun_{len(self.out.lights)}",
                    kind="directional",
                    pos=(0.0, 0.0, 10.0),
                    dir=(-0.5, 0.1, -0.9),
                    diffuse=(0.8, 0.8, 0.8),
                    specular=(0.2, 0.2, 0.2),
                )
            )
        else:
            self.r.warn(
                element,
                f"include of {uri!r} is not supported (only model://ground_plane and "
                "model://sun); inline the model's <model> in the world file",
            )

    def physics(self, element: ET.Element) -> None:
        for child in element:
            if child.tag == "max_step_size":
                (step,) = self.r.floats(child, 1)
                self.out.physics["timestep"] = step
            else:
                self.r.warn(child, "physics setting not supported; MuJoCo defaults are used")

    def gravity(self, element: ET.Element) -> None:
        gx, gy, gz = self.r.floats(element, 3)
        self.out.physics["gravity"] = (gx, gy, gz)

    def scene(self, element: ET.Element) -> None:
        for child in element:
            if child.tag == "ambient":
                r, g, b, _ = self.r.colour(child)
                self.out.headlight["ambient"] = (r, g, b)
            elif child.tag == "shadows":
                if self.r.boolean(child, default=False):
                    self.r.warn(child, "shadows are always off in visnav")
            else:
                self.r.warn(child, "scene setting not supported; skipped")

    def light(self, element: ET.Element) -> None:
        kind = element.get("type", "point")
        if kind not in ("directional", "point", "spot"):
            self.r.warn(element, f"light type {kind!r} not supported; skipped")
            return
        rot, pos = self.r.pose(element)
        kwargs: dict[str, Any] = {
            "name": element.get("name") or f"light_{len(self.out.lights)}",
            "kind": kind,
            "pos": tuple(float(v) for v in pos),
        }
        handled = {"pose"}
        direction = element.find("direction")
        if direction is not None:
            handled.add("direction")
            kwargs["dir"] = tuple(float(v) for v in rot @ np.array(self.r.floats(direction, 3)))
        for tag in ("diffuse", "specular"):
            child = element.find(tag)
            if child is not None:
                handled.add(tag)
                kwargs[tag] = self.r.colour(child)[:3]
        attenuation = element.find("attenuation")
        if attenuation is not None:
            handled.add("attenuation")
            constant = float(attenuation.findtext("constant") or 1.0)
            linear = float(attenuation.findtext("linear") or 0.0)
            quadratic = float(attenuation.findtext("quadratic") or 0.0)
            kwargs["attenuation"] = (constant, linear, quadratic)
            for child in attenuation:
                if child.tag not in ("constant", "linear", "quadratic"):
                    self.r.warn(child, "light attenuation setting not supported; skipped")
        spot = element.find("spot")
        if spot is not None:
            handled.add("spot")
            outer = spot.findtext("outer_angle")
            if outer is not None:
                kwargs["cutoff"] = math.degrees(float(outer))
        cast = element.find("cast_shadows")
        if cast is not None:
            handled.add("cast_shadows")
            if self.r.boolean(cast, default=False):
                self.r.warn(cast, "shadows are always off in visnav")
        for child in element:
            if child.tag not in handled:
                self.r.warn(child, "light setting not supported; skipped")
        try:
            self.out.lights.append(Light(**kwargs))
        except WorldError as exc:
            raise self.r.error(element, str(exc)) from None

    def model(self, element: ET.Element, parent: _Pose | None = None) -> None:
        name = element.get("name") or f"model_{len(self.out.shapes)}"
        pose = self.r.pose(element)
        if parent is not None:
            pose = _compose(parent, pose)
        if not self.r.boolean(element.find("static"), default=False):
            self.r.warn(element, f"model {name!r} is not static; placed as static geometry")
        for child in element:
            if child.tag == "link":
                self.link(child, name, pose)
            elif child.tag == "model":
                self.model(child, pose)
            elif child.tag not in ("pose", "static"):
                self.r.warn(child, f"model element not supported (model {name!r}); skipped")

    def link(self, element: ET.Element, model: str, model_pose: _Pose) -> None:
        link = element.get("name") or "link"
        pose = _compose(model_pose, self.r.pose(element))
        visuals: list[tuple[str, ET.Element]] = []
        collisions: list[tuple[str, ET.Element]] = []
        for child in element:
            if child.tag == "visual":
                visuals.append((child.get("name") or f"visual_{len(visuals)}", child))
            elif child.tag == "collision":
                collisions.append((child.get("name") or f"collision_{len(collisions)}", child))
            elif child.tag not in ("pose", "inertial", "self_collide", "gravity", "kinematic"):
                self.r.warn(child, f"link element not supported (link {model}/{link}); skipped")
        parsed_visuals = [self.geometry(e, pose, f"{model}/{link}/{n}") for n, e in visuals]
        parsed_collisions = [self.geometry(e, pose, f"{model}/{link}/{n}") for n, e in collisions]
        used: set[int] = set()
        for shape in parsed_collisions:
            if shape is None:
                continue
            match = next(
                (
                    i
                    for i, v in enumerate(parsed_visuals)
                    if v is not None and i not in used and _same_geometry(v, shape)
                ),
                None,
            )
            if match is not None:
                used.add(match)
                visual = parsed_visuals[match]
                if visual is not None:
                    self.out.shapes.append(_with(visual, name=visual.name, collision=True))
            else:
                self.out.shapes.append(_with(shape, visual=False, collision=True))
        for i, visual in enumerate(parsed_visuals):
            if visual is not None and i not in used:
                self.out.shapes.append(_with(visual, visual=True, collision=False))

    def geometry(self, element: ET.Element, link_pose: _Pose, name: str) -> Shape | None:
        is_visual = element.tag == "visual"
        rot, pos = _compose(link_pose, self.r.pose(element))
        allowed = ("pose", "geometry", "material") if is_visual else ("pose", "geometry")
        for child in element:
            if child.tag not in allowed:
                self.r.warn(child, f"{element.tag} setting not supported ({name}); skipped")
        rgba = self.material(element.find("material"), name) if is_visual else _DEFAULT_RGBA
        geometry = element.find("geometry")
        if geometry is None or len(geometry) == 0:
            raise self.r.error(element, f"{name}: missing <geometry> with a shape inside")
        shape_el = geometry[0]
        common: dict[str, Any] = {
            "name": name,
            "pos": tuple(float(v) for v in pos),
            "rpy": _rpy(rot),
            "rgba": rgba,
        }
        try:
            return self._shape(shape_el, common, rot, pos)
        except WorldError as exc:
            raise self.r.error(shape_el, f"{name}: {exc}") from None

    def _shape(
        self,
        shape_el: ET.Element,
        common: dict[str, Any],
        rot: npt.NDArray[np.float64],
        pos: npt.NDArray[np.float64],
    ) -> Shape | None:
        tag = shape_el.tag
        if tag == "box":
            sx, sy, sz = self.r.child_floats(shape_el, "size", 3)
            return Box(size=(sx, sy, sz), **common)
        if tag == "cylinder":
            (radius,) = self.r.child_floats(shape_el, "radius", 1)
            (length,) = self.r.child_floats(shape_el, "length", 1)
            return Cylinder(radius=radius, length=length, **common)
        if tag == "sphere":
            (radius,) = self.r.child_floats(shape_el, "radius", 1)
            return Sphere(radius=radius, **common)
        if tag == "plane":
            normal = np.array(self.r.child_floats(shape_el, "normal", 3, (0.0, 0.0, 1.0)))
            size = self.r.child_floats(shape_el, "size", 2, (100.0, 100.0))
            world_normal = rot @ normal
            if not np.allclose(world_normal / np.linalg.norm(world_normal), (0.0, 0.0, 1.0)):
                self.r.warn(
                    shape_el, "only horizontal planes (normal 0 0 1) are supported; skipped"
                )
                return None
            if self.out.ground is None or self.out.ground.size[0] * self.out.ground.size[1] < (
                size[0] * size[1]
            ):
                self.out.ground = Ground(
                    size=(size[0], size[1]), z=float(pos[2]), rgba=common["rgba"]
                )
            return None
        if tag == "mesh":
            return self._mesh(shape_el, common)
        self.r.warn(
            shape_el, f"geometry <{tag}> not supported (box, cylinder, sphere, plane, mesh)"
        )
        return None

    def _mesh(self, shape_el: ET.Element, common: dict[str, Any]) -> Shape | None:

        uri = (shape_el.findtext("uri") or "").strip()
        if uri.startswith(("model://", "package://", "http://", "https://")):
            self.r.warn(shape_el, f"mesh uri {uri!r} cannot be resolved; use a file path")
            return None
        path = Path(uri.removeprefix("file://"))
        if not path.is_absolute() and self.r.base_dir is not None:
            path = self.r.base_dir / path
        scale = self.r.child_floats(shape_el, "scale", 3, (1.0, 1.0, 1.0))
        sx, sy, sz = scale
        for child in shape_el:
            if child.tag not in ("uri", "scale"):
                self.r.warn(child, "mesh setting not supported; skipped")
        return Mesh(
            file=str(path),
            scale=(sx, sy, sz),
            bounds=mesh_bounds(path, (sx, sy, sz)),
            **common,
        )

    def material(self, element: ET.Element | None, name: str) -> tuple[float, float, float, float]:
        if element is None:
            return _DEFAULT_RGBA
        rgba: tuple[float, float, float, float] | None = None
        for child in element:
            if child.tag == "diffuse" or (child.tag == "ambient" and rgba is None):
                rgba = self.r.colour(child)
            elif child.tag == "script":
                script = (child.findtext("name") or "").strip()
                if script in _GAZEBO_COLOURS:
                    rgba = rgba or _GAZEBO_COLOURS[script]
                else:
                    self.r.warn(child, f"material script {script!r} unknown ({name}); grey used")
            elif child.tag not in ("specular", "emissive", "ambient"):
                self.r.warn(child, f"material element not supported ({name}); skipped")
        return rgba or _DEFAULT_RGBA


def _same_geometry(a: Shape, b: Shape) -> bool:
    if type(a) is not type(b):
        return False
    if not np.allclose(a.pos, b.pos, atol=1e-9) or not np.allclose(
        a.rotation, b.rotation, atol=1e-9
    ):
        return False
    if isinstance(a, Box) and isinstance(b, Box):
        return bool(np.allclose(a.size, b.size))
    if isinstance(a, Cylinder) and isinstance(b, Cylinder):
        return math.isclose(a.radius, b.radius) and math.isclose(a.length, b.length)
    if isinstance(a, Sphere) and isinstance(b, Sphere):
        return math.isclose(a.radius, b.radius)
    if isinstance(a, Mesh) and isinstance(b, Mesh):
        return a.file == b.file and np.allclose(a.scale, b.scale)
    return False


def _with(shape: Shape, **changes: Any) -> Shape:
    from dataclasses import replace  # noqa: PLC0415

    return replace(shape, **changes)


def parse_sdf_world(
    text: str,
    *,
    source: str = "<string>",
    base_dir: str | Path | None = None,
    seed: int | None = None,
) -> WorldDescription:
    """Parse SDF text (the subset in the module docstring) into a world.

    Args:
        text: The SDF document.
        source: File name used in messages.
        base_dir: Directory relative mesh paths start from.
        seed: The world's seed (SDF has none; default 0).

    Returns:
        The world; ``world.warnings`` lists everything skipped (each also
        issued as a :class:`WorldWarning`).

    Raises:
        WorldError: Malformed XML (with line), no ``<world>`` or ``<model>``,
            invalid numbers or sizes.
    """
    reader = _SdfReader(source, Path(base_dir) if base_dir is not None else None)
    root = reader.parse(text)
    if root.tag != "sdf":
        raise reader.error(root, "the root element must be <sdf>")
    parser = _WorldParser(reader)
    world = root.find("world")
    name = "sdf_world"
    if world is not None:
        name = world.get("name") or name
        parser.world(world)
    else:
        models = root.findall("model")
        if not models:
            raise reader.error(root, "expected a <world> (or a <model>) inside <sdf>")
        for model in models:
            parser.model(model)
    for child in root:
        if child.tag not in ("world", "model"):
            reader.warn(child, "not supported at the top level; skipped")
    out = parser.out
    try:
        return WorldDescription(
            name=name,
            seed=0 if seed is None else int(seed),
            source=source,
            ground=out.ground,
            shapes=tuple(out.shapes),
            lights=tuple(out.lights),
            headlight=Headlight(**out.headlight),
            physics=Physics(**out.physics),
            warnings=tuple(reader.warnings),
        )
    except WorldError as exc:
        msg = f"{source}: {exc}"
        raise WorldError(msg) from None


def load_sdf_world(path: str | Path, *, seed: int | None = None) -> WorldDescription:
    """Read an SDF world file (see :func:`parse_sdf_world`).

    Args:
        path: The ``.sdf`` / ``.world`` file.
        seed: The world's seed.

    Returns:
        The world.

    Raises:
        WorldError: The file cannot be read or is invalid.
    """
    file = Path(path)
    text = read_text(file, what="the SDF world", error=WorldError)
    return parse_sdf_world(text, source=str(file), base_dir=file.parent, seed=seed)
