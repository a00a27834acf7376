"""roslaunch XML import: a typical Gazebo tutorial launch file, ROS 1 semantics, bad input."""

from __future__ import annotations

import math
import textwrap
import threading
from pathlib import Path

import numpy as np
import pytest

from visnav.cli.main import main
from visnav.graph import Context, Node
from visnav.launch import (
    LaunchArgError,
    Launcher,
    LaunchParseError,
    NodeSpec,
    RoslaunchImportError,
    load_launch,
)
from visnav.node_registry import resolve_node_class
from visnav.tf import Buffer, transform_to_matrix
from visnav.tf.ros import TransformListener
from visnav.tf.static_tf import (
    StaticTransformError,
    static_transform_from_params,
    static_transform_params_from_args,
)

DATA = Path(__file__).parent / "data"
TUTORIAL = DATA / "my_robot" / "launch" / "gazebo.launch"


def write(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return path


def by_fqn(nodes: list[NodeSpec]) -> dict[str, NodeSpec]:
    return {n.fqn: n for n in nodes}


def test_gazebo_tutorial_launch_file_maps_onto_visnav() -> None:
    desc = load_launch(TUTORIAL, {"x": "1.5"})
    nodes = by_fqn(desc.nodes)
    assert {n: s.executable for n, s in nodes.items()} == {
        "/gazebo": "sim",
        "/camera_optical_tf": "static_transform_publisher",
        "/map_odom_tf": "static_transform_publisher",
        "/camera/image_proc": "image_proc",
        "/camera/depth_to_scan": "depthimage_to_laserscan",
    }
    # empty_world.launch: the simulator, and /use_sim_time for every node; spawn_model's
    # robot (robot_description from the xacro command, launch arg passed through) is folded
    # into the sim node, and the sim publishes the robot state itself
    sim = nodes["/gazebo"].params
    assert sim["world"] == "empty"
    assert "paused" not in sim  # the sim node has no paused start: a note when true
    assert all(n.use_sim_time is True for n in desc.nodes)
    assert any("gui:=true" in note for note in desc.notes)
    assert any("spawn_model /spawn_urdf" in note and "folded" in note for note in desc.notes)
    assert any("robot_state_publisher /robot_state_publisher" in note for note in desc.notes)
    urdf = sim["robot"]
    assert '<robot name="bot">' in urdf
    assert 'xyz="0.2 0 0.25"' in urdf
    assert sim["spawn"] == [1.5, 0.0, 0.05, 1.57]
    optical = nodes["/camera_optical_tf"].params
    assert (optical["yaw"], optical["pitch"], optical["roll"]) == (-1.5708, 0.0, -1.5708)
    assert (optical["frame_id"], optical["child_frame_id"]) == (
        "camera_link",
        "camera_optical_frame",
    )
    assert nodes["/map_odom_tf"].params["qw"] == 1.0  # tf's form: quaternion + period
    scan = nodes["/camera/depth_to_scan"]
    assert scan.params == {"output_frame": "camera_link", "range_max": 8.0, "scan_height": 3}
    assert scan.remaps == (
        ("depth", "depth/image_raw"),
        ("depth_camera_info", "depth/camera_info"),
        ("scan", "/scan"),
    )
    assert (scan.process, scan.respawn, scan.respawn_delay) == ("own", True, 2.0)
    assert nodes["/camera/image_proc"].process == "shared"
    assert scan.source == f"{TUTORIAL}:41"


def test_tutorial_args_rviz_and_not_built_nodes() -> None:
    desc = load_launch(TUTORIAL, {"rviz": "true", "camera_height": "0.5", "paused": "true"})
    nodes = by_fqn(desc.nodes)
    assert nodes["/rviz"].executable == "viz"
    assert nodes["/rviz"].params["fixed_frame"] == "odom"  # read from the .rviz config
    assert nodes["/rviz"].params["config"].endswith("config/view.rviz")
    assert 'xyz="0.2 0 0.5"' in nodes["/gazebo"].params["robot"]
    assert "paused" not in nodes["/gazebo"].params
    assert any("paused:=true is ignored" in note for note in desc.notes)
    assert resolve_node_class("viz").__name__ == "ViewerNode"


def test_mapped_nodes_resolve_the_ros1_topics() -> None:
    nodes = by_fqn(load_launch(TUTORIAL).nodes)
    with Context(transport="local") as ctx:
        spec = nodes["/camera/depth_to_scan"]
        node = resolve_node_class(spec.executable)(spec.name, context=ctx, **spec.node_kwargs())
        assert sorted(s.topic_name for s in node.subscriptions if s.topic_name != "/clock") == [
            "/camera/depth/camera_info",
            "/camera/depth/image_raw",
        ]
        topics = [p.topic_name for p in node.publishers if p.topic_name != "/parameter_events"]
        assert topics == ["/scan"]
        assert node.converter.output_frame_id == "camera_link"
        assert node.converter.range_max == 8.0


def test_static_transform_publisher_node_publishes_the_optical_frame() -> None:
    spec = by_fqn(load_launch(TUTORIAL).nodes)["/camera_optical_tf"]
    buffer = Buffer()
    with Context(transport="local") as ctx:
        TransformListener(buffer, Node("listener", context=ctx))
        resolve_node_class(spec.executable)(
            spec.name, context=ctx, **{**spec.node_kwargs(), "use_sim_time": False}
        )
        ctx.spin_some()
        t = buffer.lookup_transform("camera_link", "camera_optical_frame", 0)
    rot = transform_to_matrix(t.transform)[:3, :3]
    # REP 103: the optical z axis looks along the body x axis, optical x along body -y
    np.testing.assert_allclose(rot @ [0, 0, 1], [1, 0, 0], atol=1e-4)
    np.testing.assert_allclose(rot @ [1, 0, 0], [0, -1, 0], atol=1e-4)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            "1 2 3 0.1 0.2 0.3 a b",
            {"x": 1, "y": 2, "z": 3, "yaw": 0.1, "pitch": 0.2, "roll": 0.3},
        ),
        ("1 2 3 0.1 0.2 0.3 a b 100", {"x": 1, "yaw": 0.1, "roll": 0.3}),  # tf: period dropped
        ("0 0 0 0 0 0 1 a b", {"qx": 0, "qw": 1}),
        ("0 0 0 0 0 0 1 a b 50", {"qw": 1}),
        ("--x 1 --yaw 0.5 --frame-id a --child-frame-id b", {"x": 1, "yaw": 0.5}),
    ],
)
def test_static_transform_argument_forms(args: str, expected: dict[str, float]) -> None:
    params = static_transform_params_from_args(args.split())
    assert (params["frame_id"], params["child_frame_id"]) == ("a", "b")
    assert {k: params[k] for k in expected} == expected


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        ("1 2 3 a b", "got 5 arguments"),
        ("1 2 3 4 5 x a b", "got 8 arguments"),
        ("1 2 3 4 5 6 a b c", "period_ms is 'c'"),
        ("--x 1 --frame a", "cannot read '--frame'"),
        ("1 2 3 nan 0 0 a b", "finite"),
    ],
)
def test_static_transform_argument_errors(args: str, fragment: str) -> None:
    with pytest.raises(StaticTransformError, match=fragment):
        static_transform_params_from_args(args.split())


