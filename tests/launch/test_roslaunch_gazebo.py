"""roslaunch import of Gazebo launch files: spawn_model options, empty_world args, packages,
``.launch.xml`` includes, searchParam'd ``tf_prefix`` and ``--skip-unmapped``."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from visnav.cli.main import main
from visnav.launch import RoslaunchImportError, load_launch

URDF = '<robot name="bot"><link name="base"/></robot>'


def _package(root: Path, name: str, launch: str, files: dict[str, str] | None = None) -> Path:
    pkg = root / name
    (pkg / "launch").mkdir(parents=True)
    (pkg / "package.xml").write_text(f"<package><name>{name}</name></package>")
    (pkg / "launch" / "robot.launch").write_text(textwrap.dedent(launch).lstrip())
    for rel, text in (files or {}).items():
        (pkg / rel).parent.mkdir(parents=True, exist_ok=True)
        (pkg / rel).write_text(text)
    return pkg / "launch" / "robot.launch"


def _spawn_file(tmp_path: Path, spawn_args: str, world_args: str = "") -> Path:
    return _package(
        tmp_path,
        "my_bot",
        f"""
        <launch>
          <include file="$(find gazebo_ros)/launch/empty_world.launch">{world_args}</include>
          <param name="robot_description" textfile="$(find my_bot)/urdf/bot.urdf"/>
          <node pkg="gazebo_ros" type="spawn_model" name="spawn" args="{spawn_args}"/>
        </launch>
        """,
        {"urdf/bot.urdf": URDF},
    )


def test_spawn_options_noted_and_mapped(tmp_path: Path) -> None:
    f = _spawn_file(
        tmp_path,
        "-urdf -param robot_description -model bot -x 1 -Y 0.5 -R 0.1 -J arm 0.3 -unpause "
        "-b -wait ground_plane -package_to_model -gazebo_namespace /sim -reference_frame world",
    )
    desc = load_launch(f)
    (sim,) = desc.nodes
    assert sim.params["spawn"] == [1.0, 0.0, 0.0, 0.5]
    assert sim.params["robot"] == URDF
    notes = " | ".join(desc.notes)
    for fragment in (
        "-R 0.1 (visnav spawns a robot upright",
        "-J arm=0.3 (joints start at 0)",
        "-gazebo_namespace /sim",
        "-b ignored: there is no bond",
        "-wait ground_plane ignored",
        "-package_to_model ignored",
    ):
        assert fragment in notes, fragment
    # the file's own package reaches the sim for package:// and model://
    assert sim.params["packages"] == [f"my_bot={tmp_path / 'my_bot'}"]


@pytest.mark.parametrize(
    ("spawn_args", "fragment"),
    [
        ("-database cafe_table -model t", "-database: visnav has no Gazebo model database"),
        ("-stdin -model t", "-stdin: the model cannot be read from standard input"),
    ],
)
def test_spawn_refusals_are_listed(tmp_path: Path, spawn_args: str, fragment: str) -> None:
    with pytest.raises(RoslaunchImportError) as info:
        load_launch(_spawn_file(tmp_path, spawn_args))
    assert fragment in str(info.value)
    assert "give the robot with -param" not in str(info.value)


@pytest.mark.parametrize(
    ("spawn_args", "fragment"),
    [
        ("-sdf -param robot_description -model t", "-sdf: visnav spawns URDF robots only"),
        (
            "-urdf -param robot_description -model t -reference_frame table::link",
            "-reference_frame table::link: visnav places a spawned robot in the world frame",
        ),
    ],
)
def test_spawns_that_cannot_fold(tmp_path: Path, spawn_args: str, fragment: str) -> None:
    with pytest.raises(RoslaunchImportError, match=fragment):
        load_launch(_spawn_file(tmp_path, spawn_args))


def test_paused_is_a_note_not_a_sim_parameter(tmp_path: Path) -> None:
    world = '<arg name="paused" value="true"/><arg name="verbose" value="true"/>'
    desc = load_launch(_spawn_file(tmp_path, "-urdf -param robot_description -model b", world))
    assert "paused" not in desc.nodes[0].params
    notes = " | ".join(desc.notes)
    assert "paused:=true is ignored" in notes
    assert "verbose:=true" in notes


def test_launch_xml_include_shares_the_parameter_server(tmp_path: Path) -> None:
    f = _package(
        tmp_path,
        "bot_bringup",
        """
        <launch>
          <arg name="multi" default="r2"/>
          <param name="tf_prefix" value="$(arg multi)"/>
          <include file="$(find bot_bringup)/launch/includes/description.launch.xml"/>
          <group ns="r2">
            <node pkg="robot_state_publisher" type="robot_state_publisher" name="rsp"/>
          </group>
        </launch>
        """,
        {
            "launch/includes/description.launch.xml": (
                '<launch><param name="robot_description" '
                'textfile="$(find bot_bringup)/bot.urdf"/></launch>'
            ),
            "bot.urdf": URDF,
        },
    )
    desc = load_launch(f)
    (rsp,) = desc.nodes
    assert rsp.params["robot_description"] == URDF  # searchParam up from /r2
    assert rsp.params["frame_prefix"] == "r2/"  # tf_prefix found by searchParam too


def test_find_through_ros_package_path_reaches_the_sim(tmp_path: Path) -> None:
    other = tmp_path / "ws" / "src" / "deep" / "assets"
    other.mkdir(parents=True)
    (other / "package.xml").write_text("<package><name>bot_assets</name></package>")
    (tmp_path / "ws" / "src" / "ignored").mkdir()
    (tmp_path / "ws" / "src" / "ignored" / "CATKIN_IGNORE").write_text("")
    f = _package(
        tmp_path,
        "my_bot",
        """
        <launch>
          <include file="$(find gazebo_ros)/launch/empty_world.launch"/>
          <param name="unused_path" value="$(find bot_assets)/worlds"/>
        </launch>
        """,
    )
    desc = load_launch(f, env={"ROS_PACKAGE_PATH": str(tmp_path / "ws")})
    packages = desc.nodes[0].params["packages"]
    assert f"bot_assets={other}" in packages
    assert f"my_bot={tmp_path / 'my_bot'}" in packages


def test_skip_unmapped_leaves_out_what_cannot_be_mapped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = _package(
        tmp_path,
        "my_bot",
        """
        <launch>
          <env name="X" value="1"/>
          <node pkg="twist_mux" type="twist_mux" name="mux"/>
          <node pkg="image_proc" type="image_proc" name="proc" args="--bad"/>
          <node pkg="tf2_ros" type="static_transform_publisher" name="tf"
                args="0 0 0 0 0 0 a b"/>
        </launch>
        """,
    )
    with pytest.raises(RoslaunchImportError, match="cannot import 3 elements"):
        load_launch(f)
    desc = load_launch(f, skip_unmapped=True)
    assert [n.name for n in desc.nodes] == ["tf"]
    skipped = [n for n in desc.notes if n.startswith("skipped (--skip-unmapped): ")]
    assert len(skipped) == 3
    assert any("<env> has no visnav counterpart" in n for n in skipped)
    assert any("twist_mux" in n for n in skipped)
    assert main(["launch", "--print", str(f), "--skip-unmapped"]) == 0
    assert "skipped (--skip-unmapped)" in capsys.readouterr().out


def test_state_publishers_are_left_out_when_the_sim_has_the_robot(tmp_path: Path) -> None:
    f = _package(
        tmp_path,
        "my_bot",
        """
        <launch>
          <include file="$(find gazebo_ros)/launch/empty_world.launch"/>
          <param name="robot_description" textfile="$(find my_bot)/urdf/bot.urdf"/>
          <node pkg="gazebo_ros" type="spawn_model" name="spawn"
                args="-urdf -param robot_description -model bot"/>
          <node pkg="joint_state_publisher" type="joint_state_publisher" name="jsp"/>
          <node pkg="robot_state_publisher" type="robot_state_publisher" name="rsp"/>
        </launch>
        """,
        {"urdf/bot.urdf": URDF},
    )
    desc = load_launch(f)
    assert [n.executable for n in desc.nodes] == ["sim"]
    notes = " | ".join(desc.notes)
    assert "joint_state_publisher /jsp" in notes
    assert "robot_state_publisher /rsp" in notes


def test_spawned_plugins_get_the_spawners_namespace_as_gazebo_ros_adds_it() -> None:
    from visnav.launch.ros_gazebo import add_plugin_namespaces

    urdf = """<robot name="r"><link name="a"/>
      <gazebo><plugin name="c" filename="libgazebo_ros_control.so"/></gazebo>
      <gazebo reference="a"><sensor type="ray" name="s">
        <plugin name="l" filename="libgazebo_ros_laser.so"><topicName>scan</topicName></plugin>
      </sensor></gazebo>
      <gazebo><plugin name="k" filename="libgazebo_ros_diff_drive.so">
        <robotNamespace>/mine</robotNamespace></plugin></gazebo>
      <gazebo><plugin name="n" filename="libgazebo_ros_diff_drive.so"><ros/></plugin></gazebo>
      <gazebo><plugin name="q" filename="libvisnav_quadrotor.so"/></gazebo>
    </robot>"""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(add_plugin_namespaces(urdf, "/"))
    got = {p.get("name"): p.findtext("robotNamespace") for p in root.iter("plugin")}
    assert got == {"c": "/", "l": "/", "k": "/mine", "n": None, "q": None}
    assert add_plugin_namespaces("<robot", "/") == "<robot"  # not XML: left to the simulator
