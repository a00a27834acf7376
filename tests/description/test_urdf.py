"""URDF / Xacro parsing: typed model, resource resolution, and clear errors for bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from visnav.description.rigid import (
    matrix_to_quat_wxyz,
    matrix_to_quat_xyzw,
    quat_xyzw_to_matrix,
    rpy_to_matrix,
)
from visnav.description.robot import load_robot
from visnav.description.urdf import (
    Box,
    Capsule,
    Cylinder,
    Mesh,
    RobotDescriptionError,
    Sphere,
    iter_links_depth_first,
    load_urdf,
    parse_urdf,
)

CUBE_OBJ = """v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
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

INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'


def robot(body: str, name: str = "r") -> str:
    return f'<?xml version="1.0"?>\n<robot name="{name}">\n{body}\n</robot>\n'


FULL = robot(
    f"""
  <material name="red"><color rgba="1 0 0 1"/></material>
  <link name="base">
    <inertial><origin xyz="0.1 0 0" rpy="0 0 0.5"/><mass value="3"/>{INERTIA}</inertial>
    <visual><origin xyz="0 0 0.1"/><geometry><box size="0.4 0.2 0.1"/></geometry>
      <material name="red"/></visual>
    <visual name="later"><geometry><sphere radius="0.05"/></geometry>
      <material name="green"/></visual>
    <collision><geometry><cylinder radius="0.1" length="0.3"/></geometry></collision>
  </link>
  <link name="arm"><inertial><mass value="1"/>{INERTIA}</inertial>
    <visual><geometry><capsule radius="0.02" length="0.2"/></geometry>
      <material name="inline"><color rgba="0 0 1 0.5"/></material></visual></link>
  <link name="slider"><inertial><mass value="0.5"/>{INERTIA}</inertial></link>
  <link name="wheel"><inertial><mass value="0.2"/>{INERTIA}</inertial></link>
  <link name="tool"/>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="arm"/><origin xyz="0 0 0.2" rpy="0 0.1 0"/>
    <axis xyz="0 0 2"/><limit lower="-1" upper="1.5" effort="10" velocity="2"/>
    <dynamics damping="0.3" friction="0.1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="arm"/><child link="slider"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.3" effort="5" velocity="1"/>
  </joint>
  <joint name="spin" type="continuous">
    <parent link="base"/><child link="wheel"/><axis xyz="0 1 0"/>
    <mimic joint="shoulder" multiplier="2" offset="0.1"/>
  </joint>
  <joint name="tool_joint" type="fixed"><parent link="slider"/><child link="tool"/>
    <origin xyz="0.05 0 0"/><calibration rising="0"/></joint>
  <material name="green"><color rgba="0 1 0 1"/></material>
"""
)


def test_parse_full_robot() -> None:
    urdf = parse_urdf(FULL)
    assert urdf.name == "r"
    assert urdf.root == "base"
    assert set(urdf.links) == {"base", "arm", "slider", "wheel", "tool"}
    base = urdf.links["base"]
    assert base.inertial is not None
    assert base.inertial.mass == 3.0
    assert base.inertial.origin.rpy == (0.0, 0.0, 0.5)
    assert isinstance(base.visuals[0].geometry, Box)
    assert base.visuals[0].geometry.size == (0.4, 0.2, 0.1)
    assert base.visuals[0].material is not None
    assert base.visuals[0].material.rgba == (1.0, 0.0, 0.0, 1.0)
    # A material defined after its use resolves too.
    assert base.visuals[1].material is not None
    assert base.visuals[1].material.rgba == (0.0, 1.0, 0.0, 1.0)
    assert base.visuals[1].name == "later"
    assert isinstance(base.visuals[1].geometry, Sphere)
    assert isinstance(base.collisions[0].geometry, Cylinder)
    assert isinstance(urdf.links["arm"].visuals[0].geometry, Capsule)
    assert urdf.links["tool"].inertial is None
    shoulder = urdf.joints["shoulder"]
    assert shoulder.type == "revolute"
    assert shoulder.axis == (0.0, 0.0, 1.0)
    assert shoulder.limit is not None
    assert (shoulder.limit.lower, shoulder.limit.upper) == (-1, 1.5)
    assert shoulder.dynamics.damping == 0.3
    assert shoulder.dynamics.friction == 0.1
    assert urdf.joints["spin"].mimic is not None
    assert urdf.joints["spin"].mimic.multiplier == 2.0
    assert urdf.joints["slide"].moves
    assert not urdf.joints["tool_joint"].moves
    assert urdf.warnings == ()  # <calibration> is real-robot metadata, not a warning
    order = [link.name for link, _ in iter_links_depth_first(urdf)]
    assert order[0] == "base"
    assert order.index("arm") < order.index("slider") < order.index("tool")
    assert urdf.parent_joint("tool") is not None
    assert urdf.parent_joint("base") is None


