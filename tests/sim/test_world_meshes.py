"""World and robot meshes in MuJoCo: true-shape collisions, rays, colours and ground truth.

The reference is the world's geometry rebuilt here with trimesh from the files as Gazebo
reads them (Collada ``<unit meter>`` times the SDF ``<scale>``, at the SDF poses), sharing
nothing with visnav's loader, convex decomposition or MuJoCo model.
"""

from __future__ import annotations

import time
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from visnav.description.errors import WorldWarning
from visnav.description.mesh_convex import convex_pieces, halfspaces
from visnav.description.mesh_files import load_mesh
from visnav.description.model_path import ModelPath
from visnav.description.robot import load_robot
from visnav.description.sdf_world import parse_sdf_world
from visnav.description.world import load_world
from visnav.description.worldmodel import WorldDescription
from visnav.sim.robot import add_robot_to_spec
from visnav.sim.world_geometry import obstacle_distance, true_occupancy_grid
from visnav.sim.world_spec import (
    COLLISION_ONLY_GROUP,
    MESH_PIECE_GROUP,
    MESH_RAY_GROUP,
    MESH_VISUAL_GROUP,
    build_world_spec,
)

DATA = Path(__file__).resolve().parent.parent / "data"
TB3 = DATA / "turtlebot3"
WORLD = TB3 / "turtlebot3_gazebo" / "worlds" / "turtlebot3_world.world"
MODEL = TB3 / "turtlebot3_gazebo" / "models" / "turtlebot3_world"


def _quiet_world(path: Path) -> WorldDescription:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WorldWarning)
        return load_world(path)


@pytest.fixture(scope="module")
def tb3_world() -> WorldDescription:
    return _quiet_world(WORLD)


@pytest.fixture(scope="module")
def oracle() -> trimesh.Trimesh:
    """turtlebot3_world's collision geometry, read from model.sdf by this test alone."""
    parts = []
    for collision in ET.parse(MODEL / "model.sdf").getroot().iter("collision"):
        x, y, z, r, p, yaw = (float(v) for v in (collision.findtext("pose") or "").split())
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_euler("xyz", [r, p, yaw]).as_matrix()
        pose[:3, 3] = (x, y, z)
        mesh = collision.find("geometry/mesh")
        if mesh is None:
            radius = float(collision.findtext("geometry/cylinder/radius") or 0)
            length = float(collision.findtext("geometry/cylinder/length") or 0)
            part = trimesh.creation.cylinder(radius=radius, height=length, sections=96)
        else:
            name = (mesh.findtext("uri") or "").rsplit("/", 1)[-1]
            text = (MODEL / "meshes" / name).read_text()
            meter = float(text.split('meter="', 1)[1].split('"', 1)[0])
            part = trimesh.load(MODEL / "meshes" / name, force="mesh")
            scale = [float(v) for v in (mesh.findtext("scale") or "1 1 1").split()]
            part.apply_scale(np.asarray(scale) * meter)
        part.apply_transform(pose)
        parts.append(part)
    mesh = trimesh.util.concatenate(parts)
    mesh.metadata["parts"] = parts  # solids overlap: test containment per part
    return mesh


