"""Fuzz the file readers: TUM trajectories and file lists, camera_info YAML, worlds, URDF/Xacro.

Each reader gets mutated versions of a valid file (and raw YAML gets random
text); only VisnavError subclasses may escape.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.description.robot import load_robot
from visnav.description.sdf_world import parse_sdf_world
from visnav.description.urdf import parse_urdf
from visnav.description.world import load_world
from visnav.msgs import CameraInfo, make
from visnav.perception.camera_info_yaml import read_camera_info_yaml, write_camera_info_yaml
from visnav.safe_yaml import load_yaml
from visnav.slam import TumSequence
from visnav.slam.trajectory import read_tum
from visnav.slam.tum import read_file_list

from .conftest import FUZZ, FUZZ_STRUCTURED, mutated, only_visnav_errors

TUM_TRAJECTORY = b"""\
# timestamp tx ty tz qx qy qz qw
1305031102.175304 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248
1305031102.211214 1.3303 0.6256 1.6464 0.6579 0.6161 -0.2932 -0.3189
1305031102.243211,1.3160,0.6254,1.6302,0.6609,0.6199,-0.2893,-0.3086
"""

RGB_TXT = b"""\
# color images
# timestamp filename
1305031102.175304 rgb/1305031102.175304.png
1305031102.211214 rgb/1305031102.211214.png
1305031102.243211 rgb/1305031102.243211.png
"""

DEPTH_TXT = RGB_TXT.replace(b"rgb", b"depth").replace(b"color", b"depth")

WORLD_YAML = b"""\
name: fuzz_world
seed: 3
physics: {timestep: 0.004, gravity: [0, 0, -9.5]}
ground: {size: [10, 8], material: floor}
textures:
  tiles: {type: checker, rgb1: [0.9, 0.9, 0.9], rgb2: [0.2, 0.2, 0.2]}
  plaster: {type: noise, rgb1: [0.9, 0.8, 0.6], rgb2: [0.3, 0.2, 0.1], width: 16, height: 16}
materials:
  floor: {texture: tiles, tile: 2.0}
  wall: {texture: plaster, tile: 1.0, specular: 0.1}
objects:
  - {type: box, name: wall, pos: [0, 3, 1], size: [6, 0.2, 2], material: wall}
  - {type: cylinder, name: pillar, pos: [2, 0, 1], radius: 0.3, length: 2, yaw: 0.5}
  - {type: sphere, pos: [-2, 0, 2], radius: 0.5, collision: false, rgba: [1, 0, 0]}
lights:
  - {type: directional, dir: [0, 0, -1], diffuse: [0.6, 0.6, 0.6]}
metadata: {start: [0, 0, 0], spawn: [1, 1, 0]}
"""

SDF_WORLD = b"""\
<sdf version="1.6">
  <world name="w">
    <include><uri>model://ground_plane</uri></include>
    <physics type="ode"><max_step_size>0.005</max_step_size></physics>
    <gravity>0 0 -9.7</gravity>
    <model name="crate"><static>true</static><pose>1 2 0 0 0 1.57</pose>
      <link name="body"><pose>0.5 0 0.5 0 0 0</pose>
        <collision name="c"><geometry><box><size>1 2 1</size></box></geometry></collision>
        <visual name="v"><geometry><cylinder><radius>0.2</radius><length>2</length></cylinder>
        </geometry><material><diffuse>1 0 0 1</diffuse></material></visual>
      </link></model>
  </world>
</sdf>
"""

URDF = b"""\
<robot name="rover">
  <link name="base_link">
    <inertial><origin xyz="0 0 0.1"/><mass value="2"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>
    <collision><geometry><box size="0.3 0.3 0.2"/></geometry></collision>
    <visual><geometry><cylinder radius="0.1" length="0.2"/></geometry></visual>
  </link>
  <link name="wheel"><inertial><mass value="0.5"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
    <collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="wheel_joint" type="continuous"><parent link="base_link"/><child link="wheel"/>
    <origin xyz="0 0.2 0" rpy="1.5708 0 0"/><axis xyz="0 0 1"/>
    <limit effort="10" velocity="5"/></joint>
  <gazebo reference="base_link">
    <sensor name="imu" type="imu"><update_rate>100</update_rate>
      <plugin name="imu_plugin" filename="libgazebo_ros_imu_sensor.so"/></sensor>
  </gazebo>
