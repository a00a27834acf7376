"""``$(...)`` substitutions: the forms, nesting, and one clear error for each mistake."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from visnav.launch.errors import LaunchArgError, LaunchParseError
from visnav.launch.substitutions import (
    SubstitutionContext,
    find_package,
    own_package,
    substitute,
    visnav_share,
)


@pytest.fixture
def ctx(tmp_path: Path) -> SubstitutionContext:
    return SubstitutionContext(
        args={"robot": "car", "which": "robot", "empty": ""},
        file=str(tmp_path / "x.launch.yaml"),
        line=7,
        packages={"my_pkg": str(tmp_path)},
        env={"HOME_X": "/home/x", "ROS_PACKAGE_PATH": ""},
    )


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("plain", "plain"),
        ("$(arg robot)", "car"),
        ("$(var robot)", "car"),
        ("/$(arg robot)/camera", "/car/camera"),
        ("$(arg robot)_$(arg robot)", "car_car"),
        ("$(arg $(arg which))", "car"),  # nested
        ("[$(arg empty)]", "[]"),
        ("$(env HOME_X)", "/home/x"),
        ("$(env NOT_SET_X fallback)", "fallback"),
        ("$(optenv NOT_SET_X)", ""),
        ("$(optenv NOT_SET_X a b)", "a b"),
        ("$(optenv HOME_X dflt)", "/home/x"),
        ("a ) b", "a ) b"),  # a lone ')' outside a substitution is text
        ("$(equals $(arg robot) car)", "true"),
        ("$(not-equals $(arg robot) car)", "false"),
        ("$(not-equals '$(arg empty)' '')", "false"),  # an empty arg, quoted
        ("$(equals '$(arg empty)' '')", "true"),
        ("$(not-equals '$(arg robot)' '')", "true"),
        ("$(equals 'a b' \"a b\")", "true"),
    ],
)
def test_substitution_table(ctx: SubstitutionContext, text: str, expected: str) -> None:
    assert substitute(text, ctx) == expected


def test_find_dirname_and_anon(ctx: SubstitutionContext, tmp_path: Path) -> None:
    share = substitute("$(find-pkg-share visnav)", ctx)
    assert Path(share) == visnav_share()
    assert (Path(share) / "description" / "robots" / "car.urdf.xacro").is_file()
    assert substitute("$(find my_pkg)/urdf", ctx) == f"{tmp_path.resolve()}/urdf"
    assert substitute("$(dirname)", ctx) == str(tmp_path.resolve())
    first = substitute("$(anon talker)", ctx)
    assert first.startswith(f"talker_{os.getpid()}_")
    assert substitute("$(anon talker)", ctx) == first  # one value per name per launch
    assert substitute("$(anon other)", ctx) != first


@pytest.mark.parametrize(
    ("text", "error", "fragment"),
    [
        ("$(arg robt)", LaunchArgError, "did you mean 'robot'?"),
        ("$(arg nope)", LaunchArgError, "arguments in scope: empty, robot, which"),
        ("$(argg robot)", LaunchParseError, "did you mean $(arg ...)?"),
        ("$(eval 1 +)", LaunchParseError, "$(eval 1 +): not a valid expression"),
        ("$(arg robot", LaunchParseError, "unclosed substitution"),
        ("$()", LaunchParseError, "empty substitution"),
        ("$(arg a b)", LaunchParseError, "expected 1 argument"),
        ("$(equals $(arg empty) x)", LaunchParseError, "expected 2 argument"),
        ("$(equals 'x y)", LaunchParseError, "close the quotes"),
        ("$(env NOT_SET_X)", LaunchArgError, "environment variable NOT_SET_X is not set"),
        ("$(find nopkg)", LaunchArgError, "--package nopkg=DIR"),
    ],
)
def test_substitution_errors_name_file_line_and_fix(
    ctx: SubstitutionContext, text: str, error: type[Exception], fragment: str
) -> None:
    with pytest.raises(error) as info:
        substitute(text, ctx)
    message = str(info.value)
    assert fragment in message
    assert message.startswith(f"{ctx.file}:7: ")


def test_packages_from_ros_package_path_and_package_xml(tmp_path: Path) -> None:
    pkg = tmp_path / "src" / "robot_pkg"
    (pkg / "launch").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>robot_pkg</name></package>")
    env = {"ROS_PACKAGE_PATH": str(tmp_path / "src")}
    assert find_package("robot_pkg", env=env) == str(pkg.resolve())
    assert own_package(pkg / "launch" / "a.launch") == ("robot_pkg", str(pkg))
    with pytest.raises(LaunchArgError, match="did you mean 'robot_pkg'"):
        find_package("robot_pk", packages={"robot_pkg": pkg}, env={})
    assert find_package("gazebo_ros", env={}, virtual=True) == "visnav://gazebo_ros"
