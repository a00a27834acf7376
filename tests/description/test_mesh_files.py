"""Mesh vertices read without MuJoCo agree with MuJoCo's loaders; bad files are MeshFileErrors."""
# ASCII STL and Collada are read too (visnav hands MuJoCo vertex data, not files): see
# tests/description/test_sdf_include.py for Collada units, colours and textures.

from __future__ import annotations

import struct
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.description.errors import DescriptionError, MeshFileError, WorldError
from visnav.description.mesh_files import mesh_vertices
from visnav.description.world_yaml import mesh_bounds

RNG_SEED = 4


def _tetra(seed: int) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    rng = np.random.default_rng(seed)
    base = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
    verts = base * rng.uniform(0.5, 2.0, size=3) + rng.uniform(-3, 3, size=3)
    return verts.astype(np.float32).astype(np.float64), [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def _write_binary_stl(path: Path, verts: np.ndarray, faces: list[tuple[int, int, int]]) -> None:
    out = bytearray(b"solid but binary".ljust(80, b" ") + struct.pack("<I", len(faces)))
    for face in faces:
        out += struct.pack("<3f", 0.0, 0.0, 0.0)
        for i in face:
            out += struct.pack("<3f", *verts[i])
        out += b"\0\0"
    path.write_bytes(bytes(out))


def _write_ascii_stl(path: Path, verts: np.ndarray, faces: list[tuple[int, int, int]]) -> None:
    lines = ["solid t"]
    for face in faces:
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += ["vertex " + " ".join(repr(float(v)) for v in verts[i]) for i in face]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid t", ""]))


def _write_obj(path: Path, verts: np.ndarray, faces: list[tuple[int, int, int]]) -> None:
    lines = ["v " + " ".join(repr(float(v)) for v in row) for row in verts]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def _write_msh(path: Path, verts: np.ndarray, faces: list[tuple[int, int, int]]) -> None:
    head = struct.pack("<4i", len(verts), 0, 0, len(faces))
    body = np.asarray(verts, dtype="<f4").tobytes() + np.asarray(faces, dtype="<i4").tobytes()
    path.write_bytes(head + body)


def _mujoco_bounds(path: Path, scale: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    spec = mujoco.MjSpec()
    spec.add_mesh(name="m", file=str(path), scale=list(scale))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m")
    model = spec.compile()
    start, count = int(model.mesh_vertadr[0]), int(model.mesh_vertnum[0])
    verts = np.asarray(model.mesh_vert[start : start + count], dtype=np.float64)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[0])
    world = verts @ rot.reshape(3, 3).T + model.geom_pos[0]
    return world.min(axis=0), world.max(axis=0)


@pytest.mark.parametrize(
    ("suffix", "writer"),
    [
        (".stl", _write_binary_stl),
        (".obj", _write_obj),
        (".msh", _write_msh),
    ],
)
@pytest.mark.parametrize("seed", [RNG_SEED, RNG_SEED + 1])
def test_bounds_match_mujoco(tmp_path: Path, suffix: str, writer: object, seed: int) -> None:
    verts, faces = _tetra(seed)
    path = tmp_path / f"m{suffix}"
    writer(path, verts, faces)  # type: ignore[operator]
    read = mesh_vertices(path)
    assert read.shape[1] == 3
    np.testing.assert_allclose(read.min(axis=0), verts.min(axis=0), atol=1e-6)
    np.testing.assert_allclose(read.max(axis=0), verts.max(axis=0), atol=1e-6)
    scale = (2.0, 0.5, 1.5)
    lo, hi = mesh_bounds(path, scale)
    ref_lo, ref_hi = _mujoco_bounds(path, scale)
    np.testing.assert_allclose(lo, ref_lo, atol=1e-5)
    np.testing.assert_allclose(hi, ref_hi, atol=1e-5)


@pytest.mark.parametrize(
    ("name", "content", "fragment"),
    [
        ("a.ply", b"ply", "expected one of .dae, .obj, .stl, .msh"),
        ("a.dae", b"<COLLADA/>", "Collada file without a <scene>"),
        ("a.dae", b"<COLLADA", "not a readable Collada file"),
        ("a.obj", b"# nothing\nf 1 2 3\n", "without 'v' vertex lines"),
        ("a.obj", b"v 1 2\n", r"'v' needs x y z \[w\]"),
        ("a.obj", b"v 1 two 3\n", "is not numbers"),
        ("a.obj", b"v 1 nan 3\n", "not finite"),
        ("a.stl", b"solid x\nendsolid x\n", "no triangles|not a readable mesh"),
        ("a.msh", b"\x01\x00", "too short for an MSH header"),
        ("a.msh", struct.pack("<4i", 5, 0, 0, 0), "do not match"),
    ],
)
def test_bad_mesh_files_name_the_file_and_the_problem(
    tmp_path: Path, name: str, content: bytes, fragment: str
) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(MeshFileError, match=fragment) as info:
        mesh_vertices(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)


def test_ascii_stl_is_read_like_the_binary_one(tmp_path: Path) -> None:
    # MuJoCo refuses ASCII STL files, but visnav passes it the vertices, not the file
    verts, faces = _tetra(RNG_SEED)
    ascii_path, binary_path = tmp_path / "ascii.stl", tmp_path / "binary.stl"
    _write_ascii_stl(ascii_path, verts, faces)
    _write_binary_stl(binary_path, verts, faces)
    with pytest.raises(ValueError, match="ASCII"):
        _mujoco_bounds(ascii_path, (1.0, 1.0, 1.0))
    a, b = mesh_vertices(ascii_path), mesh_vertices(binary_path)
    np.testing.assert_allclose(a.min(axis=0), b.min(axis=0), atol=1e-6)
    np.testing.assert_allclose(a.max(axis=0), b.max(axis=0), atol=1e-6)


def test_missing_mesh_is_a_world_error_in_a_world(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="does not exist; give a path relative"):
        mesh_bounds(tmp_path / "nope.stl", (1.0, 1.0, 1.0))
    with pytest.raises(MeshFileError, match="cannot be read"):
        mesh_vertices(tmp_path / "nope.stl")


@settings(max_examples=150, deadline=None)
@given(
    suffix=st.sampled_from([".stl", ".obj", ".msh", ".dae"]),
    data=st.one_of(
        st.binary(max_size=400),
        st.lists(
            st.sampled_from(["v 1 2 3", "v a b c", "vertex 1 2 3", "solid", "v 1e999 0 0", "f 1"]),
            max_size=8,
        ).map(lambda lines: "\n".join(lines).encode()),
    ),
)
def test_fuzz_only_description_errors_escape(
    tmp_path_factory: pytest.TempPathFactory, suffix: str, data: bytes
) -> None:
    path = tmp_path_factory.mktemp("fuzz") / f"m{suffix}"
    path.write_bytes(data)
    try:
        verts = mesh_vertices(path)
    except DescriptionError:
        return
    assert verts.ndim == 2
    assert verts.shape[1] == 3
    assert np.isfinite(verts).all()


def test_collada_with_raw_angle_brackets_in_attributes_loads_as_gazebo_reads_it() -> None:
    # velodyne_simulator's meshes carry id="<STL_BINARY>": not XML, but TinyXML takes it
    from pathlib import Path

    from visnav.description.mesh_files import load_mesh

    path = (
        Path(__file__).resolve().parents[1]
        / "data/velodyne_simulator/velodyne_description/meshes/VLP16_base_1.dae"
    )
    assert b'id="<STL_BINARY>"' in path.read_bytes()
    mesh = load_mesh(path)
    low, high = mesh.bounds
    assert 0.10 < high[1] - low[1] < 0.11  # the VLP-16's base, 103.6 mm across (in metres)
    assert any("&lt;" in note for note in mesh.warnings)