</robot>
"""

XACRO = b"""\
<?xml version="1.0"?>
<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="mass" default="2"/>
  <xacro:property name="side" value="0.3"/>
  <xacro:macro name="box_link" params="name size">
    <link name="${name}"><inertial><mass value="$(arg mass)"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>
      <collision><geometry><box size="${size} ${size} ${size}"/></geometry></collision></link>
  </xacro:macro>
  <xacro:box_link name="base_link" size="${side}"/>
  <xacro:if value="${side > 0.1}"><link name="extra"/>
    <joint name="j" type="fixed"><parent link="base_link"/><child link="extra"/></joint>
  </xacro:if>
</robot>
"""


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz_files")


def _camera_info_seed(workdir: Path) -> bytes:
    info = make(
        CameraInfo,
        height=480,
        width=640,
        distortion_model="plumb_bob",
        d=np.array([0.1, -0.2, 0.0, 0.001, 0.0]),
        k=np.array([500.0, 0, 320, 0, 500, 240, 0, 0, 1]),
        r=np.eye(3).reshape(-1),
        p=np.array([500.0, 0, 320, 0, 0, 500, 240, 0, 0, 0, 1, 0]),
    )
    return write_camera_info_yaml(workdir / "seed_camera.yaml", info).read_bytes()


def test_seeds_are_valid(workdir: Path) -> None:
    (workdir / "t.txt").write_bytes(TUM_TRAJECTORY)
    assert len(read_tum(workdir / "t.txt")) == 3
    (workdir / "rgb.txt").write_bytes(RGB_TXT)
    assert len(read_file_list(workdir / "rgb.txt")) == 3
    info = read_camera_info_yaml(_seed_cam(workdir))
    assert info.width == 640
    (workdir / "w.yaml").write_bytes(WORLD_YAML)
    assert load_world(workdir / "w.yaml").name == "fuzz_world"
    assert parse_sdf_world(SDF_WORLD.decode()).name == "w"
    assert "wheel" in parse_urdf(URDF.decode()).links
    (workdir / "x.urdf.xacro").write_bytes(XACRO)
    assert "extra" in load_robot(workdir / "x.urdf.xacro").urdf.links


def _seed_cam(workdir: Path) -> Path:
    path = workdir / "seed_camera.yaml"
    if not path.exists():
        _camera_info_seed(workdir)
    return path


@FUZZ
@given(blob=mutated(TUM_TRAJECTORY))
def test_tum_trajectory(workdir: Path, blob: bytes) -> None:
    path = workdir / "traj.txt"
    path.write_bytes(blob)
    traj = only_visnav_errors(read_tum, path)
    if traj is not None:
        assert np.isfinite(traj.positions).all()
        norms = np.linalg.norm(traj.quaternions, axis=1)
        assert (norms > 0).all()


@FUZZ
@given(rgb=mutated(RGB_TXT), depth=st.one_of(st.just(DEPTH_TXT), mutated(DEPTH_TXT)))
def test_tum_file_lists(workdir: Path, rgb: bytes, depth: bytes) -> None:
    folder = workdir / "seq"
    folder.mkdir(exist_ok=True)
    (folder / "rgb.txt").write_bytes(rgb)
    (folder / "depth.txt").write_bytes(depth)
    only_visnav_errors(read_file_list, folder / "rgb.txt")
    seq = only_visnav_errors(TumSequence, folder)
    if seq is not None:
        stamps = [f.stamp for f in seq.frames]
        assert stamps == sorted(stamps)


@FUZZ
@given(st.data())
def test_camera_info_yaml(workdir: Path, data: st.DataObject) -> None:
    blob = data.draw(mutated(_seed_cam(workdir).read_bytes()))
    path = workdir / "camera.yaml"
    path.write_bytes(blob)
    only_visnav_errors(read_camera_info_yaml, path)


@FUZZ
@given(blob=mutated(WORLD_YAML))
def test_world_yaml(workdir: Path, blob: bytes) -> None:
    path = workdir / "world.yaml"
    path.write_bytes(blob)
    only_visnav_errors(load_world, path)


@FUZZ
@given(blob=mutated(SDF_WORLD))
def test_sdf_world(workdir: Path, blob: bytes) -> None:
    path = workdir / "world.sdf"
    path.write_bytes(blob)
    only_visnav_errors(load_world, path)


@FUZZ
@given(blob=mutated(URDF))
def test_urdf(workdir: Path, blob: bytes) -> None:
    path = workdir / "robot.urdf"
    path.write_bytes(blob)
    only_visnav_errors(load_robot, path)


@FUZZ
@given(blob=mutated(XACRO), mass=st.sampled_from(["2", "-1", "nan", "x", ""]))
def test_xacro(workdir: Path, blob: bytes, mass: str) -> None:
    path = workdir / "robot.urdf.xacro"
    path.write_bytes(blob)
    only_visnav_errors(load_robot, path, args={"mass": mass})


@FUZZ
@given(text=st.text(max_size=120))
def test_yaml_loader_random_text(text: str) -> None:
    only_visnav_errors(load_yaml, text, source="fuzz.yaml")


@FUZZ
@given(blob=mutated(WORLD_YAML))
def test_yaml_loader_mutated(blob: bytes) -> None:
    only_visnav_errors(load_yaml, blob.decode("utf-8", errors="replace"), source="fuzz.yaml")


# --------------------------------------------------------------------------- structure-aware
_numbers = st.one_of(
    st.integers(-5, 5), st.floats(allow_nan=True, allow_infinity=True, width=32), st.just(1e300)
)
_values = st.recursive(
    st.one_of(st.none(), st.booleans(), _numbers, st.sampled_from(["", "x", "floor", "checker"])),
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.sampled_from(["a", "type"]), inner)
    ),
    max_leaves=6,
)
_vector = st.one_of(st.lists(_numbers, min_size=0, max_size=5), _values)


def _section(keys: tuple[str, ...]) -> st.SearchStrategy[dict[str, object]]:
    return st.dictionaries(st.sampled_from([*keys, "bogus"]), _vector, max_size=len(keys) + 1)


@FUZZ_STRUCTURED
@given(st.data())
def test_structured_world(data: st.DataObject) -> None:
    from visnav.description import world_yaml as wy
    from visnav.description.world_yaml import world_from_dict

    shape_type = data.draw(st.sampled_from([*wy._SHAPE_KEYS, "cube"]))
    shape = data.draw(_section(wy._COMMON_SHAPE_KEYS + wy._SHAPE_KEYS.get(shape_type, ())))
    shape["type"] = shape_type
    doc: dict[str, object] = {
        "name": data.draw(st.sampled_from(["w", "", "a b"])),
        "objects": [shape],
        "ground": data.draw(st.one_of(st.none(), _section(wy._GROUND_KEYS))),
        "physics": data.draw(_section(wy._PHYSICS_KEYS)),
        "lights": [data.draw(_section(wy._LIGHT_KEYS))],
        "textures": {"t": data.draw(_section(wy._TEXTURE_KEYS))},
        "materials": {"floor": data.draw(_section(wy._MATERIAL_KEYS))},
        "headlight": data.draw(_section(wy._HEADLIGHT_KEYS)),
    }
    keep = data.draw(st.lists(st.sampled_from(sorted(doc)), unique=True))
    only_visnav_errors(world_from_dict, {k: doc[k] for k in keep})


_CAMERA_FIELDS = (
    "image_width", "image_height", "camera_name", "camera_matrix", "distortion_model",
    "distortion_coefficients", "rectification_matrix", "projection_matrix",
)  # fmt: skip


@FUZZ_STRUCTURED
@given(st.data())
def test_structured_camera_info(workdir: Path, data: st.DataObject) -> None:
    import yaml

    doc = yaml.safe_load(_seed_cam(workdir).read_text())
    for key in data.draw(st.lists(st.sampled_from(_CAMERA_FIELDS), max_size=3)):
        if data.draw(st.booleans()):
            doc.pop(key, None)
        elif isinstance(doc.get(key), dict) and data.draw(st.booleans()):
            sub = data.draw(st.sampled_from(["rows", "cols", "data"]))
            doc[key][sub] = data.draw(_vector)
        else:
            doc[key] = data.draw(_vector)
    path = workdir / "structured_camera.yaml"
    path.write_text(yaml.safe_dump(doc))
    only_visnav_errors(read_camera_info_yaml, path)
