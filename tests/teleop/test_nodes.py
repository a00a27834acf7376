"""The teleop nodes on a local graph, with scripted keys instead of a terminal."""

from __future__ import annotations

import io
import time
from collections.abc import Iterator
from typing import Any

import pytest

from visnav.graph import Context, Node
from visnav.graph.errors import ParameterError
from visnav.msgs.types import Twist, TwistStamped
from visnav.teleop.errors import NotATerminalError
from visnav.teleop.nodes import TeleopTwistKeyboardNode, Turtlebot3TeleopKeyNode
from visnav.teleop.terminal import TerminalKeys


class ScriptedKeys:
    """Hands out one scripted key per read; records close()."""

    def __init__(self, keys: str) -> None:
        self.keys = list(keys)
        self.closed = False

    def read_keys(self, timeout_s: float) -> list[str]:
        del timeout_s
        return [self.keys.pop(0)] if self.keys else []

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _listen(ctx: Context, msg_type: type[Any] = Twist) -> list[Any]:
    got: list[Any] = []
    Node("listener", context=ctx).create_subscription(msg_type, "cmd_vel", got.append, 100)
    return got


def _xz(twists: list[Twist]) -> list[tuple[float, float, float]]:
    return [(t.linear.x, t.linear.y, t.angular.z) for t in twists]


def test_twist_keyboard_publishes_keys_and_stops_on_ctrl_c(ctx: Context) -> None:
    got = _listen(ctx)
    lines: list[str] = []
    keys = ScriptedKeys("iuJ,k\x03")
    node = TeleopTwistKeyboardNode(
        keys=keys, out=lines.append, context=ctx, parameter_overrides={"key_timeout": 0.0}
    )
    assert ctx.spin_until(lambda: node.finished, timeout_s=5.0)
    ctx.spin_some()
    assert _xz(got) == [
        (0.0, 0.0, 0.0),  # the first command once a subscriber is there
        (0.5, 0.0, 0.0),
        (0.5, 0.0, 1.0),
        (0.0, 0.5, 0.0),
        (-0.5, 0.0, 0.0),
        (0.0, 0.0, 0.0),  # k
        (0.0, 0.0, 0.0),  # Ctrl-C: the stop command
    ]
    assert keys.closed
    assert any("u  i  o" in line for line in lines)


def test_twist_keyboard_waits_for_a_subscriber(ctx: Context) -> None:
    lines: list[str] = []
    keys = ScriptedKeys("i")
    node = TeleopTwistKeyboardNode(keys=keys, out=lines.append, context=ctx)
    ctx.spin(0.3)
    assert keys.keys == ["i"]  # not read yet: the first key is not lost
    assert lines == []
    got = _listen(ctx)
    ctx.spin_until(lambda: len(got) >= 2, timeout_s=5.0)
    assert _xz(got)[:2] == [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0)]
    node.destroy_node()


def test_key_timeout_stops_the_robot(ctx: Context) -> None:
    got = _listen(ctx)
    node = TeleopTwistKeyboardNode(
        keys=ScriptedKeys("i"), out=lambda _: None, context=ctx,
        parameter_overrides={"key_timeout": 0.2},
    )  # fmt: skip
    start = time.monotonic()
    ctx.spin_until(lambda: len(got) >= 3, timeout_s=5.0)
    assert _xz(got) == [(0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (0.0, 0.0, 0.0)]
    assert time.monotonic() - start >= 0.2
    ctx.spin(0.4)
    assert len(got) == 3  # stopped already: the next timeouts publish nothing
    node.destroy_node()


def test_repeat_rate_and_stamped(ctx: Context) -> None:
    got = _listen(ctx, TwistStamped)
    node = TeleopTwistKeyboardNode(
        keys=ScriptedKeys("o"), out=lambda _: None, context=ctx,
        parameter_overrides={"repeat_rate": 20.0, "key_timeout": 0.0, "stamped": True,
                             "frame_id": "base_link", "speed": 0.3, "turn": 0.7},
    )  # fmt: skip
    ctx.spin(0.6)
    node.destroy_node()
    ctx.spin_some()
    forward = [m for m in got if m.twist.linear.x == 0.3]
    assert len(forward) >= 5  # repeated at 20 Hz, not only on the key
    assert all(m.twist.angular.z == -0.7 for m in forward)
    assert {m.header.frame_id for m in got} == {"base_link"}
    assert got[-1].twist.linear.x == 0.0  # destroyed: the stop command


def test_bad_parameter_is_refused(ctx: Context) -> None:
    with pytest.raises(ParameterError, match="repeat_rate"):
        TeleopTwistKeyboardNode(
            keys=ScriptedKeys(""), context=ctx, parameter_overrides={"repeat_rate": -1.0}
        )


def test_tb3_publishes_every_event_smoothed(ctx: Context) -> None:
    got = _listen(ctx)
    lines: list[str] = []
    keys = ScriptedKeys("ww")
    node = Turtlebot3TeleopKeyNode(
        keys=keys, out=lines.append, context=ctx, parameter_overrides={"model": "waffle"}
    )
    assert any("waffle" in line for line in lines)
    ctx.spin(0.65)  # two keys, then a timeout event every 0.1 s
    assert 6 <= len(got) <= 9
    assert _xz(got)[:2] == [(0.005, 0.0, 0.0), (0.01, 0.0, 0.0)]
    assert [t.linear.x for t in got[2:5]] == pytest.approx([0.015, 0.02, 0.02])
    keys.keys = list("\x03")
    assert ctx.spin_until(lambda: node.finished, timeout_s=2.0)
    ctx.spin_some()
    assert _xz(got)[-1] == (0.0, 0.0, 0.0)


def test_tb3_unknown_model_warns(ctx: Context, caplog: pytest.LogCaptureFixture) -> None:
    node = Turtlebot3TeleopKeyNode(
        keys=ScriptedKeys(""), out=lambda _: None, context=ctx,
        parameter_overrides={"model": "rosbot"},
    )  # fmt: skip
    assert "burger's speed limits" in caplog.text
    assert node.keyboard.max_linear == 0.22
    node.destroy_node()


def test_ctrl_c_ends_the_process_when_last_node() -> None:
    with Context(transport="local") as ctx:
        node = Turtlebot3TeleopKeyNode(keys=ScriptedKeys("\x03"), out=lambda _: None, context=ctx)
        with pytest.raises(SystemExit) as exc:
            ctx.spin(1.0)
        assert exc.value.code == 0
        assert node.finished


def test_not_a_terminal() -> None:
    with pytest.raises(NotATerminalError, match="not a terminal"):
        TerminalKeys(io.StringIO("i"))
    with Context(transport="local") as ctx:
        # under pytest, standard input is captured: not a terminal
        with pytest.raises(NotATerminalError, match=r"teleop_twist_keyboard.*interactive"):
            TeleopTwistKeyboardNode(context=ctx)
        assert ctx.nodes == []  # the half-built node is gone
