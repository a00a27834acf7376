"""The YAML launch format: args, substitutions, includes, groups, nodes, and bad input."""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import pytest

from visnav.cli.main import main
from visnav.launch import (
    LaunchArgError,
    LaunchParseError,
    NodeSpec,
    load_launch,
    parse_launch_args,
)
from visnav.node_registry import UnknownNodeError


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return path


MAIN = """
launch:
  - arg: {name: robot, default: car, description: which robot}
  - arg: {name: rate, default: "10"}
  - arg: {name: with_scan, default: "true"}
  - let: {name: cam_ns, value: "$(arg robot)_cam"}
  - include:
      file: sensors.launch.yaml
      namespace: $(arg robot)
      args: {camera: $(var cam_ns), rate: $(arg rate)}
  - group:
      namespace: $(arg robot)
      use_sim_time: true
      remap: {/tf: tf}
      children:
        - node:
            exec: depthimage_to_laserscan
            name: scan
            if: $(arg with_scan)
            params: {range_max: 8.0, nested: {a: 1, b: [1, 2]}, rate: $(arg rate)}
            remap: {depth: $(var cam_ns)/depth, /tf: /tf_own}
        - node: {exec: image_proc, unless: $(arg with_scan)}
        - node:
            exec: static_transform_publisher
            args: "0 0 1 0 0 0 base_link $(var cam_ns)"
            use_sim_time: false
"""

SENSORS = """
launch:
  - arg: {name: camera}
  - arg: {name: rate, default: "5"}
  - group:
      namespace: $(arg camera)
      children:
        - node:
            exec: image_proc
            name: rectify
            process: own
            respawn_delay: 0.5
            params: {queue_size: $(arg rate)}
        - node: {exec: convert_metric, respawn: true, respawn_max_retries: 3}
"""


@pytest.fixture
def files(tmp_path: Path) -> Path:
    write(tmp_path / "sensors.launch.yaml", SENSORS)
    return write(tmp_path / "main.launch.yaml", MAIN)


def by_fqn(nodes: list[NodeSpec]) -> dict[str, NodeSpec]:
    return {n.fqn: n for n in nodes}


def test_args_includes_groups_and_nodes(files: Path) -> None:
    desc = load_launch(files)
    assert [a.name for a in desc.args.values()] == ["robot", "rate", "with_scan"]
    assert desc.args["robot"].description == "which robot"
    nodes = by_fqn(desc.nodes)
    assert list(nodes) == [
        "/car/car_cam/rectify",
        "/car/car_cam/convert_metric",
        "/car/scan",
        "/car/static_transform_publisher",
    ]
    rectify = nodes["/car/car_cam/rectify"]
    assert rectify.params == {"queue_size": 10}  # "$(arg rate)" typed back to an int
    assert (rectify.process, rectify.respawn, rectify.respawn_delay) == ("own", False, 0.5)
    metric = nodes["/car/car_cam/convert_metric"]
    assert (metric.process, metric.respawn, metric.respawn_max_retries) == ("own", True, 3)
    scan = nodes["/car/scan"]
    assert scan.params == {"range_max": 8.0, "nested.a": 1, "nested.b": [1, 2], "rate": 10}
    # the node's own rules first (rcl: first match wins), then the group's
    assert scan.remaps == (("depth", "car_cam/depth"), ("/tf", "/tf_own"), ("/tf", "tf"))
    assert (scan.use_sim_time, scan.process) == (True, "shared")
    assert scan.source == f"{files}:15"
    tf = nodes["/car/static_transform_publisher"]
    assert tf.use_sim_time is False
    assert tf.params["z"] == 1.0
    assert tf.params["child_frame_id"] == "car_cam"


def test_command_line_args_override_defaults_and_conditions(files: Path) -> None:
    desc = load_launch(files, parse_launch_args(["robot:=quad", "with_scan:=false"]))
    assert [n.fqn for n in desc.nodes] == [
        "/quad/quad_cam/rectify",
        "/quad/quad_cam/convert_metric",
        "/quad/image_proc",
        "/quad/static_transform_publisher",
    ]
    assert desc.args["robot"].value == "quad"
    assert desc.args["robot"].default == "car"


def test_included_file_sees_only_the_args_it_is_given(tmp_path: Path) -> None:
    write(tmp_path / "inner.yaml", "launch:\n  - node: {exec: image_proc, name: $(arg robot)}\n")
    top = write(
        tmp_path / "top.yaml",
        """
        launch:
          - arg: {name: robot, default: car}
          - include: {file: inner.yaml}
        """,
    )
    with pytest.raises(LaunchArgError, match=r"inner.yaml:2: \$\(arg robot\): no argument"):
        load_launch(top)
    write(
        tmp_path / "top2.yaml",
        """
        launch:
          - arg: {name: robot, default: car}
          - include: {file: inner.yaml, pass_all_args: true}
        """,
    )
    write(
        tmp_path / "inner.yaml",
        "launch:\n  - arg: {name: robot}\n  - node: {exec: image_proc, name: $(arg robot)}\n",
    )
    assert [n.fqn for n in load_launch(tmp_path / "top2.yaml").nodes] == ["/car"]