def test_static_transform_rotation() -> None:
    t = static_transform_from_params(
        {"yaw": math.pi / 2, "frame_id": "a", "child_frame_id": "b", "x": 1}
    )
    q = t.transform.rotation
    np.testing.assert_allclose([q.x, q.y, q.z, q.w], [0, 0, math.sqrt(0.5), math.sqrt(0.5)])
    with pytest.raises(StaticTransformError, match="give one rotation"):
        static_transform_from_params(
            {"yaw": 1.0, "qz": 1.0, "frame_id": "a", "child_frame_id": "b"}
        )
    with pytest.raises(StaticTransformError, match="two different, non-empty frame ids"):
        static_transform_from_params({"frame_id": "a", "child_frame_id": "a"})


def test_everything_unmappable_is_listed_in_one_error(tmp_path: Path) -> None:
    f = write(
        tmp_path / "robot.launch",
        """
        <launch>
          <env name="GAZEBO_MODEL_PATH" value="/models"/>
          <machine name="remote" address="10.0.0.2"/>
          <include file="$(find gazebo_ros)/launch/willowgarage_world.launch"/>
          <param name="robot_description" command="cat robot.urdf"/>
          <node pkg="joint_state_publisher" type="joint_state_publisher" name="jsp"/>
          <node pkg="image_proc" type="image_proc" name="ok"/>
          <node pkg="gazebo_ros" type="spawn_model" name="spawn" args="-model m -database m -bb"/>
          <rosparam command="delete" param="x"/>
        </launch>
        """,
    )
    with pytest.raises(RoslaunchImportError) as info:
        load_launch(f)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"{f}: cannot import 8 elements of this roslaunch file: ")
    for fragment in (
        f"{f}:2: <env> has no visnav counterpart",
        f"{f}:3: <machine> has no visnav counterpart",
        f"{f}:4: <include file='$(find gazebo_ros)/launch/willowgarage_world.launch'>",
        f"{f}:5: <param command='cat robot.urdf'>: visnav runs only xacro commands",
        f"{f}:9: <rosparam command='delete'>",
        f"{f}:6: joint_state_publisher /jsp needs a robot_description parameter",
        f"{f}:8: spawn_model /spawn: option '-bb' is not mapped (did you mean -b?)",
        f"{f}:8: spawn_model /spawn: -database: visnav has no Gazebo model database",
    ):
        assert fragment in text, fragment
    assert "visnav maps: <launch>, <arg>" in text
    assert "ROS 2 launch files (Python or XML) are out of scope" in text


