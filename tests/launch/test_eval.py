"""``$(eval ...)``: roslaunch's expression language, evaluated by walking a whitelist."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.launch.errors import LaunchArgError, LaunchError, LaunchParseError
from visnav.launch.expression import LaunchEvalError, auto_value
from visnav.launch.loader import load_launch
from visnav.launch.substitutions import SubstitutionContext, substitute


@pytest.fixture
def ctx(tmp_path: Path) -> SubstitutionContext:
    return SubstitutionContext(
        args={"model": "burger", "n": "3", "half": "0.5", "gui": "true", "empty": ""},
        file=str(tmp_path / "x.launch"),
        line=4,
        packages={"my_pkg": str(tmp_path)},
        env={"TB3": "waffle_pi", "ROS_PACKAGE_PATH": ""},
    )


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("$(eval arg('model') == 'burger')", "True"),
        ("$(eval model == 'waffle')", "False"),  # a bare name is the arg (roslaunch)
        ("$(eval arg('n') * 2)", "6"),
        ("$(eval n + half)", "3.5"),
        ("$(eval 'turtlebot3_' + arg('model'))", "turtlebot3_burger"),
        ("$(eval arg('model').upper() + '_' + str(n))", "BURGER_3"),
        ("$(eval gui and n > 2)", "True"),
        ("$(eval not gui or false)", "False"),
        ("$(eval 'a' if arg('model') == 'burger' else 'b')", "a"),
        ("$(eval arg('model')[0:3])", "bur"),
        ("$(eval arg('model') in ['burger', 'waffle'])", "True"),
        ("$(eval 1 < n <= 3)", "True"),
        ("$(eval 7 // 2 + 7 % 2 + 2 ** 3)", "12"),
        ("$(eval -n)", "-3"),
        ("$(eval int('4') + float('0.25'))", "4.25"),
        ("$(eval round_to if False else 1)", "1"),  # the untaken branch is not evaluated
        ("$(eval radians(180) == pi)", "True"),
        ("$(eval env('TB3'))", "waffle_pi"),
        ("$(eval optenv('UNSET_X', 'dflt'))", "dflt"),
        ("$(eval optenv('UNSET_X'))", ""),
        ("$(eval len_ok if False else 'x,y'.split(','))", "['x', 'y']"),
        ("$(eval '$(arg model)' == 'burger')", "True"),  # inner $(...) first (ROS 2's rule)
        ("$(eval arg('model') + ')')", "burger)"),  # a quoted ')' does not close it
        ("x=$(eval n * 2) y=$(arg model)", "x=6 y=burger"),
        ("$(eval arg('empty') == '')", "True"),
        ("$(eval True)", "True"),
    ],
)
def test_expressions(ctx: SubstitutionContext, text: str, expected: str) -> None:
    assert substitute(text, ctx) == expected


def test_find_anon_dirname(ctx: SubstitutionContext, tmp_path: Path) -> None:
    assert substitute("$(eval find('my_pkg') + '/urdf')", ctx) == f"{tmp_path}/urdf"
    assert substitute("$(eval dirname())", ctx) == str(tmp_path)
    first = substitute("$(eval anon('rviz'))", ctx)
    assert first.startswith("rviz_")
    assert substitute("$(anon rviz)", ctx) == first  # one name per launch


def test_auto_value_is_roslaunchs() -> None:
    assert auto_value("2") == 2
    assert auto_value("2.5") == 2.5
    assert auto_value("TRUE") is True
    assert auto_value("1e3") == "1e3"  # no '.': int() fails, so it stays text in roslaunch
    assert auto_value("burger") == "burger"


@pytest.mark.parametrize(
    ("text", "error", "needle"),
    [
        ("$(eval ().__class__)", LaunchEvalError, "'__' is not allowed"),
        ("$(eval (1).real)", LaunchEvalError, "attribute access is not supported"),
        ("$(eval lambda: 1)", LaunchEvalError, "a lambda is not supported"),
        ("$(eval [x for x in 'ab'])", LaunchEvalError, "a list comprehension is not supported"),
        ("$(eval open('/etc/passwd'))", LaunchEvalError, "the function open() is not supported"),
        ("$(eval str(1, base=2))", LaunchEvalError, "keyword arguments is not supported"),
        ("$(eval 'a'.format(1))", LaunchEvalError, "string method .format() is not supported"),
        ("$(eval '%s' % 1)", LaunchEvalError, "string formatting"),
        ("$(eval {1: 2})", LaunchEvalError, "a dict literal"),
        ("$(eval f'{n}')", LaunchEvalError, "an f-string"),
        ("$(eval 1 is 1)", LaunchEvalError, "the comparison Is"),
        ("$(eval 1/0)", LaunchEvalError, "ZeroDivisionError"),
        ("$(eval 'a' + 1)", LaunchEvalError, "TypeError"),
        ("$(eval 10 ** 10000)", LaunchEvalError, "too large"),
        ("$(eval 'ab' * 10 ** 6)", LaunchEvalError, "too large"),
        ("$(eval [[1] * 1000] * 1000)", LaunchEvalError, "too large"),
        ("$(eval 1 +)", LaunchEvalError, "not a valid expression"),
        ("$(eval)", LaunchEvalError, "not a valid expression"),
        ("$(eval sqrt)", LaunchEvalError, "sqrt is a function"),
        ("$(eval arg('n', 'm'))", LaunchEvalError, "arg() takes 1 argument"),
        ("$(eval arg(3))", LaunchEvalError, "arg() takes text"),
        ("$(eval (-8) ** 0.5)", LaunchEvalError, "complex"),
        ("$(eval nosuch)", LaunchArgError, "no argument 'nosuch'"),
        ("$(eval env('UNSET_X'))", LaunchArgError, "UNSET_X is not set"),
        ("$(eval (1 + 2)", LaunchParseError, "unclosed $(eval"),
    ],
)
def test_errors_name_the_expression(
    ctx: SubstitutionContext, text: str, error: type[Exception], needle: str
) -> None:
    with pytest.raises(error) as info:
        substitute(text, ctx)
    assert needle in str(info.value)
    assert str(info.value).startswith(f"{ctx.file}:4: ")


def test_eval_in_a_roslaunch_file(tmp_path: Path) -> None:
    launch = tmp_path / "x.launch"
    launch.write_text(
        """<launch>
  <arg name="model" default="burger"/>
  <arg name="n" default="2"/>
  <arg name="is_burger" value="$(eval arg('model') == 'burger')"/>
  <node pkg="tf2_ros" type="static_transform_publisher" name="tf_a"
        args="$(eval str(n * 0.5)) 0 0 0 0 0 a b" if="$(arg is_burger)"/>
  <node pkg="tf2_ros" type="static_transform_publisher" name="tf_b"
        args="0 0 0 0 0 0 a c" unless="$(eval model == 'burger')"/>