def test_meshes_resolve_relative_package_and_file_uris(tmp_path: Path) -> None:
    pkg = tmp_path / "src" / "my_robot"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>my_robot</name></package>")
    (pkg / "meshes" / "cube.obj").write_text(CUBE_OBJ)
    (pkg / "meshes" / "cube.stl").write_text("solid x\nendsolid x\n")
    urdf_dir = pkg / "urdf"
    urdf_dir.mkdir()
    body = f"""
  <link name="a"><inertial><mass value="1"/>{INERTIA}</inertial>
    <visual><geometry><mesh filename="package://my_robot/meshes/cube.obj" scale="2 2 2"/>
    </geometry></visual>
    <visual><geometry><mesh filename="../meshes/cube.stl"/></geometry></visual>
    <visual><geometry><mesh filename="file://{pkg}/meshes/cube.obj"/></geometry></visual>
  </link>"""
    path = urdf_dir / "r.urdf"
    path.write_text(robot(body))
    urdf = load_urdf(path)
    meshes = [v.geometry for v in urdf.links["a"].visuals]
    assert all(isinstance(m, Mesh) for m in meshes)
    assert [m.path for m in meshes] == [  # type: ignore[union-attr]
        (pkg / "meshes" / "cube.obj").resolve(),
        (pkg / "meshes" / "cube.stl").resolve(),
        (pkg / "meshes" / "cube.obj").resolve(),
    ]
    assert meshes[0].scale == (2.0, 2.0, 2.0)  # type: ignore[union-attr]
    # An explicit package mapping works for text without a file.
    text = robot(body.replace("../meshes/cube.stl", "package://other/cube.stl"))
    urdf = parse_urdf(text, packages={"my_robot": pkg, "other": pkg / "meshes"})
    assert len(urdf.links["a"].visuals) == 3


def test_missing_mesh_names_file_element_and_paths(tmp_path: Path) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(
        robot(
            '<link name="a">\n<visual><geometry>\n'
            '<mesh filename="package://nopkg/meshes/body.stl"/>\n'
            "</geometry></visual></link>"
        )
    )
    with pytest.raises(RobotDescriptionError) as info:
        load_urdf(path)
    text = str(info.value)
    assert f"{path}:5" in text  # file and line of the <mesh>
    assert "<mesh>" in text
    assert "link 'a'" in text
    assert "package://nopkg/meshes/body.stl" in text
    assert "tried" in text
    assert "Fix:" in text


def test_unsupported_mesh_format_is_a_warning(tmp_path: Path) -> None:
    (tmp_path / "m.ply").write_text("ply")  # Collada, OBJ, STL and MSH are read
    text = robot(
        f'<link name="a"><inertial><mass value="1"/>{INERTIA}</inertial>'
        '<visual><geometry><mesh filename="m.ply"/></geometry></visual></link>'
    )
    urdf = parse_urdf(text, base_dir=tmp_path)
    assert urdf.links["a"].visuals == ()
    assert any("m.ply" in w and "Collada, STL or OBJ" in w for w in urdf.warnings)


