"""Mesh files read without MuJoCo: Collada, OBJ, STL and MuJoCo's MSH, with their colours.

Worlds and robots name mesh files as Gazebo reads them; :func:`load_mesh` turns one into
triangles in metres, grouped into :class:`MeshPart` of one colour each, which the
simulator hands to MuJoCo as vertex data (MuJoCo itself reads neither Collada nor
materials):

* Collada ``.dae`` (pycollada): every ``<instance_geometry>`` of the visual scene with
  its node transforms; ``<unit meter=...>`` scales the mesh, as Gazebo does;
  ``<up_axis>`` is ignored, as Gazebo ignores it (a Y_UP file shows lying down there too);
  each primitive's colour is its material's diffuse colour, or the mean colour of its
  diffuse texture image (looked up beside the file and in ``../materials/textures``,
  Gazebo's places); a texture that is not found is one warning and the part is drawn
  in the diffuse colour of the effect (grey if none);
* Wavefront ``.obj`` (trimesh, with its ``.mtl`` colours) and ``.stl`` (binary or ASCII,
  trimesh; no colour);
* MuJoCo's ``.msh`` (four int32 counts, float32 vertices, normals, texture coordinates,
  int32 faces).

Every problem is one :class:`~visnav.description.errors.MeshFileError` naming the file
and what is wrong.
"""

from __future__ import annotations

import io
import os
import re
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from visnav.description.errors import MeshFileError

if TYPE_CHECKING:
    from collections.abc import MutableMapping

__all__ = ["MESH_SUFFIXES", "MeshData", "MeshPart", "load_mesh", "mesh_vertices"]

MESH_SUFFIXES = (".dae", ".obj", ".stl", ".msh")
"""Mesh formats read here (Gazebo's Collada, OBJ, STL, and MuJoCo's MSH)."""

_MAX_BYTES = 512 * 1024 * 1024  # a mesh larger than this is refused rather than read
_MAX_TRIANGLES = 2_000_000

RGBA = tuple[float, float, float, float]


@dataclass(frozen=True, eq=False)
class MeshPart:
    """Triangles of one colour of a mesh, in the mesh frame, in metres.

    Attributes:
        vertices: ``(N, 3)`` float64 positions (units, node transforms and scale applied).
        faces: ``(M, 3)`` int64 vertex indices.
        rgba: The part's colour from the file, or None (the file has none).
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    rgba: RGBA | None = None


@dataclass(frozen=True, eq=False)
class MeshData:
    """A loaded mesh: its parts (one per colour) and what went wrong while reading it."""

    file: str
    parts: tuple[MeshPart, ...]
    warnings: tuple[str, ...] = ()

    @property
    def vertices(self) -> NDArray[np.float64]:
        """All vertices ``(N, 3)``."""
        return np.concatenate([p.vertices for p in self.parts], axis=0)

    @property
    def triangles(self) -> NDArray[np.float64]:
        """All triangles ``(M, 3, 3)``."""
        return np.concatenate([p.vertices[p.faces] for p in self.parts], axis=0)

    @property
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Axis-aligned bounds (min corner, max corner) of the vertices."""
        v = self.vertices
        lo, hi = v.min(axis=0), v.max(axis=0)
        return (
            (float(lo[0]), float(lo[1]), float(lo[2])),
            (float(hi[0]), float(hi[1]), float(hi[2])),
        )

    def scaled(self, scale: tuple[float, float, float]) -> MeshData:
        """The mesh scaled per axis (a negative factor mirrors it; faces keep their order)."""
        if scale == (1.0, 1.0, 1.0):
            return self
        factor = np.asarray(scale, dtype=np.float64)
        flip = bool(np.prod(np.sign(factor)) < 0)
        parts = tuple(
            MeshPart(
                vertices=p.vertices * factor,
                faces=p.faces[:, ::-1].copy() if flip else p.faces,
                rgba=p.rgba,
            )
            for p in self.parts
        )
        return MeshData(file=self.file, parts=parts, warnings=self.warnings)


def _error(name: str, text: str) -> MeshFileError:
    return MeshFileError(f"mesh file {name!r}: {text}")


