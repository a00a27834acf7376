"""Guards of a simulation: spawn poses, instability, MuJoCo's log, Xacro args and cycles."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import mujoco
import pytest

from visnav.description.robot import expand_xacro, load_robot
from visnav.description.urdf import RobotDescriptionError
from visnav.description.world_yaml import world_from_dict
from visnav.graph import Context, Node
from visnav.msgs.types import Clock
from visnav.sim.guards import (
    InstabilityMonitor,
    SecondSimulationError,
    SimulationUnstableError,
    SpawnPoseError,
    check_spawn_pose,
    refuse_second_simulation,
    route_mujoco_warnings,
    world_bounds,
)
from visnav.sim.simulator import RobotSpawn, Simulator

BOX_ROBOT = """<robot name="box">
  <link name="base_link">
    <inertial><mass value="2"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>
    <collision><geometry><box size="0.3 0.3 0.2"/></geometry></collision>
  </link>
</robot>"""

WORLD = {"name": "flat", "ground": {"size": [20, 10]}, "metadata": {"spawn": [0.0, 0.0, 0.0]}}

XACRO_NS = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'


def test_world_bounds_follow_the_ground_or_the_obstacles() -> None:
    assert world_bounds(world_from_dict(WORLD)) == (-10.0, -5.0, 10.0, 5.0)
    no_ground = world_from_dict(
        {
            "name": "w",
            "ground": None,
            "objects": [{"type": "box", "pos": [5, 0, 0.5], "size": [1, 1, 1]}],
        }
    )
    x0, y0, x1, y1 = world_bounds(no_ground)
    assert (x0, x1) == pytest.approx((4.5 - 10.0, 5.5 + 10.0))
    assert (y0, y1) == pytest.approx((-10.5, 10.5))


@pytest.mark.parametrize(
    ("pose", "words"),
    [
        ((1e300, 0, 0, 0), ["1e+300", "outside world 'flat'", "x from -10 to 10"]),
        ((0, 6, 0, 0), ["outside", "y from -5 to 5"]),
        ((0, 0, -5, 0), ["outside", "z from -1"]),
        ((0, 0, 0, math.nan), ["not finite"]),
        ((0, 0, math.inf, 0), ["not finite"]),
        ((0, 0, 0), ["expected x y z yaw"]),
    ],
)
def test_bad_spawn_poses_are_refused(pose: tuple[float, ...], words: list[str]) -> None:
    with pytest.raises(SpawnPoseError) as info:
        check_spawn_pose(pose, world_from_dict(WORLD), robot="car")
    text = str(info.value)
    assert "robot 'car'" in text
    for word in words:
        assert word in text
    assert "fix" in text or "expected" in text


def test_a_good_spawn_pose_passes() -> None:
    assert check_spawn_pose((1, -2, 0.5, 3), world_from_dict(WORLD)) == (1.0, -2.0, 0.5, 3.0)


def test_simulator_refuses_a_spawn_outside_the_world(domain: int) -> None:
    with Context(domain) as ctx, pytest.raises(SpawnPoseError, match="outside world"):
        Simulator(
            world_from_dict(WORLD),
            [RobotSpawn(source=BOX_ROBOT, spawn=(0, 1e300, 0, 0))],
            context=ctx,
        )


def test_instability_stops_the_run_and_mujoco_writes_no_log_file(
    domain: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.chdir(tmp_path)
    with Context(domain) as ctx, Simulator(world_from_dict(WORLD), [BOX_ROBOT], context=ctx) as sim:
        sim.step(5)  # a sound state steps without complaint
        sim.data.qvel[:] = 1e300
        with (
            caplog.at_level(logging.WARNING, logger="visnav.sim.mujoco"),
            pytest.raises(SimulationUnstableError) as info,
        ):
            sim.step(3)
    text = str(info.value)
    assert "unstable" in text
    assert "sim time 0.0" in text
    assert "fix:" in text
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    assert any("MuJoCo:" in r.getMessage() for r in caplog.records)


def test_instability_monitor_on_a_raw_model(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    route_mujoco_warnings()
    body = '<body pos="1e300 0 0"><freejoint/><geom size=".1"/></body>'
    xml = f"<mujoco><worldbody>{body}</worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    monitor = InstabilityMonitor(data)
    mujoco.mj_step(model, data)
    with pytest.raises(SimulationUnstableError, match=r"position \(QPOS\) of degree of freedom 0"):
        monitor.check(2_000_000)
    monitor.check(4_000_000)  # reported once, not again for the same event
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_a_second_simulation_in_the_domain_is_refused(domain: int) -> None:
    with Context(domain) as ctx:
        refuse_second_simulation(ctx)  # nobody publishes /clock yet
        other = Node("sim", context=ctx)
        other.create_publisher(Clock, "/clock", 1)
        with pytest.raises(SecondSimulationError) as info:
            refuse_second_simulation(ctx, command="visnav sim")
    text = str(info.value)
    assert f"graph domain {domain}" in text
    assert "node /sim" in text
    assert "VISNAV_DOMAIN=<number> visnav sim" in text


def _xacro(path: Path, body: str) -> Path:
    path.write_text(f'<?xml version="1.0"?>\n<robot name="r" {XACRO_NS}>\n{body}\n</robot>\n')
    return path


def test_xacro_include_cycle_is_named(tmp_path: Path) -> None:
    a = _xacro(tmp_path / "a.xacro", '<xacro:include filename="b.xacro"/><link name="base_link"/>')
    _xacro(tmp_path / "b.xacro", '<xacro:include filename="c.xacro"/>')
    _xacro(tmp_path / "c.xacro", '<xacro:include filename="b.xacro"/>')
    with pytest.raises(RobotDescriptionError) as info:
        load_robot(a)
    text = str(info.value)
    assert "include cycle: b.xacro -> c.xacro -> b.xacro" in text
    assert len(text) < 300


def test_unknown_xacro_argument_is_refused_and_known_ones_listed(tmp_path: Path) -> None:
    body = (
        '<xacro:arg name="rate" default="10"/><xacro:property name="r" value="$(arg rate)"/>'
        '<link name="base_link"><inertial><mass value="${r}"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'
    )
    file = _xacro(tmp_path / "r.urdf.xacro", body)
    assert load_robot(file, args={"rate": "3"}).urdf.links["base_link"] is not None
    with pytest.raises(RobotDescriptionError) as info:
        load_robot(file, args={"nope": "1", "rate": "3"})
    text = str(info.value)
    assert "unknown Xacro argument nope (given as nope:=1)" in text
    assert "declares: rate" in text
    # the xacro tool (and roslaunch's xacro commands) ignore unknown args: so does expand_xacro
    assert "base_link" in expand_xacro(file, args={"nope": "1"})
