"""Grouped description warnings: counts, order by consequence, file:line through Xacro includes."""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import pytest

from visnav.description.errors import RobotDescriptionError, WorldWarning
from visnav.description.robot import expand_xacro, load_robot
from visnav.description.warning_summary import (
    Consequence,
    DescriptionWarning,
    consequence_of,
    log_warning_summary,
    summarize_warnings,
)
from visnav.description.xacro_locations import LOCATION_ATTRIBUTE

TB3 = Path(__file__).parents[1] / "data" / "turtlebot3" / "turtlebot3_description"

KP = [
    f"g.xacro:{line}: <kp>: gazebo reference '{link}': <kp> is not modelled and is ignored"
    for line, link in ((14, "wheel_left_link"), (25, "wheel_right_link"), (36, "caster"))
]
SENSOR = (
    "g.xacro:115: <sensor>: sensor 'sonar' of type 'sonar' is not supported "
    "(camera, depth, imu and ray are) and is ignored"
)
RATE = "g.xacro:163: <plugin>: sensor 'cam': plugin <updateRate> 30 differs from <update_rate> 10"
OPTION = "g.xacro:62: <plugin>: plugin 'drive': <publishWheelJointState> is not supported; use X"
PLUGIN = (
    "g.xacro:85: <plugin>: model plugin 'libfoo.so' (name 'foo') is not supported and is ignored"
)
NO_ROS = "g.xacro:54: <sensor>: sensor 'imu': no gazebo_ros IMU plugin: nothing is published"


def test_same_warning_on_several_elements_is_one_line_with_count_and_places() -> None:
    summary = summarize_warnings([*KP, RATE], subject="robot 'r'")
    assert summary.total == 4
    assert len(summary.groups) == 2
    kp = next(g for g in summary.groups if g.tag == "kp")
    assert kp.count == 3
    assert kp.locations == ("g.xacro:14", "g.xacro:25", "g.xacro:36")
    assert kp.text == (
        "gazebo reference 'wheel_left_link', 'wheel_right_link', 'caster': "
        "<kp> is not modelled and is ignored"
    )
    line = kp.format()
    assert line == f"  g.xacro:14, 25, 36: {kp.text} (3x)"


def test_many_names_are_cut_and_counted() -> None:
    many = [f"g.xacro:{k}: <mu1>: gazebo reference 'l{k}': <mu1> is not modelled" for k in range(9)]
    (group,) = summarize_warnings(many, subject="s").groups
    assert group.text == "gazebo reference 'l0', 'l1', 'l2' (+6): <mu1> is not modelled"
    assert group.format().startswith("  g.xacro:0, 1, 2, 3, 4, 5 (+3): ")


def test_lost_sensors_and_plugins_come_first_then_changed_then_details() -> None:
    summary = summarize_warnings([*KP, OPTION, RATE, SENSOR, PLUGIN, NO_ROS], subject="s")
    order = [(g.consequence, g.tag) for g in summary.groups]
    assert order == [
        (Consequence.LOST, "sensor"),  # first appearance within a class
        (Consequence.LOST, "plugin"),
        (Consequence.LOST, "sensor"),
        (Consequence.CHANGED, "plugin"),
        (Consequence.CHANGED, "plugin"),
        (Consequence.DETAIL, "kp"),
    ]
    assert [g.locations[0] for g in summary.lost] == ["g.xacro:115", "g.xacro:85", "g.xacro:54"]
    text = summary.format().splitlines()
    assert text[0] == ("s: 8 warnings (6 distinct); 3 lose a sensor, drive or plugin (marked !)")
    assert [line[:4] for line in text[1:]] == ["  ! "] * 3 + ["    "] * 3