def _msh(data: bytes, name: str) -> list[MeshPart]:
    if len(data) < 16:
        msg = f"mesh file {name!r}: {len(data)} bytes, too short for an MSH header (16 bytes)"
        raise MeshFileError(msg)
    nvert, nnormal, ntex, nface = struct.unpack_from("<4i", data, 0)
    expected = 16 + 4 * (3 * nvert + 3 * nnormal + 2 * ntex + 3 * nface)
    if min(nvert, nnormal, ntex, nface) < 0 or nvert == 0 or len(data) != expected:
        msg = (
            f"mesh file {name!r}: MSH header counts ({nvert}, {nnormal}, {ntex}, {nface}) do "
            f"not match its {len(data)} bytes; write it again with MuJoCo's MSH layout"
        )
        raise MeshFileError(msg)
    vertices = (
        np.frombuffer(data, dtype="<f4", count=3 * nvert, offset=16)
        .reshape(nvert, 3)
        .astype(np.float64)
    )
    offset = 16 + 4 * (3 * nvert + 3 * nnormal + 2 * ntex)
    faces = np.frombuffer(data, dtype="<i4", count=3 * nface, offset=offset).reshape(nface, 3)
    if nface and (faces.min() < 0 or faces.max() >= nvert):
        raise _error(name, f"an MSH face index is outside 0..{nvert - 1}")
    return [MeshPart(vertices=vertices, faces=faces.astype(np.int64))]


def _check_obj(text: str, name: str) -> None:
    """Refuse malformed ``v`` lines with a message naming the line (trimesh would guess)."""
    count = 0
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if words and words[0] == "v":
            if len(words) not in (4, 5, 7, 8):  # x y z [w] or x y z r g b [a]
                msg = f"mesh file {name!r}:{number}: 'v' needs x y z [w], got {words[1:]}"
                raise MeshFileError(msg)
            try:
                values = [float(w) for w in words[1:4]]
            except ValueError:
                msg = f"mesh file {name!r}:{number}: vertex {' '.join(words[1:])!r} is not numbers"
                raise MeshFileError(msg) from None
            if not all(np.isfinite(values)):
                raise _error(name, f"line {number}: a vertex coordinate is not finite")
            count += 1
    if count == 0:
        raise _error(name, "an OBJ file without 'v' vertex lines")


def _texture_colour(path: str, base: Path, notes: list[str], name: str) -> RGBA | None:
    from visnav.description.gazebo_materials import image_mean_colour  # noqa: PLC0415

    file = Path(path.removeprefix("file://"))
    candidates = [file] if file.is_absolute() else [base / file]
    candidates += [base.parent / "materials" / "textures" / file.name, base / file.name]
    for candidate in candidates:
        if candidate.is_file():
            mean = image_mean_colour(candidate)
            if mean is not None:
                return mean
    notes.append(
        f"mesh file {name!r}: texture {path!r} not found or unreadable (looked beside the "
        "file and in ../materials/textures); drawn untextured"
    )
    return None


def _collada_colour(
    primitive: Any, base: Path, notes: list[str], name: str, seen: set[str]
) -> RGBA | None:
    material = getattr(primitive, "material", None)
    effect = getattr(material, "effect", None)
    diffuse = getattr(effect, "diffuse", None)
    if isinstance(diffuse, tuple) and len(diffuse) >= 3:
        values = [min(max(float(v), 0.0), 1.0) for v in (*diffuse[:4], 1.0)[:4]]
        return (values[0], values[1], values[2], values[3])
    image = getattr(getattr(getattr(diffuse, "sampler", None), "surface", None), "image", None)
    path = getattr(image, "path", None)
    if isinstance(path, str) and path:
        if path in seen:
            return None
        colour = _texture_colour(path, base, notes, name)
        if colour is None:
            seen.add(path)
        return colour
    return None