def test_unknown_elements_and_transmissions_warn() -> None:
    text = robot(
        '<link name="a"><sensor_thing/></link><transmission name="t"/><foo/>'
        '<link name="b"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/>'
        "<bar/></joint>"
    )
    urdf = parse_urdf(text)
    joined = "\n".join(urdf.warnings)
    for needle in ("<sensor_thing>", "transmission 't'", "<foo>", "<bar>"):
        assert needle in joined


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ('<link name="a"/><link name="a"/>', "duplicate link name 'a'"),
        ('<link name="a"/><link name="b"/>', "2 root links"),
        (
            '<link name="a"/><joint name="j" type="fixed"><parent link="a"/>'
            '<child link="nope"/></joint>',
            "child link 'nope' does not exist",
        ),
        (
            '<link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/>'
            '<child link="b"/></joint>',
            "needs <limit>",
        ),
        (
            '<link name="a"/><link name="b"/><joint name="j" type="continuous"><parent link="a"/>'
            '<child link="b"/><axis xyz="0 0 0"/></joint>',
            "axis xyz=(0.0, 0.0, 0.0) is zero",
        ),
        (
            '<link name="a"/><link name="b"/><joint name="j" type="ball"><parent link="a"/>'
            '<child link="b"/></joint>',
            "type='ball'",
        ),
        (
            '<link name="a"/><link name="b"/><joint name="j" type="planar"><parent link="a"/>'
            '<child link="b"/></joint>',
            "planar joints are not supported",
        ),
        (
            '<link name="a"><visual><geometry><box size="1 0 1"/></geometry></visual></link>',
            "non-positive edge",
        ),
        (
            '<link name="a"><visual><geometry><box size="1 x 1"/></geometry></visual></link>',
            "not 3 finite number",
        ),
        ('<link name="a"><visual><geometry/></visual></link>', "exactly one shape"),
        ('<link name="a"><inertial><mass value="-1"/></inertial></link>', "value=-1.0"),
        (
            '<link name="a"/><link name="b"/><link name="c"/>'
            '<joint name="j1" type="fixed"><parent link="a"/><child link="b"/></joint>'
            '<joint name="j2" type="fixed"><parent link="c"/><child link="b"/></joint>',
            "already the child",
        ),
        (
            '<link name="a"/><link name="b"/><link name="c"/>'
            '<joint name="j1" type="fixed"><parent link="b"/><child link="c"/></joint>'
            '<joint name="j2" type="fixed"><parent link="c"/><child link="b"/></joint>',
            "cycle",
        ),
    ],
)
def test_bad_urdf_is_one_clear_error(body: str, needle: str) -> None:
    with pytest.raises(RobotDescriptionError) as info:
        parse_urdf(robot(body), source="bad.urdf")
    text = str(info.value)
    assert needle in text, text
    assert text.startswith("bad.urdf:")
    assert "Fix:" in text


@pytest.mark.parametrize(
    ("inertia", "moments"),
    [
        ("ixx='1' iyy='1' izz='5' ixy='0' ixz='0' iyz='0'", [2.0, 2.0, 4.0]),  # triangle
        # Husarion ROSbot 2.0's body_link: a negative principal moment, then the triangle
        ("ixx='0.01' ixy='0.01' ixz='0' iyy='0.01' iyz='0.01' izz='0.01'", None),
    ],
)
def test_non_physical_inertia_is_replaced_by_the_nearest_physical_one(
    inertia: str, moments: list[float] | None
) -> None:
    body = f"<link name='a'><inertial><mass value='1'/><inertia {inertia}/></inertial></link>"
    urdf = parse_urdf(robot(body), source="bad.urdf")  # Gazebo runs it: not an error
    (warning,) = urdf.warnings
    assert warning.startswith("bad.urdf:")
    assert "is not physical" in warning
    assert "nearest physical tensor" in warning
    inertial = urdf.links["a"].inertial
    assert inertial is not None
    eig = np.linalg.eigvalsh(inertial.inertia_matrix())
    assert eig.min() >= -1e-12
    assert eig[0] + eig[1] >= eig[2] - 1e-12
    if moments is not None:
        np.testing.assert_allclose(eig, moments)
    again = robot(body.replace(inertia, " ".join(
        f"{n}='{v!r}'" for n, v in zip(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"),
                                       inertial.inertia, strict=True)
    )))  # fmt: skip
    assert not parse_urdf(again).warnings  # the replacement is physical


def test_the_axis_of_a_fixed_joint_is_not_read() -> None:
    """urdfdom reads <axis> of moving joints only (ROSbot 2.0 writes xyz="0 0 0" on a fixed one)."""
    body = (
        '<link name="a"/><link name="b"/><joint name="j" type="fixed"><parent link="a"/>'
        '<child link="b"/><axis xyz="0 0 0"/></joint>'
    )
    assert parse_urdf(robot(body)).joints["j"].type == "fixed"


