"""The YAML world format: parsing with file and line in every error.

The format is documented in :mod:`visnav.description.world` and ``docs/worlds.md``;
:func:`world_from_dict` also validates the documents the built-in generators make.
"""

from __future__ import annotations

import difflib
import math
import zlib
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar, cast

import numpy as np

from visnav.description.errors import MeshFileError, WorldError
from visnav.description.mesh_files import mesh_vertices
from visnav.description.worldmodel import (
    Box,
    Cylinder,
    Ground,
    Headlight,
    Light,
    Material,
    Mesh,
    Physics,
    Shape,
    Sphere,
    Texture,
    WorldDescription,
)
from visnav.safe_yaml import load_yaml_lines
from visnav.textfile import read_text

if TYPE_CHECKING:
    import os
    from collections.abc import Callable, Mapping

__all__ = ["DEFAULT_GROUND_MATERIAL", "load_yaml_world", "mesh_bounds", "world_from_dict"]

_TOP_KEYS = (
    "name",
    "seed",
    "physics",
    "ground",
    "headlight",
    "textures",
    "materials",
    "objects",
    "lights",
    "metadata",
)
_COMMON_SHAPE_KEYS = (
    "type",
    "name",
    "pos",
    "rpy",
    "yaw",
    "material",
    "rgba",
    "visual",
    "collision",
)
_SHAPE_KEYS: dict[str, tuple[str, ...]] = {
    "box": ("size",),
    "cylinder": ("radius", "length"),
    "sphere": ("radius",),
    "mesh": ("file", "scale"),
}
_TEXTURE_KEYS = (
    "type",
    "rgb1",
    "rgb2",
    "width",
    "height",
    "seed",
    "scale",
    "mark",
    "markrgb",
    "random",
    "file",
)
_MATERIAL_KEYS = (
    "texture",
    "rgba",
    "tile",
    "texrepeat",
    "specular",
    "shininess",
    "reflectance",
    "emission",
)
_LIGHT_KEYS = (
    "name",
    "type",
    "pos",
    "dir",
    "diffuse",
    "ambient",
    "specular",
    "attenuation",
    "cutoff",
)
_GROUND_KEYS = ("size", "z", "material", "texture", "tile", "rgba")
_HEADLIGHT_KEYS = ("active", "ambient", "diffuse", "specular")
_PHYSICS_KEYS = ("timestep", "gravity", "integrator")

DEFAULT_GROUND_MATERIAL = "ground_default"

_T = TypeVar("_T")


