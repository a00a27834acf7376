"""ROBOTIS' TurtleBot3 launch files (noetic) import and start as they are written.

``tests/data/turtlebot3`` holds the packages (SOURCE.md): ``roslaunch turtlebot3_gazebo
turtlebot3_world.launch`` with ``TURTLEBOT3_MODEL=burger`` or ``waffle_pi`` must give one
``sim`` node with the robot's Xacro expanded and the package directories its meshes need;
``turtlebot3_remote.launch`` (what the SLAM and navigation tutorials include) a
robot_state_publisher; ``turtlebot3_model.launch`` adds joint_state_publisher and rviz.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from visnav.cli.main import main
from visnav.graph import Context
from visnav.launch import Launcher, LaunchParseError, load_launch
from visnav.launch.errors import LaunchArgError
from visnav.launch.loader import find_package_launch_file
from visnav.launch.substitutions import ros_packages
from visnav.sim.sim_node import SimulatorNode, SimulatorNodeError

DATA = Path(__file__).resolve().parents[1] / "data"
TB3 = DATA / "turtlebot3"
GAZEBO = TB3 / "turtlebot3_gazebo"
DESCRIPTION = TB3 / "turtlebot3_description"
BRINGUP = TB3 / "turtlebot3_bringup"
# the launch files' $(find pkg) through ROS_PACKAGE_PATH, as a sourced workspace gives them
ENV = {"ROS_PACKAGE_PATH": str(TB3)}
# where each world launch file puts the robot (its x_pos / y_pos defaults)
WORLDS = {
    "turtlebot3_empty_world": ("empty.world", [0.0, 0.0, 0.0, 0.0]),
    "turtlebot3_world": ("turtlebot3_world.world", [-2.0, -0.5, 0.0, 0.0]),
    "turtlebot3_house": ("turtlebot3_house.world", [-3.0, 1.0, 0.0, 0.0]),
}


def _env(model: str) -> dict[str, str]:
    return {**ENV, "TURTLEBOT3_MODEL": model}


@pytest.mark.parametrize("model", ["burger", "waffle_pi"])
@pytest.mark.parametrize("launch", sorted(WORLDS))
def test_gazebo_world_launch_files_import(model: str, launch: str) -> None:
    desc = load_launch(GAZEBO / "launch" / f"{launch}.launch", env=_env(model))
    (sim,) = desc.nodes
    assert (sim.executable, sim.fqn, sim.use_sim_time) == ("sim", "/gazebo", True)
    world, spawn = WORLDS[launch]
    assert sim.params["world"] == str(GAZEBO / "worlds" / world)
    assert sim.params["spawn"] == spawn
    assert f'<robot name="turtlebot3_{model}">' in sim.params["robot"]
    # package:// meshes and model:// models: every package the import knows reaches the sim
    packages = dict(item.split("=", 1) for item in sim.params["packages"])
    assert packages["turtlebot3_description"] == str(DESCRIPTION)
    assert packages["turtlebot3_gazebo"] == str(GAZEBO)
    assert "paused" not in sim.params  # empty_world's paused:=false is Gazebo's default
    assert any("folded into the sim node /gazebo" in note for note in desc.notes)
    assert any("gui:=true" in note for note in desc.notes)


def test_model_arg_overrides_the_environment() -> None:
    desc = load_launch(
        GAZEBO / "launch" / "turtlebot3_world.launch",
        {"model": "burger", "x_pos": "1.5"},
        env={**ENV, "TURTLEBOT3_MODEL": "waffle_pi"},
    )
    assert '<robot name="turtlebot3_burger">' in desc.nodes[0].params["robot"]
    assert desc.nodes[0].params["spawn"][0] == 1.5


def test_missing_turtlebot3_model_says_what_to_set() -> None:
    with pytest.raises(LaunchArgError, match="TURTLEBOT3_MODEL is not set"):
        load_launch(GAZEBO / "launch" / "turtlebot3_world.launch", env=ENV)


def test_package_and_file_as_roslaunch_takes_them() -> None:
    assert {name for name, _ in ros_packages(TB3)} >= {
        "turtlebot3_description",
        "turtlebot3_gazebo",
        "turtlebot3_bringup",
    }
    found = find_package_launch_file("turtlebot3_gazebo", "turtlebot3_house.launch", env=ENV)
    assert found == GAZEBO / "launch" / "turtlebot3_house.launch"
    with pytest.raises(LaunchParseError, match=r"did you mean 'turtlebot3_house\.launch'"):
        find_package_launch_file("turtlebot3_gazebo", "turtlebot3_hose.launch", env=ENV)
    with pytest.raises(LaunchArgError, match="did you mean 'turtlebot3_gazebo'"):
        find_package_launch_file("turtlebot3_gazeb", "turtlebot3_house.launch", env=ENV)
    # an explicit --package wins, and a path inside the package works too
    found = find_package_launch_file(
        "turtlebot3_gazebo",
        "launch/turtlebot3_world.launch",
        packages={"turtlebot3_gazebo": GAZEBO},
    )
    assert found == GAZEBO / "launch" / "turtlebot3_world.launch"


def test_cli_takes_package_and_file(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("TURTLEBOT3_MODEL", "waffle_pi")
    monkeypatch.setenv("ROS_PACKAGE_PATH", "")
    monkeypatch.chdir(tmp_path)  # relative --package directories are made absolute
    rel = os.path.relpath(TB3, tmp_path)
    code = main(
        [
            "launch",
            "--print",
            "--json",
            "turtlebot3_gazebo",
            "turtlebot3_world.launch",
            "x_pos:=0.5",
            "--package",
            f"turtlebot3_description={rel}/turtlebot3_description",
            "--package",
            f"turtlebot3_gazebo={rel}/turtlebot3_gazebo",
        ]
    )
    assert code == 0
    out = capsys.readouterr().out
    assert '"turtlebot3_waffle_pi"' in out or "turtlebot3_waffle_pi" in out
    assert f"turtlebot3_description={DESCRIPTION}" in out
    assert "0.5" in out


def test_remote_launch_starts_robot_state_publisher() -> None:
    desc = load_launch(BRINGUP / "launch" / "turtlebot3_remote.launch", env=_env("burger"))
    (rsp,) = desc.nodes
    assert (rsp.executable, rsp.fqn) == ("robot_state_publisher", "/robot_state_publisher")
    # includes/description.launch.xml (a .launch.xml include) set it on the same server
    assert '<robot name="turtlebot3_burger">' in rsp.params["robot_description"]
    assert rsp.params["publish_frequency"] == 50.0
    assert "frame_prefix" not in rsp.params  # tf_prefix "" (multi_robot_name's default)
    multi = load_launch(
        BRINGUP / "launch" / "turtlebot3_remote.launch",
        {"multi_robot_name": "tb3_0"},
        env=_env("waffle_pi"),
    )
    assert multi.nodes[0].params["frame_prefix"] == "tb3_0/"


def test_model_launch_adds_joint_state_publisher_and_rviz() -> None:
    desc = load_launch(BRINGUP / "launch" / "turtlebot3_model.launch", env=_env("waffle_pi"))
    nodes = {n.fqn: n for n in desc.nodes}
    assert set(nodes) >= {"/robot_state_publisher", "/joint_state_publisher"}
    jsp = nodes["/joint_state_publisher"]
    assert jsp.executable == "joint_state_publisher"
    assert (jsp.params["rate"], jsp.params["use_gui"]) == (50.0, True)
    assert '<robot name="turtlebot3_waffle_pi">' in jsp.params["robot_description"]
    if "/rviz" in nodes:  # the viewer is installed
        assert nodes["/rviz"].executable == "viz"
    else:
        assert any("rviz /rviz is skipped" in note for note in desc.notes)


def _wait_for(predicate: Any, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.1)
    return False


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(300)
def test_empty_world_launch_runs_the_burger(domain: int) -> None:
    desc = load_launch(GAZEBO / "launch" / "turtlebot3_empty_world.launch", env=_env("burger"))
    launcher = Launcher(desc, domain=domain)
    stop = threading.Event()
    thread = threading.Thread(target=launcher.run, args=(stop,), daemon=True)
    thread.start()
    try:
        assert _wait_for(lambda: bool(launcher.shared_nodes) or not thread.is_alive(), 120)
        assert thread.is_alive(), f"the launch ended: {launcher.events}"
        sim_node = launcher.shared_nodes[0]
        sim = sim_node.sim
        assert sim.robot().description.urdf.name == "turtlebot3_burger"
        assert sim.model.nmesh > 0  # package://turtlebot3_description meshes were found
        start = sim.now_ns
        assert _wait_for(lambda: sim.now_ns - start > 1_000_000_000, 60)
    finally:
        stop.set()
        thread.join(30)


def test_sim_node_packages_parameter_is_checked() -> None:
    with (
        Context(transport="local") as ctx,
        pytest.raises(SimulatorNodeError, match="parameter packages: 'nodir' is not name=DIR"),
    ):
        SimulatorNode(context=ctx, parameter_overrides={"packages": ["nodir"], "world": "empty"})


def test_skip_missing_models_reaches_the_sim_node(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("TURTLEBOT3_MODEL", "burger")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(TB3))
    argv = ["launch", "turtlebot3_gazebo", "turtlebot3_house.launch", "--print", "--json"]
    assert main(argv) == 0
    assert '"skip_missing_models"' not in capsys.readouterr().out
    assert main([*argv, "--skip-missing-models"]) == 0
    out = capsys.readouterr().out
    assert '"skip_missing_models": true' in out