def _contains(oracle: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    inside = np.zeros(len(points), dtype=bool)
    for part in oracle.metadata["parts"]:
        inside |= part.contains(points)
    return inside


def _rays(model: mujoco.MjModel, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    n = len(directions)
    dist = np.zeros(n)
    geom = np.zeros(n, dtype=np.int32)
    groups = np.ones(mujoco.mjNGROUP, dtype=np.uint8)
    groups[MESH_VISUAL_GROUP] = 0  # as the lidar: rays skip visual copies
    groups[MESH_PIECE_GROUP] = 0  # and the convex pieces: they hit the mesh's ray geom
    mujoco.mj_multiRay(
        model, data, origin, directions.ravel(), groups, 1, -1, geom, dist, None, n, 50.0
    )
    return np.where(geom >= 0, dist, np.inf)


def _oracle_rays(mesh: trimesh.Trimesh, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
    origins = np.repeat(origin[None], len(directions), axis=0)
    where, index, _ = mesh.ray.intersects_location(origins, directions, multiple_hits=True)
    out = np.full(len(directions), np.inf)
    np.minimum.at(out, index, np.linalg.norm(where - origins[index], axis=1))
    return out


@pytest.mark.parametrize(
    ("x", "y", "z"), [(-2.0, -0.5, 0.1), (0.5, 0.55, 0.3), (1.6, -1.0, 0.05), (2.2, 0.3, 0.8)]
)
def test_rays_see_the_walls_pillars_and_hexagons_where_they_are(
    tb3_world: WorldDescription, oracle: trimesh.Trimesh, x: float, y: float, z: float
) -> None:
    model = build_world_spec(tb3_world).compile()
    angles = np.linspace(-np.pi, np.pi, 720, endpoint=False)
    pitch = np.where(np.arange(720) % 3 == 0, 0.0, np.where(np.arange(720) % 3 == 1, 0.3, -0.2))
    directions = np.column_stack(
        [np.cos(angles) * np.cos(pitch), np.sin(angles) * np.cos(pitch), np.sin(pitch)]
    )
    origin = np.array([x, y, z])
    got = _rays(model, origin, directions)
    truth = _oracle_rays(oracle, origin, directions)
    floor = np.where(directions[:, 2] < 0, -z / np.minimum(directions[:, 2], -1e-9), np.inf)
    truth = np.minimum(truth, floor)  # the ground plane
    assert np.isfinite(truth).mean() > 0.6
    np.testing.assert_allclose(got, truth, atol=2e-3)


def test_mesh_geoms_collide_with_the_true_shape(tb3_world: WorldDescription) -> None:
    """A ball inside the hexagonal wall stays there (the wall's hull would eject it)."""
    spec = build_world_spec(tb3_world)
    ball = spec.worldbody.add_body(name="ball", pos=[-2.0, -0.5, 0.3])
    ball.add_freejoint()
    ball.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0], density=500)
    rolling = spec.worldbody.add_body(name="pushed", pos=[-1.5, 0.8, 0.2])
    rolling.add_freejoint()
    rolling.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0], density=500)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    data.qvel[6:9] = (-3.0, 3.0, 0.0)  # thrown at the wall (its inner side: r 2.54 to 2.93 m)
    for _ in range(int(1.5 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(data.xpos[model.body("ball").id], (-2.0, -0.5, 0.1), atol=0.01)
    pushed = data.xpos[model.body("pushed").id]
    assert np.hypot(pushed[0], pushed[1]) < 2.93  # stopped by the wall, not through it
    groups = {int(model.geom_group[g]) for g in range(model.ngeom) if model.geom_contype[g]}
    assert groups <= {0, COLLISION_ONLY_GROUP, MESH_PIECE_GROUP}
    ray_geoms = [g for g in range(model.ngeom) if model.geom_group[g] == MESH_RAY_GROUP]
    assert ray_geoms
    assert not any(model.geom_contype[g] or model.geom_conaffinity[g] for g in ray_geoms)


def test_occupancy_and_distance_follow_the_mesh_geometry(
    tb3_world: WorldDescription, oracle: trimesh.Trimesh
) -> None:
    resolution = 0.05
    grid, origin = true_occupancy_grid(
        tb3_world, resolution, (0.05, 0.4), bounds=(-4.0, -4.0, 4.0, 4.0)
    )
    ny, nx = grid.shape
    xs = origin[0] + (np.arange(nx) + 0.5) * resolution
    ys = origin[1] + (np.arange(ny) + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)
    centres = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, 0.2)])
    inside = _contains(oracle, centres).reshape(grid.shape)
    near = np.zeros_like(inside)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            shifted = centres + np.array([dx * resolution, dy * resolution, 0.0])
            near |= _contains(oracle, shifted).reshape(grid.shape)
    assert inside.sum() > 1000
    assert grid[inside].all()  # every cell whose centre is in an obstacle is occupied
    assert not grid[~near].any()  # and no cell a full cell away from every obstacle
    points = centres[::7]
    distance = obstacle_distance(tb3_world, points)
    contained = _contains(oracle, points)
    assert np.all(distance[contained] <= 1e-9)
    assert np.all(distance[~contained] > -1e-9)


def test_ground_truth_inside_the_ring_is_free(tb3_world: WorldDescription) -> None:
    # a mesh counted as its bounding box would put the whole arena inside the wall
    distance = obstacle_distance(tb3_world, [[-2.0, -0.5, 0.1], [0.55, 0.55, 0.2]])
    assert distance[0] > 0.5
    assert distance[1] > 0.2


