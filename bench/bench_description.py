"""Benchmark: reading robots, worlds and meshes in ``visnav.description`` (no MuJoCo).

Rows, each a median of ``ROUNDS`` rounds, the reference timed alternately in the same
rounds (so both see the same machine load):

* **mesh bounds** of a binary STL with 20,000 triangles:
  :func:`visnav.description.mesh_files.mesh_vertices` (numpy, what world parsing uses
  since issue 17) against the MuJoCo route it replaced (``MjSpec.add_mesh`` + compile +
  reading back ``mesh_vert``).
* **car description**: :func:`visnav.description.robots.resolve_robot` of the built-in
  car (Xacro expansion, URDF and ``<gazebo>`` parsing) against adding the same, already
  parsed, robot to a MuJoCo spec and compiling it (the simulator's next step), for scale.
* **office world**: :func:`visnav.description.world.load_world` of the built-in office
  against :func:`visnav.sim.world_spec.build_world_spec` + compile of the result.

Run: python bench/bench_description.py
"""

from __future__ import annotations

import statistics
import struct
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from visnav.description.mesh_files import mesh_vertices
from visnav.description.robots import resolve_robot
from visnav.description.world import load_world
from visnav.sim.robot import add_robot_to_spec
from visnav.sim.world_spec import build_world_spec

ROUNDS = 9
TRIANGLES = 20_000


def write_stl(path: Path, triangles: int, seed: int = 0) -> None:
    """A binary STL of random triangles (seeded)."""
    rng = np.random.default_rng(seed)
    body = np.zeros((triangles, 50), dtype=np.uint8)
    floats = rng.uniform(-1.0, 1.0, size=(triangles, 12)).astype("<f4")
    body[:, :48] = floats.view(np.uint8).reshape(triangles, 48)
    path.write_bytes(b"bench".ljust(80, b" ") + struct.pack("<I", triangles) + body.tobytes())


def mujoco_bounds(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The replaced route: let MuJoCo load the mesh and read its vertices back."""
    spec = mujoco.MjSpec()
    spec.add_mesh(name="m", file=str(path))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="m")
    model = spec.compile()
    start, count = int(model.mesh_vertadr[0]), int(model.mesh_vertnum[0])
    verts = np.asarray(model.mesh_vert[start : start + count], dtype=np.float64)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[0])
    world = verts @ rot.reshape(3, 3).T + model.geom_pos[0]
    return world.min(axis=0), world.max(axis=0)


def timed(fn: Callable[[], object]) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def row(name: str, fn: Callable[[], object], ref_name: str, ref: Callable[[], object]) -> None:
    fn()
    ref()  # warm-up (imports, caches)
    ours, theirs = [], []
    for _ in range(ROUNDS):
        ours.append(timed(fn))
        theirs.append(timed(ref))
    a, b = statistics.median(ours), statistics.median(theirs)
    print(f"{name:<38} {a * 1e3:9.2f} ms   {ref_name:<34} {b * 1e3:9.2f} ms   ratio {a / b:6.3f}")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        stl = Path(tmp) / "bench.stl"
        write_stl(stl, TRIANGLES)
        verts = mesh_vertices(stl)
        lo, hi = mujoco_bounds(stl)
        assert np.allclose(verts.min(axis=0), lo, atol=1e-5)
        assert np.allclose(verts.max(axis=0), hi, atol=1e-5)
        row(
            f"mesh bounds, STL {TRIANGLES} triangles",
            lambda: mesh_vertices(stl),
            "MuJoCo load + compile",
            lambda: mujoco_bounds(stl),
        )
    car = resolve_robot("car")

    def compile_car() -> None:
        spec = mujoco.MjSpec()
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1])
        add_robot_to_spec(spec, car, prefix="car/", spawn_xyz_yaw=(0.0, 0.0, 0.1, 0.0))
        spec.compile()

    row(
        "car: resolve_robot (xacro+URDF+gazebo)",
        lambda: resolve_robot("car"),
        "car: add_robot_to_spec + compile",
        compile_car,
    )
    office = load_world("office")
    row(
        "office: load_world",
        lambda: load_world("office"),
        "office: build_world_spec + compile",
        lambda: build_world_spec(office).compile(),
    )


if __name__ == "__main__":
    main()