def _collada(path: Path, name: str, notes: list[str]) -> list[MeshPart]:
    import collada  # type: ignore[import-untyped]  # noqa: PLC0415  (pycollada, untyped)
    from collada import common  # noqa: PLC0415

    try:
        with warnings.catch_warnings():  # pycollada uses numpy.matrix
            warnings.simplefilter("ignore", PendingDeprecationWarning)
            return _collada_parts(collada, common, path, name, notes)
    except MeshFileError:
        raise
    except Exception as exc:  # noqa: BLE001  (pycollada raises many types on broken files)
        raise _error(name, f"not a readable Collada file ({type(exc).__name__}: {exc})") from None


_ATTRIBUTE = re.compile(rb'="([^"]*)"')


def _escape_attribute(match: re.Match[bytes]) -> bytes:
    return b'="' + match[1].replace(b"<", b"&lt;").replace(b">", b"&gt;") + b'"'


def _open_collada(collada: Any, common: Any, path: Path, name: str, notes: list[str]) -> Any:
    """The parsed Collada document, read as leniently as Gazebo reads it.

    A raw ``<`` or ``>`` in an attribute value (STL converters write ``id="<STL_BINARY>"``),
    which Gazebo's TinyXML accepts, is escaped, with one note.
    """
    ignore = [common.DaeUnsupportedError, common.DaeBrokenRefError]
    try:
        return collada.Collada(str(path), ignore=ignore)
    except common.DaeMalformedError as exc:
        if "XML Parsing Error" not in str(exc):
            raise
        data = path.read_bytes()
        repaired = _ATTRIBUTE.sub(_escape_attribute, data)
        if repaired == data:
            raise
        document = collada.Collada(io.BytesIO(repaired), ignore=ignore)
        notes.append(
            f"mesh {name!r}: '<' or '>' inside attribute values is not XML; read as Gazebo's "
            "parser reads it (fix the file: write &lt; and &gt;)"
        )
        return document


def _collada_parts(
    collada: Any, common: Any, path: Path, name: str, notes: list[str]
) -> list[MeshPart]:
    document = _open_collada(collada, common, path, name, notes)
    meter = float(document.assetInfo.unitmeter or 1.0)
    scene = document.scene
    if scene is None:
        raise _error(name, "a Collada file without a <scene>; export it with a scene")
    missing: set[str] = set()
    colour_of: dict[int, RGBA | None] = {}
    by_colour: dict[RGBA | None, list[tuple[NDArray[np.float64], NDArray[np.int64]]]] = {}
    for bound in scene.objects("geometry"):
        for primitive in bound.primitives():
            if hasattr(primitive, "triangleset"):
                primitive = primitive.triangleset()  # noqa: PLW2901
            index = getattr(primitive, "vertex_index", None)
            if index is None or primitive.vertex is None or np.shape(index)[-1:] != (3,):
                continue  # lines and points draw nothing solid
            vertices = np.asarray(primitive.vertex, dtype=np.float64).reshape(-1, 3)
            faces = np.asarray(primitive.vertex_index, dtype=np.int64).reshape(-1, 3)
            if len(faces) == 0:
                continue
            key = id(getattr(primitive, "material", None))
            if key not in colour_of:
                colour_of[key] = _collada_colour(primitive, path.parent, notes, name, missing)
            by_colour.setdefault(colour_of[key], []).append((vertices * meter, faces))
    return [_merge(rgba, chunks) for rgba, chunks in by_colour.items()]


def _merge(
    rgba: RGBA | None, chunks: list[tuple[NDArray[np.float64], NDArray[np.int64]]]
) -> MeshPart:
    vertices: list[NDArray[np.float64]] = []
    faces: list[NDArray[np.int64]] = []
    offset = 0
    for v, f in chunks:
        vertices.append(v)
        faces.append(f + offset)
        offset += len(v)
    return MeshPart(vertices=np.concatenate(vertices), faces=np.concatenate(faces), rgba=rgba)


