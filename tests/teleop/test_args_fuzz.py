"""Fuzz ``visnav teleop``'s argument handling: only visnav errors escape."""

from __future__ import annotations

import argparse

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.cli.teleop import add_arguments, teleop_overrides
from visnav.errors import VisnavError
from visnav.teleop.errors import TeleopError

_SETTINGS = settings(
    max_examples=150, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)  # fmt: skip

_TOKENS = st.one_of(
    st.sampled_from(["_speed:=0.3", "_turn:=", "cmd_vel:=/r/cmd_vel", ":=", "__ns:=/x",
                     "_stamped:=true", "_speed:=[1", "_x:={a: 1}", "speed", "_:=1",
                     "_speed:=!!python/object:os.system", "--turtlebot3", "--model",
                     "waffle", "--speed", "0.3", "--stamped", "--frame-id", "base"]),
    st.text(max_size=10),
)  # fmt: skip


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(exit_on_error=False)
    add_arguments(parser)
    return parser


@_SETTINGS
@given(st.lists(_TOKENS, max_size=6))
def test_teleop_arguments_only_visnav_errors(argv: list[str]) -> None:
    try:
        args = _parser().parse_args(argv)
    except (argparse.ArgumentError, SystemExit):
        return  # argparse's own usage errors (exit 2), before any visnav code
    try:
        params, remaps = teleop_overrides(args)
    except VisnavError:
        return
    assert all(isinstance(k, str) for k in params)
    assert all(k and not k.startswith("_") for k in remaps)


def test_ros_style_arguments(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("TURTLEBOT3_MODEL", raising=False)
    args = _parser().parse_args(["_speed:=0.3", "cmd_vel:=/r/cmd_vel", "--turn", "0.8"])
    assert teleop_overrides(args) == ({"speed": 0.3, "turn": 0.8}, {"cmd_vel": "/r/cmd_vel"})
    args = _parser().parse_args(["--tb3", "--topic", "/tb3/cmd_vel"])
    assert teleop_overrides(args) == ({"model": "burger"}, {"cmd_vel": "/tb3/cmd_vel"})
    monkeypatch.setenv("TURTLEBOT3_MODEL", "waffle_pi")
    assert teleop_overrides(_parser().parse_args(["--tb3"]))[0] == {"model": "waffle_pi"}
    with pytest.raises(TeleopError, match="--speed: teleop_twist_keyboard options"):
        teleop_overrides(_parser().parse_args(["--tb3", "--speed", "1"]))
    with pytest.raises(TeleopError, match="expected NAME:=VALUE"):
        teleop_overrides(_parser().parse_args(["speed=1"]))
