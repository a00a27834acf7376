"""Vertices of the mesh files MuJoCo loads (STL, OBJ, MSH), read without MuJoCo.

Worlds need a mesh's bounds (ground-truth distances treat a mesh as its bounding box)
while they are parsed, before any simulator exists, so :mod:`visnav.description` reads
the vertex positions itself:

* binary STL (80-byte header, triangle count, 50 bytes per triangle); ASCII STL is
  refused, as MuJoCo refuses it (a binary file whose header starts with ``solid`` is fine);
* Wavefront OBJ: every ``v x y z [w]`` line (other statements are not needed for bounds);
* MuJoCo's MSH: four int32 counts (vertices, normals, texture coordinates, faces), then
  float32 vertex positions.

Differences from MuJoCo's loaders: OBJ vertices that no face uses still count (MuJoCo's
compiler may drop them); values are float64 as written in the file (MuJoCo stores
float32). Every problem is one :class:`~visnav.description.errors.MeshFileError` naming
the file and what is wrong.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from visnav.description.errors import MeshFileError

__all__ = ["MESH_SUFFIXES", "mesh_vertices"]

MESH_SUFFIXES = (".stl", ".obj", ".msh")
"""Mesh formats read here (the ones MuJoCo loads)."""

_MAX_BYTES = 512 * 1024 * 1024  # a mesh larger than this is refused rather than read


def _binary_stl(data: bytes, name: str) -> NDArray[np.float64] | None:
    if len(data) < 84:
        return None
    (count,) = struct.unpack_from("<I", data, 80)
    if len(data) != 84 + 50 * count:
        return None
    if count == 0:
        msg = f"mesh file {name!r}: binary STL with no triangles; export the mesh again"
        raise MeshFileError(msg)
    records = np.frombuffer(data, dtype=np.uint8, offset=84).reshape(count, 50)
    floats = records[:, 12:48].copy().view("<f4").reshape(count * 3, 3)
    return np.asarray(floats, dtype=np.float64)


def _obj(text: str, name: str) -> NDArray[np.float64]:
    rows: list[list[float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if words and words[0] == "v":
            if len(words) not in (4, 5):
                msg = f"mesh file {name!r}:{number}: 'v' needs x y z [w], got {words[1:]}"
                raise MeshFileError(msg)
            try:
                rows.append([float(w) for w in words[1:4]])
            except ValueError:
                msg = f"mesh file {name!r}:{number}: vertex {' '.join(words[1:])!r} is not numbers"
                raise MeshFileError(msg) from None
    if not rows:
        msg = f"mesh file {name!r}: an OBJ file without 'v' vertex lines"
        raise MeshFileError(msg)
    return np.asarray(rows, dtype=np.float64)


def _msh(data: bytes, name: str) -> NDArray[np.float64]:
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
    return (
        np.frombuffer(data, dtype="<f4", count=3 * nvert, offset=16)
        .reshape(nvert, 3)
        .astype(np.float64)
    )


def mesh_vertices(file: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Return the vertex positions ``(N, 3)`` of an STL, OBJ or MSH file, as written.

    Raises:
        MeshFileError: a missing or unreadable file, another format, a malformed file or
            a vertex that is not finite.
    """
    path = Path(file)
    name = str(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        msg = (
            f"mesh file {name!r} has suffix {suffix or '(none)'!r}: expected one of "
            f"{', '.join(MESH_SUFFIXES)} (convert other formats, e.g. .dae, with a mesh tool)"
        )
        raise MeshFileError(msg)
    try:
        size = path.stat().st_size
        if size > _MAX_BYTES:
            msg = f"mesh file {name!r} is {size} bytes: larger than {_MAX_BYTES}; simplify it"
            raise MeshFileError(msg)
        data = path.read_bytes()
    except OSError as exc:
        msg = f"mesh file {name!r} cannot be read ({exc.strerror or exc}); check the path"
        raise MeshFileError(msg) from None
    if suffix == ".msh":
        vertices = _msh(data, name)
    elif suffix == ".stl":
        binary = _binary_stl(data, name)
        if binary is None:
            msg = (
                f"mesh file {name!r} is not a binary STL (its {len(data)} bytes do not match a "
                "triangle count; ASCII STL is not loaded by MuJoCo): export it as binary STL"
            )
            raise MeshFileError(msg)
        vertices = binary
    else:
        vertices = _obj(data.decode("latin-1"), name)
    if not np.isfinite(vertices).all():
        msg = f"mesh file {name!r}: a vertex coordinate is not finite (NaN or Inf)"
        raise MeshFileError(msg)
    return vertices
