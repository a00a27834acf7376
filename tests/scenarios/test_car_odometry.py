"""The car scenario's odometry contract: wheel encoders required unless --ideal-sensors."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import pytest

from visnav.scenarios.car import wheel_odometry
from visnav.scenarios.runner import ScenarioError
from visnav.sim.robot import RobotDescription
from visnav.sim.simulator import resolve_robot


def _fake_sim(description: RobotDescription) -> SimpleNamespace:
    robot = SimpleNamespace(name="car", description=description)
    return SimpleNamespace(robot=lambda: robot)


def test_the_car_has_wheel_encoders_by_default() -> None:
    drive = wheel_odometry(_fake_sim(resolve_robot("car")), encoders=True)
    assert drive.odometry_source == "encoder"
    assert drive.odometry_topic == "/odom"


def test_ideal_sensors_need_no_encoders() -> None:
    ideal = resolve_robot("car", args={"ideal_sensors": "true"})
    assert wheel_odometry(_fake_sim(ideal), encoders=False).odometry_source == "world"
    with pytest.raises(ScenarioError, match=r"<odometry_source>0</odometry_source>") as info:
        wheel_odometry(_fake_sim(ideal), encoders=True)
    assert "--ideal-sensors" in str(info.value)
    assert "\n" not in str(info.value)


def test_a_robot_with_only_ground_truth_odometry_is_refused() -> None:
    desc = resolve_robot("car")
    only_p3d = dataclasses.replace(desc, gazebo=dataclasses.replace(desc.gazebo, diff_drives=()))
    assert only_p3d.gazebo.odometry  # the p3d ground truth is still there
    with pytest.raises(ScenarioError, match=r"no libgazebo_ros_diff_drive\.so plugin"):
        wheel_odometry(_fake_sim(only_p3d), encoders=True)