def _trimesh_file(path: Path, name: str) -> list[MeshPart]:
    import trimesh  # noqa: PLC0415

    try:
        scene: Any = trimesh.load(str(path), force="scene")
        by_colour: dict[RGBA | None, list[tuple[NDArray[np.float64], NDArray[np.int64]]]] = {}
        for node in scene.graph.nodes_geometry:
            transform, geometry_name = scene.graph[node]
            geometry = scene.geometry[geometry_name]
            if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
                continue
            vertices = trimesh.transform_points(np.asarray(geometry.vertices), transform)
            rgba = _trimesh_colour(geometry) if path.suffix.lower() == ".obj" else None
            by_colour.setdefault(rgba, []).append(
                (np.asarray(vertices, dtype=np.float64), np.asarray(geometry.faces, np.int64))
            )
    except Exception as exc:  # noqa: BLE001  (trimesh raises many types on broken files)
        raise _error(name, f"not a readable mesh ({type(exc).__name__}: {exc})") from None
    return [_merge(rgba, chunks) for rgba, chunks in by_colour.items()]


def _trimesh_colour(geometry: Any) -> RGBA | None:
    visual = geometry.visual
    colour: Any = None
    if visual.kind == "texture":
        material = visual.material
        colour = getattr(material, "baseColorFactor", None)
        if colour is None:
            colour = getattr(material, "diffuse", None)
    elif visual.kind in ("vertex", "face"):
        colour = visual.main_color
    if colour is None:
        return None
    values = np.asarray(colour, dtype=np.float64).ravel()[:4] / 255.0
    if values.size == 3:
        values = np.append(values, 1.0)
    r, g, b, a = (float(v) for v in np.clip(values, 0.0, 1.0))
    return (r, g, b, a)


def load_mesh(
    file: str | os.PathLike[str],
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0),
    *,
    cache: MutableMapping[str, MeshData] | None = None,
) -> MeshData:
    """Read a Collada, OBJ, STL or MSH file into coloured triangle parts, in metres.

    Args:
        file: The mesh file.
        scale: Per-axis scale applied after the file's own units.
        cache: Meshes already read (by resolved path, unscaled), filled as files are read;
            pass one dict while loading one world so a mesh used twice is read once.

    Returns:
        The mesh, with warnings (a missing texture, ...).

    Raises:
        MeshFileError: A missing or unreadable file, another format, a malformed file,
            a non-finite vertex or a file without triangles.
    """
    path = Path(file)
    name = str(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        msg = (
            f"mesh file {name!r} has suffix {suffix or '(none)'!r}: expected one of "
            f"{', '.join(MESH_SUFFIXES)} (convert other formats with a mesh tool)"
        )
        raise MeshFileError(msg)
    key = str(path.resolve()) if path.exists() else name
    if cache is not None and key in cache:
        return cache[key].scaled(scale)
    try:
        size = path.stat().st_size
        if size > _MAX_BYTES:
            msg = f"mesh file {name!r} is {size} bytes: larger than {_MAX_BYTES}; simplify it"
            raise MeshFileError(msg)
        data = path.read_bytes() if suffix == ".msh" else b""
    except OSError as exc:
        msg = f"mesh file {name!r} cannot be read ({exc.strerror or exc}); check the path"
        raise MeshFileError(msg) from None
    notes: list[str] = []
    if suffix == ".msh":
        parts = _msh(data, name)
    elif suffix == ".dae":
        parts = _collada(path, name, notes)
    else:
        if suffix == ".obj":
            _check_obj(path.read_bytes().decode("latin-1"), name)
        parts = _trimesh_file(path, name)
    parts = [p for p in parts if len(p.faces)]
    if not parts:
        raise _error(name, "no triangles in the file; export the mesh again")
    if sum(len(p.faces) for p in parts) > _MAX_TRIANGLES:
        raise _error(name, f"more than {_MAX_TRIANGLES} triangles; simplify it")
    for part in parts:
        if not np.isfinite(part.vertices).all():
            raise _error(name, "a vertex coordinate is not finite (NaN or Inf)")
        if part.faces.min() < 0 or part.faces.max() >= len(part.vertices):
            raise _error(name, "a face refers to a vertex that does not exist")
    mesh = MeshData(file=name, parts=tuple(parts), warnings=tuple(notes))
    if cache is not None:
        cache[key] = mesh
    return mesh.scaled(scale)


def mesh_vertices(file: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Return the vertex positions ``(N, 3)`` of a mesh file, in metres (see :func:`load_mesh`).

    Raises:
        MeshFileError: see :func:`load_mesh`.
    """
    return load_mesh(file).vertices