class _Reader:
    """Typed access to a parsed document with errors that name file, line and field."""

    def __init__(self, source: str, base_dir: Path | None) -> None:
        self.source = source
        self.base_dir = base_dir

    def error(self, node: object, path: str, message: str) -> WorldError:
        line = getattr(node, "line", None)
        where = f"{self.source}:{line}" if line is not None else self.source
        return WorldError(f"{where}: {path}: {message}")

    def mapping(self, node: object, path: str, allowed: tuple[str, ...]) -> Mapping[str, Any]:
        if not isinstance(node, dict):
            raise self.error(node, path, f"expected a mapping, got {type(node).__name__} {node!r}")
        for key in node:
            if key not in allowed:
                close = difflib.get_close_matches(str(key), allowed, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise self.error(
                    node, path, f"unknown key {key!r}{hint} (allowed: {', '.join(allowed)})"
                )
        return cast("Mapping[str, Any]", node)

    def number(self, parent: object, path: str, value: object) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(parent, path, f"expected a number, got {value!r}")
        if not math.isfinite(value):
            raise self.error(parent, path, f"expected a finite number, got {value!r}")
        return float(value)

    def integer(self, parent: object, path: str, value: object) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(parent, path, f"expected an integer, got {value!r}")
        return value

    def boolean(self, parent: object, path: str, value: object) -> bool:
        if not isinstance(value, bool):
            raise self.error(parent, path, f"expected true or false, got {value!r}")
        return value

    def string(self, parent: object, path: str, value: object) -> str:
        if not isinstance(value, str) or not value:
            raise self.error(parent, path, f"expected a non-empty string, got {value!r}")
        return value

    def vector(self, parent: object, path: str, value: object, n: int) -> tuple[float, ...]:
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise self.error(parent, path, f"expected a list of {n} numbers, got {value!r}")
        return tuple(self.number(parent, path, v) for v in value)

    def vec2(self, parent: object, path: str, value: object) -> tuple[float, float]:
        x, y = self.vector(parent, path, value, 2)
        return (x, y)

    def vec3(self, parent: object, path: str, value: object) -> tuple[float, float, float]:
        x, y, z = self.vector(parent, path, value, 3)
        return (x, y, z)

    def rgba(self, parent: object, path: str, value: object) -> tuple[float, float, float, float]:
        if isinstance(value, (list, tuple)) and len(value) == 3:
            value = [*value, 1.0]
        r, g, b, a = self.vector(parent, path, value, 4)
        return (r, g, b, a)

    def resolve(self, file: str) -> Path:
        path = Path(file).expanduser()
        if not path.is_absolute() and self.base_dir is not None:
            path = self.base_dir / path
        return path


def _derived_seed(world_seed: int, name: str) -> int:
    state = np.random.SeedSequence([world_seed & 0xFFFFFFFF, zlib.crc32(name.encode())])
    return int(state.generate_state(1)[0] & 0x7FFFFFFF)


def _call(reader: _Reader, node: object, path: str, build: Callable[[], Any]) -> Any:
    """Run a model constructor; give its WorldError the file and line."""
    try:
        return build()
    except WorldError as exc:
        raise reader.error(node, path, str(exc)) from None


def _parse_texture(reader: _Reader, name: str, node: object, world_seed: int) -> Texture:
    path = f"textures.{name}"
    m = reader.mapping(node, path, _TEXTURE_KEYS)
    if "type" not in m:
        raise reader.error(node, path, "missing 'type' (checker, gradient, flat, noise or file)")
    kwargs: dict[str, Any] = {"name": name, "kind": reader.string(node, f"{path}.type", m["type"])}
    for key in ("rgb1", "rgb2", "markrgb"):
        if key in m:
            kwargs[key] = reader.vec3(node, f"{path}.{key}", m[key])
    for key in ("width", "height", "scale"):
        if key in m:
            kwargs[key] = reader.integer(node, f"{path}.{key}", m[key])
    kwargs["seed"] = (
        reader.integer(node, f"{path}.seed", m["seed"])
        if "seed" in m
        else _derived_seed(world_seed, name)
    )
    if "mark" in m:
        kwargs["mark"] = reader.string(node, f"{path}.mark", m["mark"])
    if "random" in m:
        kwargs["random"] = reader.number(node, f"{path}.random", m["random"])
    if "file" in m:
        file = reader.resolve(reader.string(node, f"{path}.file", m["file"]))
        if not file.is_file():
            raise reader.error(node, f"{path}.file", f"image {str(file)!r} does not exist")
        kwargs["file"] = str(file)
    return cast("Texture", _call(reader, node, path, lambda: Texture(**kwargs)))


def _parse_material(reader: _Reader, name: str, node: object) -> Material:
    path = f"materials.{name}"
    m = reader.mapping(node, path, _MATERIAL_KEYS)
    kwargs: dict[str, Any] = {"name": name}
    if "texture" in m:
        kwargs["texture"] = reader.string(node, f"{path}.texture", m["texture"])
    if "rgba" in m:
        kwargs["rgba"] = reader.rgba(node, f"{path}.rgba", m["rgba"])
    if "tile" in m:
        kwargs["tile"] = reader.number(node, f"{path}.tile", m["tile"])
    if "texrepeat" in m:
        kwargs["texrepeat"] = reader.vec2(node, f"{path}.texrepeat", m["texrepeat"])
    for key in ("specular", "shininess", "reflectance", "emission"):
        if key in m:
            kwargs[key] = reader.number(node, f"{path}.{key}", m[key])
    return cast("Material", _call(reader, node, path, lambda: Material(**kwargs)))


def mesh_bounds(
    file: str | os.PathLike[str], scale: tuple[float, float, float]
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Axis-aligned bounds of a mesh file's scaled vertices, in the file's own frame.

    Args:
        file: STL, OBJ or MSH file (formats MuJoCo reads).
        scale: Per-axis scale applied to the vertices.

    Returns:
        ``(min_corner, max_corner)``.

    Raises:
        WorldError: The file is missing, not STL / OBJ / MSH, or malformed
            (:func:`~visnav.description.mesh_files.mesh_vertices`).
    """
    if not Path(file).is_file():
        msg = f"mesh file {str(file)!r} does not exist; give a path relative to the world file"
        raise WorldError(msg)
    try:
        vertices = mesh_vertices(file)
    except MeshFileError as exc:
        raise WorldError(str(exc)) from None
    original = vertices * np.asarray(scale, dtype=np.float64)
    lo = original.min(axis=0)
    hi = original.max(axis=0)
    return (float(lo[0]), float(lo[1]), float(lo[2])), (float(hi[0]), float(hi[1]), float(hi[2]))


def _parse_shape(reader: _Reader, index: int, node: object) -> Shape:
    path = f"objects[{index}]"
    if not isinstance(node, dict):
        raise reader.error(node, path, f"expected a mapping, got {node!r}")
    if "type" not in node:
        raise reader.error(node, path, f"missing 'type' (one of {', '.join(_SHAPE_KEYS)})")
    kind = node["type"]
    if kind not in _SHAPE_KEYS:
        close = difflib.get_close_matches(str(kind), list(_SHAPE_KEYS), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise reader.error(
            node,
            f"{path}.type",
            f"unknown shape type {kind!r}{hint} (supported: {', '.join(_SHAPE_KEYS)})",
        )
    m = reader.mapping(node, path, _COMMON_SHAPE_KEYS + _SHAPE_KEYS[kind])
    name = reader.string(node, f"{path}.name", m["name"]) if "name" in m else f"{kind}_{index}"
    path = f"{path} ({name})"
    kwargs: dict[str, Any] = {"name": name}
    if "pos" in m:
        kwargs["pos"] = reader.vec3(node, f"{path}.pos", m["pos"])
    if "rpy" in m and "yaw" in m:
        raise reader.error(node, path, "give either 'rpy' or 'yaw', not both")
    if "rpy" in m:
        kwargs["rpy"] = reader.vec3(node, f"{path}.rpy", m["rpy"])
    if "yaw" in m:
        kwargs["rpy"] = (0.0, 0.0, reader.number(node, f"{path}.yaw", m["yaw"]))
    if "material" in m:
        kwargs["material"] = reader.string(node, f"{path}.material", m["material"])
    if "rgba" in m:
        kwargs["rgba"] = reader.rgba(node, f"{path}.rgba", m["rgba"])
    for key in ("visual", "collision"):
        if key in m:
            kwargs[key] = reader.boolean(node, f"{path}.{key}", m[key])
    for key in _SHAPE_KEYS[kind]:
        if key not in m and key != "scale":
            raise reader.error(node, path, f"{kind} needs '{key}'")
    if kind == "box":
        kwargs["size"] = reader.vec3(node, f"{path}.size", m["size"])
        return cast("Shape", _call(reader, node, path, lambda: Box(**kwargs)))
    if kind == "cylinder":
        kwargs["radius"] = reader.number(node, f"{path}.radius", m["radius"])
        kwargs["length"] = reader.number(node, f"{path}.length", m["length"])
        return cast("Shape", _call(reader, node, path, lambda: Cylinder(**kwargs)))
    if kind == "sphere":
        kwargs["radius"] = reader.number(node, f"{path}.radius", m["radius"])
        return cast("Shape", _call(reader, node, path, lambda: Sphere(**kwargs)))
    scale_value = m.get("scale", 1.0)
    if isinstance(scale_value, (int, float)) and not isinstance(scale_value, bool):
        s = reader.number(node, f"{path}.scale", scale_value)
        scale = (s, s, s)
    else:
        scale = reader.vec3(node, f"{path}.scale", scale_value)
    if not all(v > 0.0 for v in scale):
        raise reader.error(node, f"{path}.scale", f"expected scales > 0, got {list(scale)}")
    file = reader.resolve(reader.string(node, f"{path}.file", m["file"]))
    kwargs["file"] = str(file)
    kwargs["scale"] = scale
    kwargs["bounds"] = _call(reader, node, f"{path}.file", lambda: mesh_bounds(file, scale))
    return cast("Shape", _call(reader, node, path, lambda: Mesh(**kwargs)))


def _parse_light(reader: _Reader, index: int, node: object) -> Light:
    path = f"lights[{index}]"
    m = reader.mapping(node, path, _LIGHT_KEYS)
    kwargs: dict[str, Any] = {
        "name": reader.string(node, f"{path}.name", m["name"]) if "name" in m else f"light_{index}"
    }
    if "type" in m:
        kwargs["kind"] = reader.string(node, f"{path}.type", m["type"])
    for key in ("pos", "dir", "diffuse", "ambient", "specular", "attenuation"):
        if key in m:
            kwargs[key] = reader.vec3(node, f"{path}.{key}", m[key])
    if "cutoff" in m:
        kwargs["cutoff"] = reader.number(node, f"{path}.cutoff", m["cutoff"])
    return cast("Light", _call(reader, node, path, lambda: Light(**kwargs)))


def _fields(
    node: Mapping[str, Any], section: str, readers: Mapping[str, Callable[[Any, str, Any], Any]]
) -> dict[str, Any]:
    """The keys of ``readers`` present in ``node``, each read by its reader, in that order."""
    return {
        key: read(node, f"{section}.{key}", node[key])
        for key, read in readers.items()
        if key in node
    }


def _named(
    reader: _Reader, doc: Mapping[str, Any], key: str, parse: Callable[[str, Any], _T]
) -> list[_T]:
    """``doc[key]``, a mapping of name -> item (``textures``, ``materials``), parsed in order."""
    node = doc.get(key)
    if node is None:
        return []
    if not isinstance(node, dict):
        raise reader.error(doc, key, f"expected a mapping of name -> {key[:-1]}")
    return [parse(str(k), v) for k, v in node.items()]


def _parse_sections(reader: _Reader, doc: Mapping[str, Any], world_seed: int) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if "physics" in doc:
        pm = reader.mapping(doc["physics"], "physics", _PHYSICS_KEYS)
        kw = _fields(
            pm,
            "physics",
            {"timestep": reader.number, "gravity": reader.vec3, "integrator": reader.string},
        )
        out["physics"] = _call(reader, pm, "physics", lambda: Physics(**kw))
    if "headlight" in doc:
        hm = reader.mapping(doc["headlight"], "headlight", _HEADLIGHT_KEYS)
        hk = _fields(
            hm,
            "headlight",
            {
                "active": reader.boolean,
                "ambient": reader.vec3,
                "diffuse": reader.vec3,
                "specular": reader.vec3,
            },
        )
        out["headlight"] = _call(reader, hm, "headlight", lambda: Headlight(**hk))
    textures: list[Texture] = _named(
        reader, doc, "textures", lambda k, v: _parse_texture(reader, k, v, world_seed)
    )
    materials: list[Material] = _named(
        reader, doc, "materials", lambda k, v: _parse_material(reader, k, v)
    )
    ground: Ground | None = Ground(material=DEFAULT_GROUND_MATERIAL)
    if "ground" in doc:
        if doc["ground"] is None or doc["ground"] is False:
            ground = None
        else:
            gm = reader.mapping(doc["ground"], "ground", _GROUND_KEYS)
            gk = _fields(
                gm,
                "ground",
                {
                    "size": reader.vec2,
                    "z": reader.number,
                    "material": reader.string,
                    "rgba": reader.rgba,
                },
            )
            if "texture" in gm:
                if "material" in gm:
                    raise reader.error(
                        gm, "ground", "give either 'material' or 'texture', not both"
                    )
                texture = reader.string(gm, "ground.texture", gm["texture"])
                tile = reader.number(gm, "ground.tile", gm.get("tile", 1.0))
                materials.append(
                    _call(
                        reader,
                        gm,
                        "ground",
                        lambda: Material(name="ground", texture=texture, tile=tile),
                    )
                )
                gk["material"] = "ground"
            elif "tile" in gm:
                raise reader.error(gm, "ground.tile", "'tile' goes with 'texture'")
            if "material" not in gk and "rgba" not in gk:
                gk["material"] = DEFAULT_GROUND_MATERIAL
            ground = _call(reader, gm, "ground", lambda: Ground(**gk))
    if ground is not None and ground.material == DEFAULT_GROUND_MATERIAL:
        textures.append(
            Texture(
                name=DEFAULT_GROUND_MATERIAL,
                kind="checker",
                rgb1=(0.55, 0.55, 0.52),
                rgb2=(0.35, 0.36, 0.38),
                mark="random",
                random=0.03,
                markrgb=(0.9, 0.9, 0.9),
            )
        )
        materials.append(
            Material(name=DEFAULT_GROUND_MATERIAL, texture=DEFAULT_GROUND_MATERIAL, tile=2.0)
        )
    out.update(ground=ground, textures=tuple(textures), materials=tuple(materials))
    shapes: list[Shape] = []
    if doc.get("objects") is not None:
        objs = doc["objects"]
        if not isinstance(objs, list):
            raise reader.error(doc, "objects", "expected a list of shapes")
        shapes = [_parse_shape(reader, i, o) for i, o in enumerate(objs)]
    out["shapes"] = tuple(shapes)
    if doc.get("lights") is not None:
        lights = doc["lights"]
        if not isinstance(lights, list):
            raise reader.error(doc, "lights", "expected a list of lights")
        out["lights"] = tuple(_parse_light(reader, i, n) for i, n in enumerate(lights))
    else:
        out["lights"] = (Light(name="sun", dir=(-0.4, 0.25, -1.0), diffuse=(0.5, 0.5, 0.5)),)
    return out


def world_from_dict(
    data: Mapping[str, Any],
    *,
    source: str = "<dict>",
    seed: int | None = None,
    base_dir: str | os.PathLike[str] | None = None,
) -> WorldDescription:
    """Build a world from a parsed YAML document (or a generator's dict).

    Args:
        data: The document (see the module docstring for the format).
        source: Name used in error messages (a path, ``builtin:<name>``).
        seed: Overrides the document's ``seed``.
        base_dir: Directory that relative mesh and image paths start from.

    Returns:
        The validated world.

    Raises:
        WorldError: Unknown keys, wrong types, negative sizes, unknown shape
            types, dangling material or texture names.
    """
    reader = _Reader(source, Path(base_dir) if base_dir is not None else None)
    doc = reader.mapping(data, "world", _TOP_KEYS)
    name = reader.string(doc, "name", doc["name"]) if "name" in doc else Path(source).stem
    world_seed = reader.integer(doc, "seed", doc["seed"]) if "seed" in doc else 0
    if seed is not None:
        world_seed = int(seed)
    sections = _parse_sections(reader, doc, world_seed)
    metadata = doc.get("metadata") or {}
    if not isinstance(metadata, dict):
        raise reader.error(doc, "metadata", f"expected a mapping, got {metadata!r}")
    return cast(
        "WorldDescription",
        _call(
            reader,
            doc,
            "world",
            lambda: WorldDescription(
                name=name,
                seed=world_seed,
                source=source,
                metadata=dict(metadata),
                **sections,
            ),
        ),
    )


def load_yaml_world(path: Path, *, seed: int | None = None) -> WorldDescription:
    """Read a YAML world file.

    Args:
        path: The file.
        seed: Overrides the file's ``seed``.

    Returns:
        The world.

    Raises:
        WorldError: Unreadable file, malformed YAML (with line and column) or invalid content.
    """
    text = read_text(path, what="the world file", error=WorldError)
    data = load_yaml_lines(
        text, source=str(path), what="the world file", error=WorldError, string_keys=True
    )
    if data is None:
        msg = f"{path}: the world file is empty; it needs at least 'objects' or 'ground'"
        raise WorldError(msg)
    return world_from_dict(data, source=str(path), seed=seed, base_dir=path.parent)