def test_spawn_model_without_a_simulator_is_refused(tmp_path: Path) -> None:
    """visnav has no spawn_model node: one that cannot join a sim node is an import error."""
    (tmp_path / "r.urdf").write_text("<robot name='r'><link name='base'/></robot>")
    f = write(
        tmp_path / "spawn.launch",
        """
        <launch>
          <param name="robot_description" textfile="$(dirname)/r.urdf"/>
          <node pkg="gazebo_ros" type="spawn_model" name="spawn"
                args="-urdf -param robot_description -model r"/>
        </launch>
        """,
    )
    with pytest.raises(RoslaunchImportError) as info:
        load_launch(f)
    text = str(info.value)
    assert "\n" not in text
    assert "spawn_model (" in text
    assert "/spawn)" in text
    assert "found 0 gazebo / sim node(s) and 1 spawn_model node(s)" in text
    assert "Fix: " in text


def test_ros1_semantics_params_remaps_includes(tmp_path: Path) -> None:
    (tmp_path / "robot.urdf").write_text("<robot name='r'><link name='base'/></robot>")
    write(
        tmp_path / "camera.launch",
        """
        <launch>
          <arg name="cam"/>
          <group ns="$(arg cam)">
            <node pkg="image_proc" type="image_proc" name="proc"/>
          </group>
        </launch>
        """,
    )
    f = write(
        tmp_path / "main.launch",
        """
        <launch>
          <arg name="cams" default="front"/>
          <param name="use_sim_time" value="false"/>
          <param name="robot_description" textfile="$(dirname)/robot.urdf"/>
          <rosparam>
            answer: 42
            nested: {a: 1.5}
          </rosparam>
          <group ns="robot">
            <remap from="image_raw" to="camera/image_raw"/>
            <node pkg="robot_state_publisher" type="robot_state_publisher" name="rsp">
              <param name="tf_prefix" value="r1"/>
              <rosparam param="joints">[a, b]</rosparam>
            </node>
            <include file="$(dirname)/camera.launch" ns="sensors">
              <arg name="cam" value="$(arg cams)"/>
            </include>
          </group>
          <node pkg="image_proc" type="image_proc" name="outside"/>
          <node pkg="image_proc" type="image_proc" name="disabled" unless="true"/>
        </launch>
        """,
    )
    desc = load_launch(f)
    nodes = by_fqn(desc.nodes)
    assert list(nodes) == ["/robot/rsp", "/robot/sensors/front/proc", "/outside"]
    rsp = nodes["/robot/rsp"]
    assert rsp.params == {
        "frame_prefix": "r1/",
        "joints": ["a", "b"],
        "robot_description": "<robot name='r'><link name='base'/></robot>",
        "publish_frequency": 50.0,  # ROS 1's default
    }
    assert all(n.use_sim_time is False for n in desc.nodes)
    # a group's <remap> reaches the nodes and includes inside it, not the ones after it
    assert nodes["/robot/sensors/front/proc"].remaps == (("image_raw", "camera/image_raw"),)
    assert nodes["/outside"].remaps == ()
    assert any("/answer" in n and "/nested/a" in n for n in desc.notes)


@pytest.mark.parametrize(
    ("value", "kind", "expected"),
    [
        ("1", None, 1),
        ("1.5", None, 1.5),
        ("True", None, True),
        ("hello", None, "hello"),
        ("1", "str", "1"),
        ("2", "double", 2.0),
        ("true", "bool", True),
        ("[1, 2]", "yaml", [1, 2]),
    ],
)
def test_param_types_as_roslaunch_guesses_them(
    tmp_path: Path, value: str, kind: str | None, expected: object
) -> None:
    type_attr = f' type="{kind}"' if kind else ""
    f = write(
        tmp_path / "p.launch",
        f"""
        <launch>
          <node pkg="image_proc" type="image_proc" name="n">
            <param name="p" value="{value}"{type_attr}/>
          </node>
        </launch>
        """,
    )
    (spec,) = load_launch(f).nodes
    assert spec.params["p"] == expected
    assert type(spec.params["p"]) is type(expected)