def test_malformed_xml_reports_line_and_column() -> None:
    with pytest.raises(RobotDescriptionError, match=r"x\.urdf:3:\d+: malformed XML"):
        parse_urdf('<robot name="r">\n<link name="a">\n</robot>', source="x.urdf")


def test_root_must_be_robot() -> None:
    with pytest.raises(RobotDescriptionError, match="root element is not <robot>"):
        parse_urdf("<sdf/>")


# --------------------------------------------------------------------------- xacro

XACRO = """<?xml version="1.0"?>
<robot name="xr" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="width" default="0.5"/>
  <xacro:property name="w" value="$(arg width)"/>
  <xacro:macro name="box_link" params="name size">
    <link name="${name}">
      <inertial><mass value="1"/>
        <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>
      <visual><geometry><box size="${size} ${size} ${size}"/></geometry></visual>
    </link>
  </xacro:macro>
  <xacro:box_link name="base" size="${w}"/>
  <xacro:include filename="$(find parts)/wheel.xacro"/>
</robot>
"""

WHEEL = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <link name="wheel"><inertial><mass value="1"/>
    <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="axle" type="continuous"><parent link="base"/><child link="wheel"/></joint>
</robot>
"""


def test_xacro_with_args_and_find(tmp_path: Path) -> None:
    parts = tmp_path / "parts"
    parts.mkdir()
    (parts / "wheel.xacro").write_text(WHEEL)
    path = tmp_path / "robot.urdf.xacro"
    path.write_text(XACRO)
    desc = load_robot(path, args={"width": "0.25"}, packages={"parts": parts})
    assert desc.name == "xr"
    geometry = desc.urdf.links["base"].visuals[0].geometry
    assert isinstance(geometry, Box)
    assert geometry.size == (0.25, 0.25, 0.25)
    assert "wheel" in desc.urdf.links
    assert desc.urdf.joints["axle"].type == "continuous"
    default = load_robot(path, packages={"parts": parts})
    geometry = default.urdf.links["base"].visuals[0].geometry
    assert isinstance(geometry, Box)
    assert geometry.size == (0.5, 0.5, 0.5)
    # The same document as text (no file): $(find) still works.
    from_text = load_robot(XACRO, packages={"parts": parts})
    assert set(from_text.urdf.links) == {"base", "wheel"}


def test_xacro_errors_name_the_file(tmp_path: Path) -> None:
    path = tmp_path / "broken.xacro"
    path.write_text(XACRO.replace("${w}", "${undefined_property}"))
    with pytest.raises(RobotDescriptionError) as info:
        load_robot(path, packages={"parts": tmp_path})
    text = str(info.value)
    assert str(path) in text
    assert "xacro failed" in text
    assert "undefined_property" in text
    missing = tmp_path / "missing_pkg.xacro"
    missing.write_text(XACRO)
    with pytest.raises(RobotDescriptionError, match=r"package 'parts' not found"):
        load_robot(missing)


def test_plain_urdf_with_args_warns(tmp_path: Path) -> None:
    path = tmp_path / "r.urdf"
    path.write_text(robot(f'<link name="a"><inertial><mass value="1"/>{INERTIA}</inertial></link>'))
    desc = load_robot(path, args={"x": "1"})
    assert any("not Xacro" in w for w in desc.warnings)
    with pytest.raises(RobotDescriptionError, match="the robot description does not exist"):
        load_robot(tmp_path / "nope.urdf")


# --------------------------------------------------------------------------- rotations

angles = st.floats(min_value=-math.pi, max_value=math.pi, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(angles, angles, angles)
def test_rpy_matches_scipy_fixed_axes(r: float, p: float, y: float) -> None:
    expected = Rotation.from_euler("xyz", [r, p, y]).as_matrix()
    np.testing.assert_allclose(rpy_to_matrix((r, p, y)), expected, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4))
def test_quaternion_round_trip(q: list[float]) -> None:
    if np.linalg.norm(q) < 1e-3:
        return
    rot = quat_xyzw_to_matrix(q)
    x, y, z, w = matrix_to_quat_xyzw(rot)
    np.testing.assert_allclose(quat_xyzw_to_matrix((x, y, z, w)), rot, atol=1e-9)
    assert w >= 0
    np.testing.assert_allclose(Rotation.from_quat([x, y, z, w]).as_matrix(), rot, atol=1e-9)
    assert matrix_to_quat_wxyz(rot) == (w, x, y, z)
