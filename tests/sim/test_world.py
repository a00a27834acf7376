"""Worlds: YAML and SDF loading, built-in worlds, MuJoCo specs, ground-truth geometry."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.description.errors import WorldError, WorldWarning
from visnav.description.model_path import ModelPath
from visnav.description.sdf_world import parse_sdf_world
from visnav.description.world import builtin_world_names, load_world
from visnav.description.world_yaml import world_from_dict
from visnav.description.worldmodel import Box, Cylinder, Sphere, WorldDescription
from visnav.sim.world_geometry import (
    obstacle_distance,
    shape_aabb,
    shape_signed_distance,
    true_occupancy_grid,
)
from visnav.sim.world_spec import WORLD_PREFIX, build_world_spec

# ----------------------------------------------------------------------------- YAML

CUBE_OBJ = """\
v 1 2 3
v 2 2 3
v 2 3 3
v 1 3 3
v 1 2 4
v 2 2 4
v 2 3 4
v 1 3 4
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
"""

WORLD_YAML = """\
name: test_world
seed: 3
physics: {timestep: 0.004, gravity: [0, 0, -9.5]}
ground: {size: [10, 8], material: floor}
headlight: {ambient: [0.2, 0.2, 0.2], diffuse: [0.5, 0.5, 0.5]}
textures:
  tiles: {type: checker, rgb1: [0.9, 0.9, 0.9], rgb2: [0.2, 0.2, 0.2], mark: random, random: 0.05}
  plaster: {type: noise, rgb1: [0.9, 0.8, 0.6], rgb2: [0.3, 0.2, 0.1], width: 64, height: 64}
  fixed: {type: noise, seed: 11, width: 32, height: 32}
materials:
  floor: {texture: tiles, tile: 2.0}
  wall: {texture: plaster, tile: 1.0, specular: 0.1}
  other: {texture: fixed}
objects:
  - {type: box, name: wall, pos: [0, 3, 1], size: [6, 0.2, 2], material: wall}
  - {type: cylinder, name: pillar, pos: [2, 0, 1], radius: 0.3, length: 2, yaw: 0.5,
     rgba: [0.2, 0.6, 0.2]}
  - {type: sphere, pos: [-2, 0, 2], radius: 0.5, collision: false, material: other}
  - {type: mesh, name: cube, file: cube.obj, scale: 0.5}
lights:
  - {type: directional, dir: [0, 0, -1], diffuse: [0.6, 0.6, 0.6]}
  - {type: spot, name: lamp, pos: [0, 0, 3], cutoff: 30}