def test_include_with_an_arg_the_file_does_not_declare(tmp_path: Path, files: Path) -> None:
    bad = write(
        tmp_path / "bad.yaml",
        "launch:\n  - include: {file: sensors.launch.yaml, args: {camera: c, rat: '3'}}\n",
    )
    with pytest.raises(LaunchArgError) as info:
        load_launch(bad)
    text = str(info.value)
    assert "sensors.launch.yaml: argument rat:='3' was given" in text
    assert "did you mean 'rate'?" in text


def test_missing_arg_suggests_the_closest_given(files: Path) -> None:
    sensors = files.parent / "sensors.launch.yaml"
    with pytest.raises(LaunchArgError) as info:
        load_launch(sensors, {"camra": "front"})
    text = str(info.value)
    assert text.startswith(f"{sensors}:2: missing arg 'camera'")
    assert "give it as camera:=VALUE; you gave camra:=..., did you mean camera:=...?" in text


def test_unknown_cli_arg_suggests_the_closest_declared(files: Path) -> None:
    with pytest.raises(LaunchArgError, match="did you mean 'robot'"):
        load_launch(files, {"robt": "x"})


def test_arg_choices(tmp_path: Path) -> None:
    f = write(tmp_path / "c.yaml", "launch:\n  - arg: {name: mode, default: a, choices: [a, b]}\n")
    assert load_launch(f, {"mode": "b"}).args["mode"].value == "b"
    with pytest.raises(LaunchArgError, match="expected one of a, b"):
        load_launch(f, {"mode": "c"})


def test_unknown_node_suggests_the_closest_with_file_and_line(tmp_path: Path) -> None:
    f = write(
        tmp_path / "u.yaml",
        "launch:\n  - arg: {name: a, default: b}\n  - node: {exec: imgae_proc}\n",
    )
    with pytest.raises(UnknownNodeError) as info:
        load_launch(f)
    text = str(info.value)
    assert text.startswith(f"{f}:3: unknown node 'imgae_proc'")
    assert text.endswith("did you mean image_proc?")


@pytest.mark.parametrize(
    ("body", "line", "fragment"),
    [
        ("launch:\n  - node: {exec: image_proc\n  - arg: x\n", 3, "does not parse as YAML"),
        ("launch:\n  - node:\n      exec: image_proc\n     name: x\n", 4, "does not parse as YAML"),
        ("nodes: []\n", 1, "a mapping with a 'launch:' list"),
        ("launch:\n  - nod: {exec: image_proc}\n", 2, "unknown entry 'nod'; did you mean 'node'?"),
        ("launch:\n  - node: {exec: image_proc, parms: {}}\n", 2, "did you mean 'params'?"),
        ("launch:\n  - node: {pkg: image_proc}\n", 2, "name the node with 'exec:"),
        ("launch:\n  - node: {name: x}\n", 2, "'node' needs 'exec'"),
        (
            "launch:\n  - node: {exec: image_proc, process: thread}\n",
            2,
            "expected 'shared' or 'own'",
        ),
        ("launch:\n  - node: {exec: image_proc, respawn: maybe}\n", 2, "expected true or false"),
        ("launch:\n  - node:\n      exec: image_proc\n      exec: x\n", 4, "'exec' appears twice"),
        ("launch:\n  - node: {exec: image_proc, params: {a: [{b: 1}]}}\n", 2, "parameter 'a'"),
        ("launch:\n  - node: {exec: image_proc, params: {a: [1, x]}}\n", 2, "mixes types"),
        ("launch:\n  - node: {exec: image_proc, args: '1 2'}\n", 2, "takes no 'args'"),
        ("launch:\n  - node: {exec: image_proc, name: a/b}\n", 2, "node name"),
        ("launch:\n  - group: {namespace: 'a b', children: []}\n", 2, "namespace 'a b'"),
        (
            "launch:\n  - node: {exec: static_transform_publisher, args: '1 2 3'}\n",
            2,
            "3 arguments",
        ),
    ],
)
def test_bad_files_give_one_error_with_file_and_line(
    tmp_path: Path, body: str, line: int, fragment: str
) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(body)
    with pytest.raises(LaunchParseError) as info:
        load_launch(f)
    text = str(info.value)
    assert text.startswith(f"{f}:{line}: "), text
    assert fragment in text


