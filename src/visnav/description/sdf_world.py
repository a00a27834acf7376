"""SDF worlds, for users coming from Gazebo (Classic): the subset visnav builds.

Supported (everything else produces a :class:`~visnav.description.errors.WorldWarning`
naming the element and its file and line, and is skipped):

* ``<sdf><world>`` (or a bare ``<sdf><model>``);
* ``<include>`` with ``<uri>``, ``<name>``, ``<pose>``, ``<static>``, in the world and in
  models (nested): ``model://NAME`` is found on Gazebo's model path (``GAZEBO_MODEL_PATH``,
  the ``gazebo_model_path`` exports of ROS packages, ``~/.gazebo/models``; see
  :mod:`visnav.description.model_path` and :mod:`visnav.description.sdf_include`);
  ``model://ground_plane`` and ``model://sun`` not on the path are Gazebo's (a 100 x 100 m
  ground; a directional light along (-0.5, 0.1, -0.9)). Models that are not found are
  one error listing them all, or (``skip_missing_models``) one warning;
* ``<model>`` with ``<pose>``, ``<static>``, nested ``<model>`` (named ``outer::inner``),
  ``<link>`` (``<pose>``), and per link ``<visual>`` / ``<collision>`` (``<pose>``,
  ``<geometry>`` with ``<box><size>``, ``<cylinder><radius><length>``,
  ``<sphere><radius>``, ``<plane>`` (becomes the ground) and ``<mesh><uri><scale>``:
  Collada, OBJ, STL or MSH by ``model://``, ``file://``, ``package://`` or a path),
  ``<material>`` with ``<diffuse>`` or ``<ambient>``, or a ``<script>`` (Gazebo's
  ``gazebo.material`` colours, or a model's own ``.material`` files); a mesh visual
  without a material keeps the file's own colours;
* ``<light>`` (directional, point, spot) with ``<pose>``, ``<diffuse>``,
  ``<specular>``, ``<direction>``, ``<attenuation>``, ``<spot><outer_angle>``;
* ``<physics><max_step_size>`` and ``<gravity>``; ``<scene><ambient>``.

A visual and a collision of one link with the same geometry and pose become one
shape; other visuals are visual-only and other collisions collision-only.
Models that are not ``<static>`` are placed as static geometry (with a warning):
visnav worlds hold no free bodies. ``<pose relative_to=...>`` other than the
parent frame is not supported. Shadows are always off. An empty value (``<pose/>``,
``<size></size>``) is a warning and SDFormat's default, as Gazebo reads it.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.description.errors import MeshFileError, WorldError
from visnav.description.mesh_files import MeshData, load_mesh
from visnav.description.model_path import ModelPath
from visnav.description.model_path import model_path as find_model_path
from visnav.description.sdf_document import Pose, SdfReader, compose, rpy_of
from visnav.description.sdf_include import SdfResources, missing_models_error
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
    import os
    from collections.abc import Callable, Mapping

    import numpy.typing as npt

    from visnav.description.worldmodel import Shape

__all__ = ["load_sdf_world", "parse_sdf_world"]

_DEFAULT_RGBA = (0.7, 0.7, 0.7, 1.0)


@dataclass
class _Parsed:
    shapes: list[Shape]
    lights: list[Light]
    ground: Ground | None
    physics: dict[str, Any]
    headlight: dict[str, Any]


# Elements that configure Gazebo itself, not the world visnav simulates: its physics engine's
# own solver and real-time loop (MuJoCo steps at <max_step_size>; the sim node paces itself),
# and what only Gazebo's client window draws. Logged at debug level (``visnav --debug``).
_GAZEBO_SOLVER = frozenset(
    ("real_time_update_rate", "real_time_factor", "ode", "bullet", "simbody", "dart",
     "max_contacts")
)  # fmt: skip
_GAZEBO_CLIENT_SCENE = frozenset(("background", "sky", "grid", "origin_visual"))


class _WorldParser:
    def __init__(self, reader: SdfReader, resources: SdfResources) -> None:
        self.r = reader
        self.res = resources
        self.meshes: dict[str, MeshData] = {}
        self.out = _Parsed(shapes=[], lights=[], ground=None, physics={}, headlight={})

    def world(self, world: ET.Element) -> None:
        handlers: dict[str, Callable[[ET.Element], None]] = {
            "include": self.include,
            "model": self.model,
            "light": self.light,
            "physics": self.physics,
            "gravity": self.gravity,
            "scene": self.scene,
        }
        for child in world:
            handler = handlers.get(child.tag)
            if child.tag == "gui":
                self.r.gazebo_only(child, "Gazebo's client window; visnav has none")
            elif handler is None:
                self.r.warn(child, "not supported by visnav worlds; skipped")
            else:
                handler(child)

    def include(
        self,
        element: ET.Element,
        parent: Pose | None = None,
        scope: str = "",
        *,
        static: bool = False,
    ) -> None:
        uri = (element.findtext("uri") or "").strip()
        for child in element:
            if child.tag not in ("uri", "name", "pose", "static", "plugin"):
                self.r.warn(child, "include setting not supported; skipped")
        if not uri:
            self.r.warn(element, "<include> without a <uri>; skipped")
            return
        included = self.res.include(element, uri, self.r.base_dir, self.r.where(element))
        if included is None:
            if uri.rstrip("/") in ("model://ground_plane", "model://sun"):
                self._builtin(uri.rstrip("/"), element, parent)
            return
        saved = self.r.base_dir
        self.r.base_dir = included.base_dir
        try:
            with self.res.nested():
                top = included.element
                if top.tag == "model":
                    self.model(top, parent, scope=scope, static=static)
                elif top.tag == "light":
                    self.light(top)
                else:
                    self.r.warn(top, "actors are not simulated; skipped")
        finally:
            self.r.base_dir = saved

    def _builtin(self, uri: str, element: ET.Element, parent: Pose | None) -> None:
        """Gazebo's own ground_plane and sun, when no model directory provides them."""
        rot, pos = self.r.pose(element)
        if parent is not None:
            rot, pos = compose(parent, (rot, pos))
        if uri == "model://ground_plane":
            self.out.ground = Ground(
                size=(100.0, 100.0), z=float(pos[2]), rgba=(0.8, 0.8, 0.8, 1.0)
            )
            return
        self.out.lights.append(
            Light(
                name=(element.findtext("name") or "").strip() or f"sun_{len(self.out.lights)}",
                kind="directional",
                pos=(0.0, 0.0, 10.0),
                dir=(-0.5, 0.1, -0.9),
                diffuse=(0.8, 0.8, 0.8),
                specular=(0.2, 0.2, 0.2),
            )
        )

    def physics(self, element: ET.Element) -> None:
        for child in element:
            if child.tag == "max_step_size":
                (step,) = self.r.floats(child, 1, (0.001,))
                self.out.physics["timestep"] = step
            elif child.tag in _GAZEBO_SOLVER:
                self.r.gazebo_only(child, "Gazebo's own solver or loop setting; MuJoCo steps")
            else:
                self.r.warn(child, "physics setting not supported; MuJoCo defaults are used")

    def gravity(self, element: ET.Element) -> None:
        gx, gy, gz = self.r.floats(element, 3, (0.0, 0.0, -9.8))
        self.out.physics["gravity"] = (gx, gy, gz)

    def scene(self, element: ET.Element) -> None:
        for child in element:
            if child.tag == "ambient":
                r, g, b, _ = self.r.colour(child)
                self.out.headlight["ambient"] = (r, g, b)
            elif child.tag == "shadows":
                self.r.gazebo_only(child, "shadows are always off in visnav's cameras")
            elif child.tag in _GAZEBO_CLIENT_SCENE:
                self.r.gazebo_only(child, "drawn by Gazebo's client only")
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
            vector = self.r.floats(direction, 3, (0.0, 0.0, -1.0))
            kwargs["dir"] = tuple(float(v) for v in rot @ np.array(vector))
        for tag in ("diffuse", "specular"):
            child = element.find(tag)
            if child is not None:
                handled.add(tag)
                default = (1.0, 1.0, 1.0, 1.0) if tag == "diffuse" else (0.1, 0.1, 0.1, 1.0)
                kwargs[tag] = self.r.colour(child, default)[:3]
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

    def model(
        self,
        element: ET.Element,
        parent: Pose | None = None,
        *,
        scope: str = "",
        static: bool = False,
    ) -> None:
        name = scope + (element.get("name") or f"model_{len(self.out.shapes)}")
        pose = self.r.pose(element)
        if parent is not None:
            pose = compose(parent, pose)
        static = self.r.boolean(element.find("static"), default=static)
        if not static and not any(c.tag in ("model", "include") for c in element):
            self.r.warn(element, f"model {name!r} is not static; placed as static geometry")
        for child in element:
            if child.tag == "link":
                self.link(child, name, pose)
            elif child.tag == "model":
                self.model(child, pose, scope=f"{name}::", static=static)
            elif child.tag == "include":
                self.include(child, pose, scope=f"{name}::", static=static)
            elif child.tag not in ("pose", "static", "allow_auto_disable", "self_collide"):
                self.r.warn(child, f"model element not supported (model {name!r}); skipped")

    def link(self, element: ET.Element, model: str, model_pose: Pose) -> None:
        link = element.get("name") or "link"
        pose = compose(model_pose, self.r.pose(element))
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

    def geometry(self, element: ET.Element, link_pose: Pose, name: str) -> Shape | None:
        is_visual = element.tag == "visual"
        rot, pos = compose(link_pose, self.r.pose(element))
        allowed = ("pose", "geometry", "material") if is_visual else ("pose", "geometry")
        quiet = ("cast_shadows", "max_contacts", "surface", "laser_retro", "transparency", "meta")
        for child in element:
            if child.tag not in allowed and child.tag not in quiet:
                self.r.warn(child, f"{element.tag} setting not supported ({name}); skipped")
        material = self.material(element.find("material"), name) if is_visual else None
        geometry = element.find("geometry")
        if geometry is None or len(geometry) == 0:
            raise self.r.error(element, f"{name}: missing <geometry> with a shape inside")
        shape_el = geometry[0]
        is_mesh = shape_el.tag == "mesh"
        common: dict[str, Any] = {
            "name": name,
            "pos": tuple(float(v) for v in pos),
            "rpy": rpy_of(rot),
            "rgba": material if material is not None or is_mesh else _DEFAULT_RGBA,
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
        if not uri:
            self.r.warn(shape_el, "mesh without a <uri>; skipped")
            return None
        path = self.res.mesh_file(uri, self.r.base_dir, self.r.where(shape_el))
        if path is None:  # its model is missing: reported with the other missing models
            return None
        sx, sy, sz = self.r.child_floats(shape_el, "scale", 3, (1.0, 1.0, 1.0))
        for child in shape_el:
            if child.tag not in ("uri", "scale"):
                self.r.warn(child, "mesh setting not supported (submesh); the whole mesh is used")
        try:
            data = load_mesh(path, (sx, sy, sz), cache=self.meshes)
        except MeshFileError as exc:
            raise WorldError(str(exc)) from None
        for text in data.warnings:
            if text not in self.r.warnings:
                self.r.note(text)
        return Mesh(
            file=str(path),
            scale=(sx, sy, sz),
            bounds=data.bounds,
            parts=data.parts,
            **common,
        )

    def material(
        self, element: ET.Element | None, name: str
    ) -> tuple[float, float, float, float] | None:
        """The visual's colour, or None when its material gives none."""
        if element is None:
            return None
        rgba: tuple[float, float, float, float] | None = None
        script_rgba: tuple[float, float, float, float] | None = None
        for child in element:
            if child.tag == "diffuse" or (child.tag == "ambient" and rgba is None):
                rgba = self.r.colour(child)
            elif child.tag == "script":
                script = (child.findtext("name") or "").strip()
                uris = [(u.text or "").strip() for u in child.findall("uri")]
                script_rgba = self.res.script_colour(uris, script, self.r.base_dir)
                for text in self.res.warnings:
                    if text not in self.r.warnings:
                        self.r.note(text)
                if script_rgba is None:
                    self.r.warn(child, f"material script {script!r} unknown ({name}); grey used")
            elif child.tag not in ("specular", "emissive", "ambient", "lighting", "shader"):
                self.r.warn(child, f"material element not supported ({name}); skipped")
        # Gazebo: a script material is the base; <ambient>/<diffuse> set after it override
        return rgba or script_rgba


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
    packages: Mapping[str, str | os.PathLike[str]] | None = None,
    model_path: ModelPath | None = None,
    skip_missing_models: bool = False,
) -> WorldDescription:
    """Parse SDF text (the subset in the module docstring) into a world.

    Args:
        text: The SDF document.
        source: File name used in messages.
        base_dir: Directory relative mesh paths start from.
        seed: The world's seed (SDF has none; default 0).
        packages: Package name -> directory: their exported model paths and
            ``package://`` URIs (see :mod:`visnav.description.model_path`).
        model_path: Where ``model://`` names are found; default
            :func:`~visnav.description.model_path.model_path` of ``packages``, the
            package holding ``source`` and the environment.
        skip_missing_models: Load the world without the models that are not found
            (one warning) instead of raising.

    Returns:
        The world; ``world.warnings`` lists everything skipped (each also
        issued as a :class:`WorldWarning`).

    Raises:
        WorldError: Malformed XML (with line), no ``<world>`` or ``<model>``,
            invalid numbers or sizes, models not found (all named in one error).
    """
    reader = SdfReader(source, Path(base_dir) if base_dir is not None else None)
    root = reader.parse(text)
    if root.tag != "sdf":
        raise reader.error(root, "the root element must be <sdf>")
    if model_path is None:
        world_file = source if base_dir is not None and Path(source).is_file() else None
        model_path = find_model_path(packages=packages, world_file=world_file)
    resources = SdfResources(
        model_path=model_path,
        parse=reader.parse,
        packages={name: Path(d) for name, d in (packages or {}).items()},
    )
    parser = _WorldParser(reader, resources)
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
    if resources.missing:
        error = missing_models_error(resources.missing, model_path, source)
        if not skip_missing_models:
            raise error
        reader.note(f"{error} -- skipped (skip_missing_models)")
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


def load_sdf_world(
    path: str | Path,
    *,
    seed: int | None = None,
    packages: Mapping[str, str | os.PathLike[str]] | None = None,
    skip_missing_models: bool = False,
) -> WorldDescription:
    """Read an SDF world file (see :func:`parse_sdf_world`).

    Args:
        path: The ``.sdf`` / ``.world`` file.
        seed: The world's seed.
        packages: Package name -> directory (model paths they export, ``package://``).
        skip_missing_models: Load the rest when models are not found (one warning).

    Returns:
        The world.

    Raises:
        WorldError: The file cannot be read or is invalid.
    """
    file = Path(path)
    text = read_text(file, what="the SDF world", error=WorldError)
    return parse_sdf_world(
        text,
        source=str(file),
        base_dir=file.parent,
        seed=seed,
        packages=packages,
        skip_missing_models=skip_missing_models,
    )