metadata: {start: [0, 0, 0]}
"""


@pytest.fixture
def world_file(tmp_path: Path) -> Path:
    (tmp_path / "cube.obj").write_text(CUBE_OBJ)
    path = tmp_path / "test.yaml"
    path.write_text(WORLD_YAML)
    return path


def test_yaml_world_parses_every_section(world_file: Path) -> None:
    world = load_world(world_file)
    assert world.name == "test_world"
    assert world.seed == 3
    assert world.physics.timestep == 0.004
    assert world.physics.gravity == (0.0, 0.0, -9.5)
    assert world.ground is not None
    assert world.ground.size == (10.0, 8.0)
    assert world.headlight.ambient == (0.2, 0.2, 0.2)
    wall = world.shape("wall")
    assert isinstance(wall, Box)
    assert wall.size == (6.0, 0.2, 2.0)
    pillar = world.shape("pillar")
    assert isinstance(pillar, Cylinder)
    assert pillar.rpy == (0.0, 0.0, 0.5)
    assert pillar.rgba == (0.2, 0.6, 0.2, 1.0)
    sphere = world.shape("sphere_2")  # auto name: type and index
    assert isinstance(sphere, Sphere)
    assert not sphere.collision
    assert [s.name for s in world.collision_shapes] == ["wall", "pillar", "cube"]
    assert world.metadata == {"start": [0, 0, 0]}
    assert [light.kind for light in world.lights] == ["directional", "spot"]


def test_mesh_bounds_come_from_the_file(world_file: Path) -> None:
    cube = load_world(world_file).shape("cube")
    lo, hi = cube.bounds  # type: ignore[union-attr]
    np.testing.assert_allclose(lo, [0.5, 1.0, 1.5], atol=1e-9)
    np.testing.assert_allclose(hi, [1.0, 1.5, 2.0], atol=1e-9)
    # the distance to the mesh is the distance to that box
    world = load_world(world_file)
    np.testing.assert_allclose(obstacle_distance(world, [[0.75, 1.25, 2.5]]), [0.5], atol=1e-9)


def test_world_spec_compiles_with_prefixed_names_and_no_shadows(world_file: Path) -> None:
    world = load_world(world_file)
    model = build_world_spec(world).compile()
    wall = model.geom(WORLD_PREFIX + "wall")
    np.testing.assert_allclose(wall.size, [3.0, 0.1, 1.0])
    pillar = model.geom(WORLD_PREFIX + "pillar")
    np.testing.assert_allclose(pillar.size[:2], [0.3, 1.0])
    np.testing.assert_allclose(pillar.rgba, [0.2, 0.6, 0.2, 1.0])
    ground = model.geom(WORLD_PREFIX + "ground")
    np.testing.assert_allclose(ground.size[:2], [5.0, 4.0])
    sphere = model.geom(WORLD_PREFIX + "sphere_2")
    assert sphere.contype[0] == 0
    assert sphere.conaffinity[0] == 0
    assert model.nlight == 2
    assert not model.light_castshadow.any()
    assert model.opt.timestep == pytest.approx(0.004)
    np.testing.assert_allclose(model.opt.gravity, [0, 0, -9.5])
    np.testing.assert_allclose(model.vis.headlight.ambient, [0.2, 0.2, 0.2])
    # a 6 m wall with a 1 m tile repeats its texture 6 x 2 times over its largest face
    mat = model.mat(int(wall.matid[0]))
    np.testing.assert_allclose(mat.texrepeat, [6.0, 2.0])
    mesh_geom = model.geom(WORLD_PREFIX + "cube")
    assert mesh_geom.type[0] == mujoco.mjtGeom.mjGEOM_MESH


def _texture_bytes(world: WorldDescription, name: str) -> bytes:
    model = build_world_spec(world).compile()
    tex = model.texture(WORLD_PREFIX + name)
    start = int(tex.adr[0])
    size = int(tex.width[0] * tex.height[0] * tex.nchannel[0])
    return bytes(model.tex_data[start : start + size])


def test_noise_textures_are_seeded(world_file: Path) -> None:
    a = load_world(world_file)
    b = load_world(world_file)
    c = load_world(world_file, seed=4)
    assert a == b
    assert _texture_bytes(a, "plaster") == _texture_bytes(b, "plaster")
    # an unseeded texture follows the world seed, an explicitly seeded one does not
    assert _texture_bytes(a, "plaster") != _texture_bytes(c, "plaster")
    assert _texture_bytes(a, "fixed") == _texture_bytes(c, "fixed")
    assert c.seed == 4


def test_ground_null_default_and_texture_shorthand() -> None:
    assert world_from_dict({"name": "w", "ground": None}).ground is None
    shorthand = world_from_dict(
        {
            "name": "w",
            "ground": {"size": [4, 4], "texture": "t", "tile": 0.5},
            "textures": {"t": {"type": "noise"}},
        }
    )
    assert shorthand.ground is not None
    assert shorthand.material(shorthand.ground.material or "").tile == 0.5
    model = build_world_spec(shorthand).compile()
    mat = model.mat(int(model.geom(WORLD_PREFIX + "ground").matid[0]))
    np.testing.assert_allclose(mat.texrepeat, [2.0, 2.0])  # per metre on the ground plane
    assert bool(mat.texuniform[0])
    world = world_from_dict({"name": "w"})
    assert world.ground is not None
    assert world.ground.material is not None
    build_world_spec(world).compile()


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("objects:\n  - {type: box, size: [1, 2\n", ["does not parse as YAML", ":3"]),
        ("objects:\n  - {type: cube, size: [1, 1, 1]}\n", ["unknown shape type 'cube'", ":2"]),
        ("objects:\n  - {type: box, size: [1, -2, 1]}\n", ["size", "> 0", "-2", ":2"]),
        ("objects:\n  - {type: sphere, radius: 0}\n", ["radius", "> 0"]),
        ("objects:\n  - {type: box, sise: [1, 1, 1]}\n", ["unknown key 'sise'", "'size'"]),
        ("physics: {timestep: -1}\n", ["timestep", "-1"]),
        ("name: a\nname: b\n", ["duplicate key 'name'", ":2"]),
        ("objects:\n  - {type: box, size: [1, 1, 1], material: nope}\n", ["unknown material"]),
        ("textures:\n  t: {type: marble}\n", ["unknown type 'marble'", ":2"]),
        ("objects:\n  - {type: mesh, file: missing.stl}\n", ["missing.stl", "does not exist"]),
        ("", ["empty"]),
    ],
)
def test_bad_yaml_raises_one_clear_error(tmp_path: Path, text: str, fragments: list[str]) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(WorldError) as info:
        load_world(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message


def test_unknown_world_name_suggests_the_closest() -> None:
    with pytest.raises(WorldError, match=r"unknown world 'ofice'.*did you mean 'office'"):
        load_world("ofice")


def test_missing_file_and_params_for_a_file(world_file: Path, tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="does not exist"):
        load_world(tmp_path / "nope.yaml")
    with pytest.raises(WorldError, match="only accepted by built-in world generators"):
        load_world(world_file, params={"size": [1, 1]})


def test_invalid_shapes_raise_in_code_too() -> None:
    with pytest.raises(WorldError, match=r"box 'b'\.size"):
        Box(name="b", size=(1.0, 0.0, 1.0))
    with pytest.raises(WorldError, match="finite"):
        Sphere(name="s", pos=(math.nan, 0.0, 0.0), radius=1.0)


# ----------------------------------------------------------------------------- SDF

SDF = """\
<?xml version="1.0"?>
<sdf version="1.6">
  <world name="gz_world">
    <include><uri>model://ground_plane</uri></include>
    <include><uri>model://sun</uri></include>
    <include><uri>model://cafe_table</uri></include>
    <physics type="ode">
      <max_step_size>0.005</max_step_size><real_time_factor>1</real_time_factor>
    </physics>
    <gravity>0 0 -9.7</gravity>
    <plugin name="x" filename="libfoo.so"/>
    <model name="crate">
      <static>true</static>
      <pose>1 2 0 0 0 1.5707963</pose>
      <link name="body">
        <pose>0.5 0 0.5 0 0 0</pose>
        <collision name="c"><geometry><box><size>1 2 1</size></box></geometry></collision>
        <visual name="v">
          <geometry><box><size>1 2 1</size></box></geometry>
          <material><script><name>Gazebo/Wood</name></script></material>
        </visual>
      </link>
    </model>
    <model name="post">
      <pose>-3 0 1 0 0 0</pose>
      <link name="l">
        <visual name="v">
          <geometry><cylinder><radius>0.2</radius><length>2</length></cylinder></geometry>
          <material><diffuse>1 0 0 1</diffuse></material>
        </visual>
        <collision name="c"><geometry><sphere><radius>0.5</radius></sphere></geometry></collision>
      </link>
    </model>
  </world>