</launch>
"""
    )
    nodes = {n.name: n for n in load_launch(launch).nodes}
    assert set(nodes) == {"tf_a"}
    assert nodes["tf_a"].params["x"] == 1.0
    waffle = {n.name for n in load_launch(launch, {"model": "waffle"}).nodes}
    assert waffle == {"tf_b"}


_ATOMS = st.sampled_from(
    [
        "1",
        "0",
        "-2",
        "2.5",
        "'a'",
        "''",
        "n",
        "model",
        "half",
        "gui",
        "True",
        "None",
        "arg('model')",
        "arg('nope')",
        "pi",
        "[1, 'a']",
        "()",
        "sqrt(2)",
        "x",
        "__import__",
        "(1).real",
        "open",
        "env('TB3')",
        "'a'.upper()",
        "'ab'[1:]",
        "10 ** 400",
        "lambda: 1",
        "{1: 2}",
    ]
)
_OPS = st.sampled_from(
    [
        " + ",
        " - ",
        " * ",
        " / ",
        " // ",
        " % ",
        " ** ",
        " == ",
        " < ",
        " in ",
        " and ",
        " or ",
        " if ",
        " else ",
        ".",
        "(",
        ")",
        "[",
        "]",
        ",",
        " not ",
        "'",
        ":",
    ]
)


@st.composite
def _expressions(draw: st.DrawFn) -> str:
    parts = [draw(_ATOMS)]
    for _ in range(draw(st.integers(0, 8))):
        parts.append(draw(_OPS))
        parts.append(draw(_ATOMS))
    return "".join(parts)


@settings(max_examples=400, deadline=None)
@given(expression=st.one_of(_expressions(), st.text(max_size=40)))
def test_fuzz_never_escapes_visnav_errors(expression: str) -> None:
    ctx = SubstitutionContext(
        args={"model": "burger", "n": "3", "half": "0.5", "gui": "true"},
        file="/tmp/fuzz.launch",
        env={"TB3": "waffle_pi", "ROS_PACKAGE_PATH": ""},
    )
    try:
        result = substitute(f"$(eval {expression})", ctx)
    except LaunchError:
        return
    assert isinstance(result, str)
    assert len(result) <= 1_000_000


def test_eval_in_a_yaml_launch_file_is_typed_afterwards(tmp_path: Path) -> None:
    launch = tmp_path / "x.launch.yaml"
    launch.write_text(
        """launch:
  - arg: {name: n, default: "3"}
  - node:
      exec: static_transform_publisher
      name: tf
      if: $(eval n > 2)
      params: {x: "$(eval n * 0.5)", frame_id: a, child_frame_id: "$(eval 'b_' + str(n))"}
"""
    )
    (node,) = load_launch(launch).nodes
    assert node.params["x"] == 1.5  # a float, as a substitution's YAML type
    assert node.params["child_frame_id"] == "b_3"
    assert load_launch(launch, {"n": "1"}).nodes == []