@pytest.mark.parametrize(
    ("message", "expected"),
    [
        (SENSOR, Consequence.LOST),
        (PLUGIN, Consequence.LOST),
        (NO_ROS, Consequence.LOST),
        (OPTION, Consequence.CHANGED),  # names a child element: the plugin still runs
        (NO_ROS.replace("plugin: ", "plugin: like Gazebo, "), Consequence.CHANGED),
        (RATE, Consequence.CHANGED),
        ("f:3: <noise>: sensor 'cam': noise type 'x' is not supported", Consequence.CHANGED),
        ("f:3: <parameter>: <ros><parameter> is not supported and is ignored", Consequence.DETAIL),
        (KP[0], Consequence.DETAIL),
        ("w.world:9: <plugin>: not supported by visnav worlds; skipped", Consequence.LOST),
        (
            "f:3: <inertia>: link 'a': inertia (1, 0, 0, 1, 0, 5) is not physical",
            Consequence.CHANGED,
        ),
    ],
)
def test_consequence_from_tag_and_text(message: str, expected: Consequence) -> None:
    warning = DescriptionWarning.parse(message)
    assert consequence_of(warning.tag, warning.text) is expected


def test_a_long_text_is_cut_on_its_line() -> None:
    long = "f.xacro:3: <material>: material 'x' is not known (known: " + "Gazebo/Abc, " * 40 + ")"
    (group,) = summarize_warnings([long], subject="s").groups
    line = group.format()
    assert line.endswith(" ...")
    assert len(line) < 230
    assert group.text == DescriptionWarning.parse(long).text  # the group keeps it whole


def test_messages_without_tag_or_location_are_kept() -> None:
    assert DescriptionWarning.parse("a.urdf: arguments {} given; ignored") == DescriptionWarning(
        "a.urdf", None, "arguments {} given; ignored"
    )
    assert DescriptionWarning.parse("plain text") == DescriptionWarning("", None, "plain text")
    (group,) = summarize_warnings(["plain text"], subject="s").groups
    assert group.format() == "  plain text"


def test_nothing_is_logged_without_warnings(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.DEBUG):
        assert log_warning_summary([], subject="s") is None
    assert not caplog.records


# --------------------------------------------------------------------------- Xacro locations

TOP = """<?xml version="1.0"?>
<robot name="nested" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="parts/level1.xacro"/>
  <link name="base_link"/>
  <xacro:sonar_on parent="base_link"/>
</robot>
"""
LEVEL1 = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="deeper/level2.xacro"/>
  <gazebo reference="base_link">
    <mu1>0.5</mu1>
    <kp>1000</kp>
  </gazebo>
</robot>
"""
LEVEL2 = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="sonar_on" params="parent">
    <link name="sonar_link"/>
    <joint name="sonar_joint" type="fixed">
      <parent link="${parent}"/>
      <child link="sonar_link"/>
    </joint>
    <gazebo reference="sonar_link">
      <sensor type="sonar" name="front_sonar">
        <update_rate>5</update_rate>
      </sensor>
    </gazebo>
  </xacro:macro>
</robot>
"""


def _line(text: str, needle: str) -> int:
    return next(k for k, line in enumerate(text.splitlines(), 1) if needle in line)


@pytest.fixture
def nested(tmp_path: Path) -> Path:
    (tmp_path / "parts" / "deeper").mkdir(parents=True)
    (tmp_path / "parts" / "level1.xacro").write_text(LEVEL1)
    (tmp_path / "parts" / "deeper" / "level2.xacro").write_text(LEVEL2)
    top = tmp_path / "nested.urdf.xacro"
    top.write_text(TOP)
    return top


def test_warnings_point_at_the_file_and_line_through_two_includes_and_a_macro(
    nested: Path,
) -> None:
    robot = load_robot(nested)
    level1 = nested.parent / "parts" / "level1.xacro"
    level2 = nested.parent / "parts" / "deeper" / "level2.xacro"
    by_tag = {DescriptionWarning.parse(w).tag: DescriptionWarning.parse(w) for w in robot.warnings}
    sensor = by_tag["sensor"]
    assert "front_sonar" in sensor.text
    assert sensor.location.endswith(f"level2.xacro:{_line(LEVEL2, '<sensor')}")
    assert Path(sensor.location.rsplit(":", 1)[0]).resolve() == level2.resolve()
    kp = by_tag["kp"]
    assert Path(kp.location.rsplit(":", 1)[0]).resolve() == level1.resolve()
    assert kp.location.endswith(f":{_line(LEVEL1, '<kp>')}")
    # the published XML carries no location attributes; the parsed elements neither
    assert LOCATION_ATTRIBUTE not in robot.xml
    assert LOCATION_ATTRIBUTE not in expand_xacro(nested)
    assert all(LOCATION_ATTRIBUTE not in b.element.attrib for b in robot.urdf.gazebo)
    # the robot is what plain xacro makes of it
    assert set(robot.urdf.links) == {"base_link", "sonar_link"}