def test_duplicate_names_and_respawn_of_shared_nodes(tmp_path: Path) -> None:
    dup = write(
        tmp_path / "d.yaml",
        """
        launch:
          - node: {exec: image_proc}
          - group: {namespace: /, children: [{node: {exec: image_proc}}]}
        """,
    )
    with pytest.raises(LaunchParseError, match=r"d.yaml:3: two nodes are named /image_proc"):
        load_launch(dup)
    shared = write(
        tmp_path / "s.yaml",
        "launch:\n  - node: {exec: image_proc, process: shared, respawn: true}\n",
    )
    with pytest.raises(LaunchParseError, match="respawn needs its own process"):
        load_launch(shared)


def test_include_cycle(tmp_path: Path) -> None:
    write(tmp_path / "a.yaml", "launch:\n  - include: {file: b.yaml}\n")
    write(tmp_path / "b.yaml", "launch:\n  - include: {file: a.yaml}\n")
    with pytest.raises(LaunchParseError, match="includes itself"):
        load_launch(tmp_path / "a.yaml")


def test_ros2_parameter_files(tmp_path: Path) -> None:
    write(
        tmp_path / "params.yaml",
        """
        /**:
          ros__parameters: {use_x: true, shared: 1}
        scan:
          ros__parameters: {range_max: 5.0, filter: {a: 2}}
        /robot/scan:
          ros__parameters: {shared: 2}
        other:
          ros__parameters: {nope: 1}
        """,
    )
    f = write(
        tmp_path / "p.yaml",
        """
        launch:
          - node:
              exec: depthimage_to_laserscan
              name: scan
              namespace: robot
              params: [$(dirname)/params.yaml, {range_max: 6.0}]
        """,
    )
    (node,) = load_launch(f).nodes
    assert node.params == {"use_x": True, "shared": 2, "range_max": 6.0, "filter.a": 2}


def test_builtin_executables_get_their_ros_names(tmp_path: Path) -> None:
    f = write(
        tmp_path / "n.yaml",
        """
        launch:
          - node: {exec: point_cloud_xyz}
          - node: {exec: launch_test_nodes:Talker}
          - node: {exec: my.mod:DepthFilterNode}
        """,
    )
    names = [n.fqn for n in load_launch(f).nodes]
    assert names == ["/point_cloud_xyz", "/talker", "/depth_filter"]


def test_json_round_trip(files: Path) -> None:
    for spec in load_launch(files).nodes:
        assert NodeSpec.from_json(spec.to_json()) == spec


def test_cli_print_and_one_line_errors(
    files: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["launch", "--print", str(files), "robot:=quad"]) == 0
    out = capsys.readouterr().out
    assert "/quad/scan  [depthimage_to_laserscan]  process=shared use_sim_time=true" in out
    assert "remap depth -> quad_cam/depth" in out
    assert main(["launch", str(files), "robot:=quad", "--print", "--json"]) == 0  # options last
    assert '"executable": "image_proc"' in capsys.readouterr().out
    bad = write(tmp_path / "bad.yaml", "launch:\n  - node: {exec: imgae_proc}\n")
    assert main(["launch", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith(f"error: {bad}:2: unknown node 'imgae_proc'")
    assert main(["launch", str(files), "robot"]) == 1
    assert "expected name:=value" in capsys.readouterr().err
    assert main(["launch", str(tmp_path / "nope.yaml")]) == 1
    assert "does not exist" in capsys.readouterr().err
    py = write(tmp_path / "x.launch.py", "")
    assert main(["launch", str(py)]) == 1
    assert "ROS 2 Python launch files are out of scope" in capsys.readouterr().err


def test_the_example_in_docs_loads(tmp_path: Path) -> None:
    docs = Path(__file__).resolve().parents[2] / "docs" / "launch.md"
    robot, camera = re.findall(r"```yaml\n(.*?)```", docs.read_text(), re.S)[:2]
    (tmp_path / "robot.launch.yaml").write_text(robot)
    (tmp_path / "camera.launch.yaml").write_text(camera)
    desc = load_launch(tmp_path / "robot.launch.yaml", {"robot": "quad"})
    nodes = by_fqn(desc.nodes)
    assert list(nodes) == [
        "/front/image_proc",
        "/front/point_cloud_xyz",
        "/quad/depth_to_scan",
        "/quad/filter",
        "/quad/static_transform_publisher",
    ]
    assert nodes["/front/image_proc"].params == {"queue_size": 30}
    assert nodes["/quad/filter"].process == "own"
    assert nodes["/quad/depth_to_scan"].remaps[0] == ("depth", "/front/depth/image_raw")