def test_world_mesh_colours_reach_mujoco(tb3_world: WorldDescription) -> None:
    model = build_world_spec(tb3_world).compile()
    wall = model.geom("world/ros_symbol/symbol/body")
    np.testing.assert_allclose(wall.rgba, (0.1, 0.1, 0.1, 1.0))  # Gazebo/FlatBlack
    assert int(wall.group[0]) == MESH_VISUAL_GROUP
    assert int(wall.contype[0]) == 0
    pieces = [
        model.geom(g).name
        for g in range(model.ngeom)
        if model.geom(g).name.startswith("world/ros_symbol/symbol/body#c")
    ]
    assert len(pieces) > 6  # the ring is split


def test_a_mesh_floor_carries_the_robot(tmp_path: Path) -> None:
    """A world without ground_plane whose floor is a mesh model (Gazebo accepts it)."""
    slab = trimesh.creation.box(extents=(6.0, 6.0, 0.2))
    slab.apply_translation((0, 0, -0.1))
    slab.export(tmp_path / "floor.stl")
    text = (
        "<sdf version='1.6'><world name='w'><model name='floor'><static>1</static>"
        "<pose>0 0 0.5 0 0 0</pose><link name='l'><collision name='c'><geometry><mesh>"
        f"<uri>file://{tmp_path / 'floor.stl'}</uri></mesh></geometry></collision>"
        "<visual name='c'><geometry><mesh>"
        f"<uri>file://{tmp_path / 'floor.stl'}</uri></mesh></geometry></visual>"
        "</link></model></world></sdf>"
    )
    world = parse_sdf_world(text, model_path=ModelPath())
    assert world.ground is None
    robot = load_robot(
        TB3 / "turtlebot3_description" / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": TB3 / "turtlebot3_description"},
    )
    spec = build_world_spec(world)
    handles = add_robot_to_spec(spec, robot, prefix="tb3/", spawn_xyz_yaw=(0, 0, 0.6, 0))
    model = spec.compile()
    data = mujoco.MjData(model)
    for _ in range(int(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    base = data.xpos[model.body(handles.bodies["base_footprint"]).id]
    assert base[2] == pytest.approx(0.5, abs=0.02)  # resting on the slab's top at z = 0.5


def test_robot_collada_meshes_keep_their_colours_and_units(tmp_path: Path) -> None:
    r200 = TB3 / "turtlebot3_description" / "meshes" / "sensors" / "r200.dae"
    urdf = tmp_path / "r.urdf"
    urdf.write_text(
        "<robot name='r'><link name='base'><inertial><mass value='1'/>"
        "<inertia ixx='0.01' iyy='0.01' izz='0.01' ixy='0' ixz='0' iyz='0'/></inertial>"
        f"<visual><geometry><mesh filename='file://{r200}' scale='1 2 1'/></geometry></visual>"
        f"<collision><geometry><mesh filename='file://{r200}'/></geometry></collision>"
        "</link></robot>"
    )
    spec = mujoco.MjSpec()
    add_robot_to_spec(spec, load_robot(urdf), prefix="r/")
    model = spec.compile()
    visuals = [model.geom(g) for g in range(model.ngeom) if ":visual0" in model.geom(g).name]
    assert len(visuals) == 5  # one geom per diffuse colour of r200.dae
    colours = {tuple(np.round(np.asarray(g.rgba, dtype=float), 3).tolist()) for g in visuals}
    assert (0.243, 0.357, 0.435, 1.0) in colours
    # the R200 is 130 mm wide in r200.dae's units (<unit meter="0.00254">), 20 mm deep
    # (x2 by the URDF scale); MuJoCo recentres each part: sizes checked on the loaded mesh
    lo, hi = (np.array(b) for b in load_mesh(r200, (1.0, 2.0, 1.0)).bounds)
    np.testing.assert_allclose(hi - lo, (0.13, 0.04, 0.0063), atol=2e-3)
    mesh_ids = {int(model.geom_dataid[g.id]) for g in visuals}
    assert len(mesh_ids) == 5
    collision = [g for g in range(model.ngeom) if ":collision0" in model.geom(g).name]
    assert len(collision) == 1  # one convex hull of the whole file


@pytest.mark.slow
def test_load_and_build_times() -> None:
    start = time.perf_counter()
    world = _quiet_world(WORLD)
    loaded = time.perf_counter()
    build_world_spec(world).compile()
    built = time.perf_counter()
    assert loaded - start < 5.0
    assert built - loaded < 10.0


def test_burger_rests_on_the_small_house_mesh_floor(monkeypatch: pytest.MonkeyPatch) -> None:
    """AWS small house has no ground_plane: its floor is the FloorB_01 mesh model."""
    monkeypatch.setenv("GAZEBO_MODEL_PATH", "")
    house = DATA / "aws_robomaker_small_house_world" / "worlds" / "small_house.world"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WorldWarning)
        world = load_world(house, skip_missing_models=True)
    assert world.ground is None
    robot = load_robot(
        TB3 / "turtlebot3_description" / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": TB3 / "turtlebot3_description"},
    )
    spec = build_world_spec(world)
    handles = add_robot_to_spec(spec, robot, prefix="tb3/", spawn_xyz_yaw=(2.0, 2.0, 0.05, 0))
    model = spec.compile()
    data = mujoco.MjData(model)
    for _ in range(int(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    base = data.xpos[model.body(handles.bodies["base_footprint"]).id]
    np.testing.assert_allclose(base, (2.0, 2.0, 0.0), atol=0.02)


def _star_prism(radii: list[float], height: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed prism over a star-shaped (generally non-convex) polygon, outward faces."""
    n = len(radii)
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.column_stack([np.cos(angles) * radii, np.sin(angles) * radii])
    bottom = np.column_stack([ring, np.zeros(n)])
    top = np.column_stack([ring, np.full(n, height)])
    vertices = np.vstack([bottom, top, [[0, 0, 0], [0, 0, height]]])
    cb, ct = 2 * n, 2 * n + 1
    faces = []
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, n + j), (i, n + j, n + i), (cb, j, i), (ct, n + i, n + j)]
    return vertices, np.array(faces)


@settings(max_examples=40, deadline=None)
@given(
    radii=st.lists(st.floats(0.3, 2.0), min_size=5, max_size=12),
    height=st.floats(0.1, 1.5),
)
def test_convex_pieces_cover_the_surface_and_stay_in_its_box(
    radii: list[float], height: float
) -> None:
    vertices, faces = _star_prism(radii, height)
    pieces = convex_pieces(vertices, faces)
    assert pieces.warning is None
    lo, hi = vertices.min(axis=0) - 2e-3, vertices.max(axis=0) + 2e-3  # 1 mm minimum depth
    planes = []
    for points in pieces.points:
        assert np.all(points >= lo)
        assert np.all(points <= hi)
        hull = halfspaces(points)
        assert hull is not None
        planes.append(hull)
    rng = np.random.default_rng(len(radii))
    weights = rng.dirichlet(np.ones(3), size=len(faces))
    samples = np.einsum("fk,fkd->fd", weights, vertices[faces])  # one point per triangle
    inside = np.zeros(len(samples), dtype=bool)
    for hull in planes:
        inside |= (samples @ hull[:, :3].T + hull[:, 3]).max(axis=1) <= 1e-6
    assert inside.all()  # no hole in the collision surface


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), count=st.integers(8, 60))
def test_a_convex_mesh_is_one_piece(seed: int, count: int) -> None:
    from scipy.spatial import ConvexHull

    points = np.random.default_rng(seed).normal(size=(count, 3))
    hull = ConvexHull(points)
    pieces = convex_pieces(points, hull.simplices)
    assert len(pieces.points) == 1


def test_mujoco_rays_hit_a_mesh_geoms_triangles_not_its_hull() -> None:
    """What lets visual and piece geoms agree with the file: mj_ray uses the triangles."""
    vertices, faces = _star_prism([2.0, 0.5] * 4, 1.0)  # a four-pointed star
    spec = mujoco.MjSpec()
    mesh = spec.add_mesh(name="star")
    mesh.uservert = vertices.astype(np.float32).ravel().tolist()
    mesh.userface = faces.astype(np.int32).ravel().tolist()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="star")
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom = np.zeros(1, dtype=np.int32)
    # along the diagonal the star's surface is its inner corner at r = 0.5, far inside the
    # hull (whose edge between the tips at (2, 0) and (0, 2) crosses it at r = 1.41)
    direction = np.array([-1.0, -1.0, 0.0]) / np.sqrt(2.0)
    distance = mujoco.mj_ray(model, data, np.array([3.0, 3.0, 0.5]), direction, None, 1, -1, geom)
    corner = np.array([0.5 * np.cos(np.pi / 4), 0.5 * np.sin(np.pi / 4)])
    assert distance == pytest.approx(np.hypot(3.0, 3.0) - np.linalg.norm(corner), abs=1e-4)