def test_errors_point_at_the_included_file_too(nested: Path) -> None:
    level2 = nested.parent / "parts" / "deeper" / "level2.xacro"
    level2.write_text(LEVEL2.replace('type="fixed"', 'type="hinge"'))
    with pytest.raises(RobotDescriptionError) as caught:
        load_robot(nested)
    assert f"level2.xacro:{_line(LEVEL2, '<joint')}: <joint>" in str(caught.value)


def test_xacro_text_without_a_file_is_located_in_the_string() -> None:
    call = '  <link name="base_link"/>\n  <xacro:sonar_on parent="base_link"/>\n</robot>'
    text = LEVEL2.replace("</robot>", call).replace("<robot ", '<robot name="s" ')
    robot = load_robot(text)
    (sensor,) = [w for w in robot.warnings if "<sensor>" in w]
    assert sensor.startswith(f"<string>:{_line(text, '<sensor')}: ")


# --------------------------------------------------------------------------- quiet


def test_loading_logs_one_block(nested: Path, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.DEBUG, logger="visnav"):
        robot = load_robot(nested)
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1
    lines = warnings[0].getMessage().splitlines()
    assert lines[0].startswith("robot 'nested' (")
    assert "nested.urdf.xacro): " in lines[0]
    assert f"{len(robot.warnings)} warnings" in lines[0]
    assert lines[1].startswith("  ! ")
    assert "front_sonar" in lines[1]
    assert all(line.startswith("    ") for line in lines[2:])
    # each warning is still there at debug level, for who asks
    debug = [r.getMessage() for r in caplog.records if r.levelno == logging.DEBUG]
    assert set(robot.warnings) <= set(debug)


def test_turtlebot3_is_one_short_block(caplog: pytest.LogCaptureFixture) -> None:
    source = TB3 / "urdf" / "turtlebot3_waffle_pi.urdf.xacro"
    with caplog.at_level(logging.WARNING, logger="visnav"):
        robot = load_robot(source, packages={"turtlebot3_description": TB3})
    (record,) = [r for r in caplog.records if r.name.startswith("visnav.description")]
    lines = record.getMessage().splitlines()
    assert len(lines) - 1 < len(robot.warnings)  # grouped
    marks = [line[2] for line in lines[1:]]
    assert marks == sorted(marks, key=lambda m: m != "!")  # what is lost comes first
    # every line points into the file where the element is written, not at line 1 of the top
    assert all("turtlebot3_waffle_pi.gazebo.xacro:" in line for line in lines[1:])
    assert all(".urdf.xacro:1:" not in w for w in robot.warnings)


WORLD = """<?xml version="1.0"?>
<sdf version="1.6">
  <world name="w">
    <physics type="ode"><real_time_factor>1</real_time_factor><ode/></physics>
    <plugin name="state" filename="libgazebo_ros_state.so"/>
    <model name="box"><static>true</static><link name="l">
      <collision name="c"><geometry><box><size>1 1 1</size></box></geometry></collision>
    </link></model>
  </world>
</sdf>
"""


def test_a_world_is_one_block_and_no_python_warnings(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    from visnav.description.world import load_world

    path = tmp_path / "w.world"
    path.write_text(WORLD)
    with warnings.catch_warnings(record=True) as caught, caplog.at_level(logging.WARNING):
        warnings.simplefilter("always")
        world = load_world(path)
    assert len(world.warnings) == 1  # the world plugin
    # Gazebo's own solver and loop settings change nothing visnav simulates: debug only
    assert not [w for w in world.warnings if "real_time_factor" in w or "<ode>" in w]
    assert not [w for w in caught if issubclass(w.category, WorldWarning)]
    (record,) = [r for r in caplog.records if r.name.startswith("visnav")]
    lines = record.getMessage().splitlines()
    assert lines[0].startswith("world 'w' (")
    assert lines[1].startswith("  ! w.world:5: <plugin>")  # a plugin of the world is lost
