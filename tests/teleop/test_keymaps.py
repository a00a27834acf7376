"""Key sequences give teleop_twist_keyboard's and turtlebot3_teleop_key's commands."""

from __future__ import annotations

import pytest

from visnav.teleop.keymaps import (
    CTRL_C,
    TB3_LIMITS,
    Turtlebot3Keyboard,
    TwistKeyboard,
    Velocity,
)


def _twists(kb: TwistKeyboard, keys: str) -> list[Velocity]:
    out = []
    for key in keys:
        result = kb.press(key)
        if result.publish:
            out.append(kb.velocity)
    return out


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        ("i", Velocity(0.5, 0.0, 0.0, 0.0)),
        ("u", Velocity(0.5, 0.0, 0.0, 1.0)),
        ("o", Velocity(0.5, 0.0, 0.0, -1.0)),
        ("j", Velocity(0.0, 0.0, 0.0, 1.0)),
        ("l", Velocity(0.0, 0.0, 0.0, -1.0)),
        ("m", Velocity(-0.5, 0.0, 0.0, -1.0)),
        (",", Velocity(-0.5, 0.0, 0.0, 0.0)),
        (".", Velocity(-0.5, 0.0, 0.0, 1.0)),
        ("U", Velocity(0.5, 0.5, 0.0, 0.0)),
        ("I", Velocity(0.5, 0.0, 0.0, 0.0)),
        ("O", Velocity(0.5, -0.5, 0.0, 0.0)),
        ("J", Velocity(0.0, 0.5, 0.0, 0.0)),
        ("L", Velocity(0.0, -0.5, 0.0, 0.0)),
        ("M", Velocity(-0.5, 0.5, 0.0, 0.0)),
        ("<", Velocity(-0.5, 0.0, 0.0, 0.0)),
        (">", Velocity(-0.5, -0.5, 0.0, 0.0)),
        ("t", Velocity(0.0, 0.0, 0.5, 0.0)),
        ("b", Velocity(0.0, 0.0, -0.5, 0.0)),
    ],
)
def test_move_keys_give_teleop_twist_keyboards_twists(key: str, expected: Velocity) -> None:
    kb = TwistKeyboard()  # speed 0.5, turn 1.0: the node's defaults
    assert _twists(kb, key) == [expected]


def test_speed_keys_scale_speed_and_turn_and_publish() -> None:
    kb = TwistKeyboard(speed=0.5, turn=1.0)
    got = _twists(kb, "iqwe")
    # q: both x1.1; w: speed x1.1; e: turn x1.1 (the same float products as the ROS node)
    speed, turn = 0.5 * 1.1, 1.0 * 1.1
    assert got[1] == Velocity(speed, 0.0, 0.0, 0.0)
    speed *= 1.1
    assert got[2] == Velocity(speed, 0.0, 0.0, 0.0)
    turn *= 1.1
    assert (kb.speed, kb.turn) == (speed, turn)
    # speed keys keep the direction (still forward) and publish the rescaled command
    got = _twists(kb, "zxcj")
    speed *= 0.9
    turn *= 0.9
    assert got[0] == Velocity(speed, 0.0, 0.0, 0.0)
    speed *= 0.9
    assert got[1] == Velocity(speed, 0.0, 0.0, 0.0)
    assert got[2] == Velocity(speed, 0.0, 0.0, 0.0)
    assert got[3] == Velocity(0.0, 0.0, 0.0, turn * 0.9)
    assert kb.speed == speed


def test_speed_limit_caps_and_says_so() -> None:
    kb = TwistKeyboard(speed=0.5, turn=1.0, speed_limit=0.6, turn_limit=1.15)
    kb.press("q")
    result = kb.press("q")
    assert kb.speed == 0.6
    assert kb.turn == 1.15
    assert any("speed_limit" in line for line in result.lines)
    assert any("turn_limit" in line for line in result.lines)