@pytest.mark.parametrize(
    ("body", "args", "error", "fragment"),
    [
        ('<launch><arg name="a" value="1"/></launch>', {"a": "2"}, LaunchArgError, "fixed value="),
        (
            '<launch><arg name="robot"/></launch>',
            {"robt": "x"},
            LaunchArgError,
            "did you mean robot:=",
        ),
        (
            '<launch><arg name="a" default="1"/></launch>',
            {"b": "2"},
            LaunchArgError,
            "no <arg name='b'>",
        ),
        (
            '<launch><include file="$(find gazebo_ros)/launch/empty_world.launch">'
            '<arg name="pasued" value="true"/></include></launch>',
            {},
            LaunchArgError,
            "empty_world.launch declares no arg 'pasued'; did you mean 'paused'?",
        ),
        (
            '<launch><node pkg="a" exec="b" name="c"/></launch>',
            {},
            LaunchParseError,
            "ROS 2 launch XML",
        ),
        (
            '<launch><param name="x" value="$(eval __import__)"/></launch>',
            {},
            LaunchParseError,
            "'__' is not allowed",
        ),
        (
            "<launch>\n<node pkg='a'\n</launch>",
            {},
            LaunchParseError,
            ":3: the launch file does not parse as XML",
        ),
        ("<nodes/>", {}, LaunchParseError, "expected <launch>"),
        (
            '<launch><include file="$(find gazebo_ros)/launch/empty_world.launch">'
            '<arg name="world_name" value="worlds/willowgarage.world"/></include></launch>',
            {},
            RoslaunchImportError,
            "Gazebo's bundled worlds are not available",
        ),
    ],
)
def test_roslaunch_bad_input(
    tmp_path: Path, body: str, args: dict[str, str], error: type[Exception], fragment: str
) -> None:
    f = tmp_path / "bad.launch"
    f.write_text(body)
    with pytest.raises(error) as info:
        load_launch(f, args)
    assert fragment in str(info.value)
    assert str(f) in str(info.value)


def test_yaml_includes_roslaunch_and_cli_prints_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = write(
        tmp_path / "top.yaml",
        f"""
        launch:
          - group:
              namespace: sim
              children:
                - include: {{file: {TUTORIAL}, args: {{x: "2"}}}}
        """,
    )
    nodes = by_fqn(load_launch(f).nodes)
    assert "/sim/camera/depth_to_scan" in nodes
    assert nodes["/sim/gazebo"].params["spawn"][0] == 2.0
    assert main(["launch", "--print", str(TUTORIAL)]) == 0
    out = capsys.readouterr().out
    assert "/gazebo  [sim]  process=shared use_sim_time=true" in out
    assert "[spawn_model]" not in out
    assert "remap depth_camera_info -> depth/camera_info" in out


def test_an_imported_roslaunch_file_runs(domain: int, tmp_path: Path) -> None:
    f = write(
        tmp_path / "tf.launch",
        """
        <launch>
          <group ns="robot">
            <node pkg="tf2_ros" type="static_transform_publisher" name="base_to_cam"
                  args="0.2 0 0.3 0 0 0 base_link camera_link"/>
          </group>
          <node pkg="tf" type="static_transform_publisher" name="map_to_odom"
                args="1 2 0 0 0 0 1 map odom 100"/>
        </launch>
        """,
    )
    launcher = Launcher(load_launch(f), domain=domain)
    stop = threading.Event()
    thread = threading.Thread(target=launcher.run, args=(stop,), daemon=True)
    thread.start()
    try:
        buffer = Buffer()
        with Context(domain) as ctx:
            TransformListener(buffer, Node("probe", context=ctx))

            def both() -> bool:
                return buffer.can_transform("base_link", "camera_link", 0) and buffer.can_transform(
                    "map", "odom", 0
                )

            assert ctx.spin_until(both, 8.0)
            cam = buffer.lookup_transform("base_link", "camera_link", 0).transform.translation
            odom = buffer.lookup_transform("map", "odom", 0).transform.translation
        assert (cam.x, cam.y, cam.z) == (0.2, 0.0, 0.3)
        assert (odom.x, odom.y, odom.z) == (1.0, 2.0, 0.0)
        names = sorted(n.get_fully_qualified_name() for n in launcher.shared_nodes)
        assert names == ["/map_to_odom", "/robot/base_to_cam"]
    finally:
        stop.set()
        thread.join(10)
