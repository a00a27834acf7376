"""RobotModel (RViz's): robot_description visuals placed by TF; the default layout."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("rerun")

import contextlib

from visnav.msgs import CameraInfo, String, make, numpy_to_image
from visnav.viz import VizError
from visnav.viz import sink as sink_module
from visnav.viz.layout import default_blueprint
from visnav.viz.robot_model import RobotModel, parse_robot_description, robot_visuals

T0 = 1_000_000_000

STL = """solid tri
facet normal 0 0 1
 outer loop
  vertex 0 0 0
  vertex 1 0 0
  vertex 0 1 0
 endloop
endfacet
endsolid tri
"""


def _urdf(mesh_dir: Path) -> str:
    (mesh_dir / "wing.stl").write_text(STL)
    (mesh_dir / "body.msh").write_bytes(b"\0" * 16)  # MuJoCo's format: Rerun cannot read it
    return f"""<robot name="rover">
  <material name="red"><color rgba="1 0 0 1"/></material>
  <link name="base_link">
    <visual><origin xyz="0 0 0.1"/><geometry><box size="0.4 0.2 0.1"/></geometry>
      <material name="red"/></visual>
    <visual><origin xyz="0.2 0 0" rpy="0 1.5707963 0"/>
      <geometry><cylinder radius="0.05" length="0.1"/></geometry></visual>
  </link>
  <link name="camera_link">
    <visual><geometry><sphere radius="0.03"/></geometry></visual>
    <visual><geometry>
      <mesh filename="file://{mesh_dir}/wing.stl" scale="2 2 2"/></geometry></visual>
    <visual><geometry><mesh filename="file://{mesh_dir}/body.msh"/></geometry></visual>
  </link>
  <link name="imu_link"/>
  <joint name="cam" type="fixed"><parent link="base_link"/><child link="camera_link"/>
    <origin xyz="0.3 0 0.2"/></joint>
  <joint name="imu" type="fixed"><parent link="base_link"/><child link="imu_link"/></joint>