</sdf>
"""


def test_sdf_subset_with_warnings_for_the_rest() -> None:
    with pytest.warns(WorldWarning) as caught:
        world = parse_sdf_world(
            SDF, source="gz.world", model_path=ModelPath(), skip_missing_models=True
        )
    texts = [str(w.message) for w in caught]
    assert any("model://cafe_table" in t and "not found" in t for t in texts)
    assert any("<plugin>" in t for t in texts)
    assert not any("<real_time_factor>" in t for t in texts)  # Gazebo's own loop: debug only
    assert any("'post' is not static" in t for t in texts)
    assert all(t.startswith("gz.world:") for t in texts)
    assert world.warnings == tuple(texts)
    assert world.name == "gz_world"
    assert world.physics.timestep == 0.005
    assert world.physics.gravity == (0.0, 0.0, -9.7)
    assert world.ground is not None
    assert world.ground.size == (100.0, 100.0)
    assert [light.kind for light in world.lights] == ["directional"]
    crate = world.shape("crate/body/v")  # visual + collision of the same box: one shape
    assert isinstance(crate, Box)
    assert crate.visual
    assert crate.collision
    np.testing.assert_allclose(crate.pos, [1.0, 2.5, 0.5], atol=1e-7)  # model pose o link pose
    assert crate.rpy[2] == pytest.approx(math.pi / 2)
    assert crate.rgba == (0.6, 0.45, 0.3, 1.0)
    post = world.shape("post/l/v")
    assert isinstance(post, Cylinder)
    assert post.visual
    assert not post.collision
    assert post.rgba == (1.0, 0.0, 0.0, 1.0)
    ball = world.shape("post/l/c")
    assert isinstance(ball, Sphere)
    assert ball.collision
    assert not ball.visual
    build_world_spec(world).compile()


def test_sdf_files_load_and_bad_xml_names_the_line(tmp_path: Path) -> None:
    good = tmp_path / "w.sdf"
    good.write_text(
        '<sdf version="1.6"><world name="w"><include><uri>model://sun</uri></include></world></sdf>'
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_world(good).name == "w"
    bad = tmp_path / "bad.world"
    bad.write_text('<sdf version="1.6">\n<world name="w">\n<model>\n</world></sdf>')
    with pytest.raises(WorldError, match=r"bad\.world:4: malformed SDF"):
        load_world(bad)
    negative = '<sdf version="1.6"><model name="m"><static>1</static><link name="l">' + (
        "<collision name='c'><geometry><box><size>1 -1 1</size></box></geometry></collision>"
        "</link></model></sdf>"
    )
    with pytest.raises(WorldError, match=r"<box>: m/l/c: .*size"):
        parse_sdf_world(negative)


# ----------------------------------------------------------------------------- built-ins


def test_builtin_names() -> None:
    assert set(builtin_world_names()) >= {"office", "forest"}


def test_forest_defaults_seeded_and_keepout() -> None:
    world = load_world("forest")
    assert len(world.collision_shapes) >= 100
    meta = world.metadata
    assert meta["bounds"] == [-20.0, -20.0, 20.0, 20.0]
    assert world == load_world("forest", seed=0)
    other = load_world("forest", seed=1)
    assert other.shapes != world.shapes
    radius = meta["keepout_radius"]
    # every obstacle stands on the ground and is taller than 0.3 m, so at z = 0.3 the 3D
    # distance is the footprint distance
    for centre in (meta["start"], meta["goal"]):
        assert obstacle_distance(world, [[*centre, 0.3]])[0] >= radius - 1e-9
    # dense forests, several seeds: the discs stay clear of every footprint
    for seed in range(4):
        dense = load_world(
            "forest",
            params={"obstacles": 300, "min_spacing": 0.3, "keepout_radius": 3.0, "goal": [5, 5]},
            seed=seed,
        )
        for centre in ([-17.0, 0.0], [5.0, 5.0]):
            assert obstacle_distance(dense, [[*centre, 0.3]])[0] >= 3.0 - 1e-9
    for shape in world.shapes:  # every obstacle lies fully inside the map
        lo, hi = shape_aabb(shape)
        assert (lo[:2] >= -20.0 - 1e-9).all()
        assert (hi[:2] <= 20.0 + 1e-9).all()
        assert lo[2] == pytest.approx(0.0, abs=1e-9)  # standing on the ground


def test_forest_spacing_between_footprints() -> None:
    world = load_world("forest", params={"obstacles": 60, "min_spacing": 1.5}, seed=5)
    shapes = world.collision_shapes
    assert len(shapes) == 60
    for i, shape in enumerate(shapes):
        # points on this obstacle's footprint outline at z = 0.3, checked against the others
        if isinstance(shape, Cylinder):
            a = np.linspace(0, 2 * np.pi, 64, endpoint=False)
            outline = np.column_stack(
                [shape.pos[0] + shape.radius * np.cos(a), shape.pos[1] + shape.radius * np.sin(a)]
            )
        else:
            assert isinstance(shape, Box)
            hx, hy = shape.size[0] / 2, shape.size[1] / 2
            t = np.linspace(-1, 1, 16)
            local = np.concatenate(
                [np.column_stack([t * hx, np.full(16, s * hy)]) for s in (-1, 1)]
                + [np.column_stack([np.full(16, s * hx), t * hy]) for s in (-1, 1)]
            )
            rot = shape.rotation[:2, :2]
            outline = local @ rot.T + np.asarray(shape.pos[:2])
        points = np.column_stack([outline, np.full(len(outline), 0.3)])
        for j, other in enumerate(shapes):
            if j != i and np.hypot(*(np.subtract(other.pos[:2], shape.pos[:2]))) < 6:
                assert shape_signed_distance(other, points).min() >= 1.5 - 1e-6


def test_forest_bad_params() -> None:
    with pytest.raises(WorldError, match=r"unknown parameter 'obstacle'.*did you mean 'obstacles'"):
        load_world("forest", params={"obstacle": 10})
    with pytest.raises(WorldError, match="could place only"):
        load_world("forest", params={"size": [6, 6], "obstacles": 200})
    with pytest.raises(WorldError, match="column_radius"):
        load_world("forest", params={"column_radius": [0.5, 0.1]})


def test_office_layout_textures_and_free_space_graph() -> None:
    world = load_world("office")
    assert world == load_world("office", seed=0)
    recoloured = load_world("office", seed=9)
    assert [s.pos for s in recoloured.shapes] == [s.pos for s in world.shapes]
    assert recoloured.textures != world.textures
    x0, y0, x1, y1 = world.metadata["bounds"]
    assert (x1 - x0, y1 - y0) == (20.0, 15.0)
    # every visible surface is textured
    textured = {m.name for m in world.materials if m.texture is not None}
    assert all(s.material in textured for s in world.shapes if s.visual)
    # the free-space graph: nodes and straight edges clear of every obstacle by 0.3 m
    graph = world.metadata["graph"]
    nodes = {k: np.asarray(v, dtype=float) for k, v in graph["nodes"].items()}
    assert set(world.metadata["rooms"]) <= set(nodes)
    for a, b in graph["edges"]:
        t = np.linspace(0.0, 1.0, 60)[:, None]
        xy = nodes[a] + t * (nodes[b] - nodes[a])
        for z in (0.1, 0.3, 1.0):
            pts = np.column_stack([xy, np.full(len(xy), z)])
            assert obstacle_distance(world, pts).min() > 0.3, (a, b, z)
    spawn = world.metadata["spawn"]
    assert obstacle_distance(world, [[spawn[0], spawn[1], 0.2]])[0] > 0.5


def test_office_views_have_texture_everywhere(mujoco_gl: str) -> None:
    world = load_world("office")
    spec = build_world_spec(world)
    views = [(-6.0, -1.5), (0.0, 3.0), (2.5, 0.0), (-6.75, 5.75)]
    for i, (x, y) in enumerate(views):
        for k in range(4):
            yaw = k * math.pi / 2
            left = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
            spec.worldbody.add_camera(
                name=f"v{i}_{k}", pos=[x, y, 0.3], xyaxes=[*(-left), 0.0, 0.0, 1.0], fovy=60
            )
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    fast = cv2.FastFeatureDetector_create(threshold=10)
    for cam, image in enumerate(_render_cameras(model, data, mujoco_gl, 160, 120)):
        grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        # the same views without textures give 0-44 corners (only geometric edges)
        assert len(fast.detect(grey)) >= 100, model.camera(cam).name


def _render_cameras(
    model: mujoco.MjModel, data: mujoco.MjData, backend: str, width: int, height: int
) -> list[np.ndarray]:
    """Render every camera of the model offscreen (RGB, uint8, top row first)."""
    if backend == "egl":
        from mujoco.egl import GLContext
    else:
        from mujoco.osmesa import GLContext
    try:
        gl = GLContext(width, height)
        gl.make_current()
    except Exception as exc:  # noqa: BLE001  (no GL on this machine)
        pytest.skip(f"no offscreen rendering: {exc}")
    try:
        context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_50.value)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, context)
        scene = mujoco.MjvScene(model, maxgeom=2000)
        option = mujoco.MjvOption()
        viewport = mujoco.MjrRect(0, 0, width, height)
        images = []
        for cam_id in range(model.ncam):
            camera = mujoco.MjvCamera()
            camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
            camera.fixedcamid = cam_id
            mujoco.mjv_updateScene(
                model, data, option, None, camera, mujoco.mjtCatBit.mjCAT_ALL.value, scene
            )
            mujoco.mjr_render(viewport, scene, context)
            rgb = np.zeros((height, width, 3), dtype=np.uint8)
            mujoco.mjr_readPixels(rgb, None, viewport, context)
            images.append(np.flipud(rgb))
        context.free()
        return images
    finally:
        gl.free()


# ----------------------------------------------------------------------------- geometry


def _geometry_world() -> WorldDescription:
    return world_from_dict(
        {
            "name": "geom",
            "ground": None,
            "objects": [
                {"type": "box", "pos": [0, 0, 0.5], "size": [1.0, 0.6, 1.0], "yaw": 0.4},
                {"type": "cylinder", "pos": [2.5, 0.3, 1.0], "radius": 0.4, "length": 2.0},
                {"type": "sphere", "pos": [-2.0, 1.0, 2.1], "radius": 0.5},
                {"type": "box", "pos": [0.5, 2.5, 1.0], "size": [2, 0.3, 0.3],
                 "rpy": [0.7, 0.3, 1.1]},
                {"type": "cylinder", "pos": [-1.5, -2.0, 0.8], "radius": 0.3, "length": 1.5,
                 "rpy": [1.2, 0.0, 0.5]},
                {"type": "box", "pos": [3.0, -2.5, 0.5], "size": [0.5, 0.5, 0.5],
                 "collision": False},
            ],
        }
    )  # fmt: skip


def test_true_occupancy_grid_matches_sampled_geometry() -> None:
    world = _geometry_world()
    res, z_range = 0.08, (0.1, 1.8)
    grid, origin = true_occupancy_grid(world, res, z_range, bounds=(-4.0, -4.0, 4.0, 4.0))
    assert grid.shape == (100, 100)
    assert origin == (-4.0, -4.0)
    iy, ix = np.mgrid[0:100, 0:100]
    cx = origin[0] + (ix.ravel() + 0.5) * res
    cy = origin[1] + (iy.ravel() + 0.5) * res
    step = 0.01
    zs = np.arange(z_range[0], z_range[1] + step / 2, step)
    best = np.full(cx.size, np.inf)
    for z in zs:
        pts = np.column_stack([cx, cy, np.full(cx.size, z)])
        best = np.minimum(best, obstacle_distance(world, pts))
    exact = grid.ravel()
    sure_occupied = best <= 0.0
    sure_free = best > step / 2  # distance is 1-Lipschitz: nothing between the samples
    assert exact[sure_occupied].all()
    assert not exact[sure_free].any()
    assert (sure_occupied | sure_free).mean() > 0.99
    assert 300 < exact.sum() < 1000
    # the visual-only box is not an obstacle; the sphere (z 1.6..2.6) pokes into the band
    assert not grid[int((-2.5 + 4) / res), int((3.0 + 4) / res)]
    assert grid[int((1.0 + 4) / res), int((-2.0 + 4) / res)]


def test_occupancy_grid_bad_input() -> None:
    world = _geometry_world()
    with pytest.raises(WorldError, match="resolution"):
        true_occupancy_grid(world, 0.0)
    with pytest.raises(WorldError, match="z_range"):
        true_occupancy_grid(world, 0.1, (1.0, 0.5))
    with pytest.raises(WorldError, match=r"shape \(\.\.\., 3\)"):
        obstacle_distance(world, np.zeros((4, 2)))


def _surface_samples(shape: Box | Cylinder | Sphere, n: int) -> np.ndarray:
    """Dense points on a shape's surface (the brute-force reference)."""
    if isinstance(shape, Sphere):
        u, v = np.meshgrid(np.linspace(0, np.pi, n), np.linspace(0, 2 * np.pi, 2 * n))
        local = shape.radius * np.column_stack(
            [(np.sin(u) * np.cos(v)).ravel(), (np.sin(u) * np.sin(v)).ravel(), np.cos(u).ravel()]
        )
        return local + np.asarray(shape.pos)
    if isinstance(shape, Cylinder):
        r, h = shape.radius, shape.length / 2
        a, z = np.meshgrid(np.linspace(0, 2 * np.pi, 2 * n), np.linspace(-h, h, n))
        side = np.column_stack([(r * np.cos(a)).ravel(), (r * np.sin(a)).ravel(), z.ravel()])
        rr, aa = np.meshgrid(np.linspace(0, r, n), np.linspace(0, 2 * np.pi, 2 * n))
        disc = np.column_stack([(rr * np.cos(aa)).ravel(), (rr * np.sin(aa)).ravel()])
        caps = [np.column_stack([disc, np.full(len(disc), s * h)]) for s in (-1, 1)]
        local = np.concatenate([side, *caps])
    else:
        half = np.asarray(shape.size) / 2
        g = np.linspace(-1, 1, n)
        faces = []
        for axis in range(3):
            others = [k for k in range(3) if k != axis]
            p, q = np.meshgrid(g, g)
            for sign in (-1, 1):
                face = np.zeros((p.size, 3))
                face[:, axis] = sign
                face[:, others[0]] = p.ravel()
                face[:, others[1]] = q.ravel()
                faces.append(face * half)
        local = np.concatenate(faces)
    return local @ shape.rotation.T + np.asarray(shape.pos)