def test_any_other_key_stops_and_ctrl_c_quits() -> None:
    kb = TwistKeyboard()
    assert _twists(kb, "ik") == [Velocity(0.5, 0, 0, 0), Velocity()]
    assert _twists(kb, "i7") == [Velocity(0.5, 0, 0, 0), Velocity()]
    result = kb.press(CTRL_C)
    assert result.quit
    assert not result.publish


def test_key_timeout_stops_a_moving_robot_once() -> None:
    kb = TwistKeyboard()
    assert not kb.press("").publish  # already stopped: nothing published
    kb.press("i")
    first = kb.press("")
    assert first.publish
    assert kb.velocity == Velocity()
    assert not kb.press("").publish


def test_help_is_repeated_every_15_speed_keys() -> None:
    kb = TwistKeyboard()
    with_help = [i for i in range(30) if len(kb.press("q" if i % 2 else "z").lines) > 3]
    assert with_help == [14, 29]


# ---------------------------------------------------------------------- turtlebot3


def _tb3(kb: Turtlebot3Keyboard, keys: list[str]) -> list[Velocity]:
    out = []
    for key in keys:
        result = kb.press(key)
        assert result.publish
        out.append(kb.velocity)
    return out


def test_tb3_steps_are_smoothed_by_half_steps() -> None:
    kb = Turtlebot3Keyboard(model="burger")
    got = _tb3(kb, ["w", "", "", "a", "", ""])
    assert [v.linear_x for v in got] == pytest.approx([0.005, 0.01, 0.01, 0.01, 0.01, 0.01])
    assert [v.angular_z for v in got] == pytest.approx([0.0, 0.0, 0.0, 0.05, 0.1, 0.1])
    assert all(v.linear_y == v.linear_z == 0.0 for v in got)
    got = _tb3(kb, ["x", "x", "", "", "d", "d", "", ""])
    assert got[-1].linear_x == pytest.approx(-0.01)
    assert got[-1].angular_z == pytest.approx(-0.1)


def test_tb3_space_and_s_stop_at_once() -> None:
    for stop in (" ", "s"):
        kb = Turtlebot3Keyboard()
        _tb3(kb, ["w"] * 10 + [""] * 30 + ["a"] * 5 + [""] * 10)
        assert kb.velocity.linear_x == pytest.approx(0.1)
        assert kb.velocity.angular_z == pytest.approx(0.5)
        assert _tb3(kb, [stop]) == [Velocity()]
        assert (kb.target_linear, kb.target_angular) == (0.0, 0.0)


@pytest.mark.parametrize("model", ["burger", "waffle", "waffle_pi"])
def test_tb3_model_limits(model: str) -> None:
    kb = Turtlebot3Keyboard(model=model)
    _tb3(kb, ["w"] * 40 + ["d"] * 40 + [""] * 200)
    lin, ang = TB3_LIMITS[model]
    assert kb.velocity == Velocity(linear_x=lin, angular_z=-ang)
    assert (lin, ang) == {"burger": (0.22, 2.84)}.get(model, (0.26, 1.82))
    _tb3(kb, ["x"] * 80 + [""] * 200)
    assert kb.velocity.linear_x == -lin


def test_tb3_unknown_model_gets_burger_limits() -> None:
    kb = Turtlebot3Keyboard(model="rosbot")
    assert not kb.known_model
    assert (kb.max_linear, kb.max_angular) == TB3_LIMITS["burger"]


def test_tb3_help_every_20_velocity_keys_and_ctrl_c() -> None:
    kb = Turtlebot3Keyboard()
    helps = [i for i in range(40) if len(kb.press("wx"[i % 2]).lines) > 1]
    assert helps == [19, 39]
    assert len(kb.press(" ").lines) == 1  # a stop does not count
    result = kb.press(CTRL_C)
    assert result.quit
    assert not result.publish


def test_velocity_to_twist() -> None:
    twist = Velocity(0.1, 0.2, 0.3, 0.4).to_twist()
    assert (twist.linear.x, twist.linear.y, twist.linear.z) == (0.1, 0.2, 0.3)
    assert (twist.angular.x, twist.angular.y, twist.angular.z) == (0.0, 0.0, 0.4)