</robot>"""


def test_visuals_of_every_shape(tmp_path: Path) -> None:
    visuals = robot_visuals(parse_robot_description(_urdf(tmp_path)))
    by = {(v.link, v.index): v for v in visuals}
    assert sorted(by) == [
        ("base_link", 0),
        ("base_link", 1),
        ("camera_link", 0),
        ("camera_link", 1),
        ("camera_link", 2),
    ]
    box = by[("base_link", 0)]
    assert box.shape == "box"
    assert box.size == (0.4, 0.2, 0.1)
    assert box.rgba == (1.0, 0.0, 0.0, 1.0)
    assert np.allclose(box.T_link_visual[:3, 3], [0, 0, 0.1])
    cyl = by[("base_link", 1)]
    assert cyl.shape == "cylinder"
    assert cyl.size == (0.05, 0.1)
    assert np.allclose(cyl.T_link_visual[:3, 2], [1, 0, 0], atol=1e-6)  # pitched onto x
    assert by[("camera_link", 0)].shape == "sphere"
    mesh = by[("camera_link", 1)]
    assert mesh.shape == "mesh"
    assert mesh.size == (2.0, 2.0, 2.0)
    assert mesh.mesh_path.endswith("wing.stl")


def test_bad_description_is_one_clear_error() -> None:
    with pytest.raises(VizError, match=r"^/robot_description: cannot show the robot model: "):
        parse_robot_description("<robot name='x'><link>", source="/robot_description")


def test_robot_model_is_placed_by_tf(session: Any, vz: Any, tmp_path: Path, caplog: Any) -> None:
    s = session(fixed_frame="odom")
    s.log("/tf_static", vz.tf_msg(vz.tf("base_link", "camera_link", 0, (0.3, 0.0, 0.2))))
    s.log("/tf", vz.tf_msg(vz.tf("odom", "base_link", T0, (1.0, 0.0, 0.0))))
    with caplog.at_level(logging.WARNING, logger="visnav.viz"):
        assert s.log("/robot_description", String(data=_urdf(tmp_path)), T0)
    assert "1 visual(s) not drawn" in caplog.text
    assert "body.msh" in caplog.text
    s.log("/tf", vz.tf_msg(vz.tf("odom", "base_link", 2 * T0, (2.0, 0.5, 0.0))))
    model = s.sink.robot_models["/robot_description"]
    assert model.placed == {"base_link", "camera_link"}
    rrd = s.finish()
    base = "world/robot_model/rover/base_link"
    cam = "world/robot_model/rover/camera_link"
    trans = rrd.rows(base, "Transform3D:translation")
    assert np.allclose(trans[0], [1.0, 0.0, 0.0])
    assert np.allclose(trans[-1], [2.0, 0.5, 0.0])
    assert np.allclose(rrd.rows(cam, "Transform3D:translation")[-1], [2.3, 0.5, 0.2])
    # geometry: static, under the link, with the visual's origin
    assert np.allclose(rrd.rows(f"{base}/visual_0", "Boxes3D:half_sizes")[0], [[0.2, 0.1, 0.05]])
    assert np.allclose(rrd.rows(f"{base}/visual_0", "Transform3D:translation")[0], [0, 0, 0.1])
    assert rrd.rows(f"{base}/visual_1", "Cylinders3D:radii")[0] == pytest.approx([0.05])
    assert rrd.rows(f"{cam}/visual_0", "Ellipsoids3D:half_sizes")
    assert rrd.rows(f"{cam}/visual_1", "Asset3D:blob")
    assert np.allclose(rrd.rows(f"{cam}/visual_1", "Transform3D:scale")[0], [2, 2, 2])
    assert f"{cam}/visual_2" not in rrd.entities  # .msh: Rerun cannot read it


def test_invalid_description_is_counted_not_fatal(session: Any) -> None:
    s = session()
    assert not s.log("/robot_description", String(data="<robot"), T0)
    assert s.sink.stats()["/robot_description"]["errors"] == 1
    assert not s.log("/chatter", String(data="hello"))  # other strings are not shown


def test_quadrotor_description_shows(session: Any, vz: Any) -> None:
    from visnav.description.robot import expand_xacro

    xacro = Path(__file__).parents[2] / "src/visnav/description/robots/quadrotor.urdf.xacro"
    text = expand_xacro(str(xacro))
    model = RobotModel(parse_robot_description(text), "world/robot_model/quadrotor")
    assert model.visuals
    assert "base_link" in model.frames
    s = session(fixed_frame="world")
    s.log("/tf", vz.tf_msg(vz.tf("world", "base_link", T0, (0.0, 0.0, 1.0))))
    assert s.log("/drone/robot_description", String(data=text), T0)
    rrd = s.finish()
    assert any(e.startswith("world/robot_model/drone/quadrotor/base_link") for e in rrd.entities)


def test_layout_puts_the_cameras_beside_the_3d_view(
    session: Any, vz: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    sent: list[list[str]] = []

    def record(root: str, cameras: list[str], *, timeline: str) -> Any:
        sent.append(list(cameras))
        assert timeline == "ros_time"
        return default_blueprint(root, cameras, timeline=timeline)

    monkeypatch.setattr(sink_module, "default_blueprint", record)
    s = session(fixed_frame="cam")
    img = numpy_to_image(np.zeros((4, 6, 3), np.uint8), "rgb8", header=vz.header("cam", T0))
    s.log("/front/image_raw", img)
    s.log("/front/camera_info", make(CameraInfo, header=vz.header("cam", T0), width=6, height=4))
    s.log("/rear/image_raw", img)
    s.finish()
    assert sent == [[], ["world/cameras/front"], ["world/cameras/front", "world/cameras/rear"]]
    bp = default_blueprint("world", ["world/cameras/front", "world/cameras/rear"])
    root = bp.root_container
    assert type(root).__name__ == "Horizontal"
    view3d, column = root.contents
    assert type(view3d).__name__ == "Spatial3DView"
    assert str(view3d.origin) == "/world"
    assert [type(v).__name__ for v in column.contents] == ["Spatial2DView", "Spatial2DView"]
    assert [str(v.origin) for v in column.contents] == [
        "/world/cameras/front",
        "/world/cameras/rear",
    ]
    assert bp.time_panel is not None  # follows the newest data, as RViz shows now


@settings(max_examples=150, deadline=None)
@given(
    st.one_of(
        st.text(max_size=80),
        st.builds(
            lambda body: f"<robot name='r'><link name='a'>{body}</link></robot>",
            st.text(alphabet="<>/=\"' abcdeglinorstvxyz0123456789.-", max_size=60),
        ),
    )
)
def test_parse_robot_description_fuzz(text: str) -> None:
    with contextlib.suppress(VizError):
        robot_visuals(parse_robot_description(text))


def test_collada_meshes_are_drawn_with_their_colours(session: Any, vz: Any) -> None:
    """A .dae mesh (Rerun cannot read Collada) is read by visnav into one coloured Mesh3D."""
    dae = Path(__file__).parents[1] / "data/husky/husky_description/meshes/top_plate.dae"
    urdf = f"""<robot name="plate"><link name="base_link">
    <visual><geometry><mesh filename="file://{dae}"/></geometry></visual></link></robot>"""
    s = session(fixed_frame="base_link")
    s.log("/tf_static", vz.tf_msg(vz.tf("base_link", "base_link_", 0)))
    assert s.log("/robot_description", String(data=urdf), T0)
    rrd = s.finish()
    (entity,) = [e for e in rrd.entities if e.endswith("base_link/visual_0")]
    assert "Mesh3D:vertex_positions" in rrd.columns(entity)
    verts = np.asarray(rrd.rows(entity, "Mesh3D:vertex_positions")[0])
    colors = np.asarray(rrd.rows(entity, "Mesh3D:vertex_colors")[0])
    assert len(verts) >= 8  # the plate: a box-like solid
    assert len(colors) == len(verts)