@settings(max_examples=25, deadline=None)
@given(
    kind=st.sampled_from(["box", "cylinder", "sphere"]),
    rpy=st.tuples(*[st.floats(-math.pi, math.pi)] * 3),
    dims=st.tuples(*[st.floats(0.2, 2.0)] * 3),
    seed=st.integers(0, 2**31 - 1),
)
def test_obstacle_distance_matches_brute_force(
    kind: str, rpy: tuple[float, float, float], dims: tuple[float, float, float], seed: int
) -> None:
    pos = (0.3, -0.2, 1.0)
    shape: Box | Cylinder | Sphere
    if kind == "box":
        shape = Box(name="s", pos=pos, rpy=rpy, size=dims)
    elif kind == "cylinder":
        shape = Cylinder(name="s", pos=pos, rpy=rpy, radius=dims[0] / 2, length=dims[1])
    else:
        shape = Sphere(name="s", pos=pos, radius=dims[0] / 2)
    world = WorldDescription(name="w", ground=None, shapes=(shape,))
    points = np.random.default_rng(seed).uniform(-2.5, 2.5, (40, 3)) + np.asarray(pos)
    exact = obstacle_distance(world, points)
    n = 60
    surface = _surface_samples(shape, n)
    brute = np.min(np.linalg.norm(points[:, None, :] - surface[None, :, :], axis=2), axis=1)
    spacing = 2.0 * max(dims) / (n - 1) * math.pi  # generous bound of the sampling gap
    np.testing.assert_array_less(np.abs(exact) - 1e-9, brute + 1e-9)  # never beyond the surface
    np.testing.assert_array_less(brute - np.abs(exact), spacing)
    # the sign says inside or out: inside points are closer to the centre than any surface
    inside = exact < 0
    if isinstance(shape, Sphere):
        np.testing.assert_array_equal(
            inside, np.linalg.norm(points - np.asarray(pos), axis=1) < shape.radius
        )


def test_obstacle_distance_shapes_and_ground() -> None:
    world = world_from_dict(
        {"name": "w", "objects": [{"type": "sphere", "pos": [0, 0, 2], "radius": 1}]}
    )
    grid = np.zeros((2, 3, 3))
    grid[..., 2] = 2.0
    grid[0, 0] = [3.0, 0.0, 2.0]
    out = obstacle_distance(world, grid)
    assert out.shape == (2, 3)
    assert out[0, 0] == pytest.approx(2.0)
    assert out[1, 1] == pytest.approx(-1.0)
    assert obstacle_distance(world, [[5.0, 0.0, 0.25]], include_ground=True)[0] == pytest.approx(
        0.25
    )
    empty = WorldDescription(name="e", ground=None)
    assert np.isinf(obstacle_distance(empty, [[0.0, 0.0, 0.0]])).all()
