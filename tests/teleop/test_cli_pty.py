"""``visnav teleop`` in a real pseudo-terminal, heard on the graph of a private domain."""

from __future__ import annotations

import os
import pty
import select
import signal
import subprocess
import sys
import termios
import time
from typing import Any

import pytest

from visnav.graph import Context, Node
from visnav.msgs.types import Twist


def _read_until(fd: int, needle: bytes, timeout_s: float) -> bytes:
    seen = b""
    end = time.monotonic() + timeout_s
    while needle not in seen and time.monotonic() < end:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            try:
                seen += os.read(fd, 4096)
            except OSError:  # the child closed the terminal
                break
    return seen


def _start(domain: int, *args: str) -> tuple[subprocess.Popen[bytes], int, int]:
    master, slave = pty.openpty()
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", "teleop", *args],
        stdin=slave,
        stdout=slave,
        stderr=subprocess.PIPE,
        env=env,
        close_fds=True,
    )
    return proc, master, slave


def _drive(
    domain: int, args: tuple[str, ...], script: list[tuple[str, int]], ready: bytes
) -> tuple[list[Twist], bytes, Any, Any]:
    """Start ``visnav teleop ARGS``, wait for ``ready``, type ``(keys, messages to await)``."""
    with Context(domain) as ctx:
        got: list[Twist] = []
        Node("listener", context=ctx).create_subscription(Twist, "/cmd_vel", got.append, 100)
        proc, master, slave = _start(domain, *args)
        before = termios.tcgetattr(slave)
        try:
            out = _read_until(master, ready, 30.0)
            assert ready in out, out.decode(errors="replace")
            during = termios.tcgetattr(slave)
            for keys, count in script:
                os.write(master, keys.encode())
                want = len(got) + count
                ctx.spin_until(lambda want=want: len(got) >= want, timeout_s=10.0)
            assert proc.wait(timeout=20) == 0, proc.stderr.read() if proc.stderr else ""
            ctx.spin(0.3)
            after = termios.tcgetattr(slave)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            os.close(master)
            os.close(slave)
    assert during[3] & termios.ICANON == 0  # raw input while running
    assert after == before  # the terminal is restored
    return got, out, before, during


@pytest.mark.slow
@pytest.mark.ci
def test_teleop_twist_keyboard_through_a_pty(domain: int) -> None:
    got, out, _, _ = _drive(
        domain,
        ("--key-timeout", "0"),
        [("i", 1), ("q", 1), ("J", 1), ("k", 1), ("\x03", 1)],
        b"currently:",
    )
    assert b"u  i  o" in out
    moves = [(t.linear.x, t.linear.y, t.angular.z) for t in got]
    speed = 0.5 * 1.1
    assert moves == [
        (0.0, 0.0, 0.0),  # the first command, once this subscriber was seen
        (0.5, 0.0, 0.0),  # i
        (speed, 0.0, 0.0),  # q: x1.1, still forward
        (0.0, speed, 0.0),  # J: holonomic left
        (0.0, 0.0, 0.0),  # k: stop
        (0.0, 0.0, 0.0),  # Ctrl-C: the stop command on exit
    ]


@pytest.mark.slow
def test_turtlebot3_teleop_key_through_a_pty(domain: int) -> None:
    got, out, _, _ = _drive(
        domain, ("--turtlebot3", "--model", "waffle"), [("w", 5), ("\x03", 1)], b"Ctrl-C"
    )
    assert b"waffle" in out
    assert b"0.26" in out
    xs = [t.linear.x for t in got]
    assert xs[0] in (0.0, 0.005)  # 0.1 s timeouts publish from the start
    assert max(xs) == pytest.approx(0.01)  # w: 0.01 m/s, reached in half steps
    assert pytest.approx(0.005) in xs
    assert xs[-1] == 0.0


@pytest.mark.slow
def test_sigint_restores_the_terminal_and_stops_the_robot(domain: int) -> None:
    """A SIGINT from elsewhere (not the Ctrl-C key): zero Twist, terminal restored, exit 130."""
    with Context(domain) as ctx:
        got: list[Twist] = []
        Node("listener", context=ctx).create_subscription(Twist, "/cmd_vel", got.append, 100)
        proc, master, slave = _start(domain, "--key-timeout", "0")
        before = termios.tcgetattr(slave)
        try:
            assert b"currently:" in _read_until(master, b"currently:", 30.0)
            os.write(master, b"l")
            ctx.spin_until(lambda: any(t.angular.z == -1.0 for t in got), timeout_s=10.0)
            proc.send_signal(signal.SIGINT)
            assert proc.wait(timeout=20) == 130
            ctx.spin_until(lambda: got[-1].angular.z == 0.0, timeout_s=5.0)
            assert termios.tcgetattr(slave) == before
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            os.close(master)
            os.close(slave)
    assert [t.angular.z for t in got][-2:] == [-1.0, 0.0]


def test_teleop_without_a_terminal_is_one_error_line(domain: int) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    for args in (("--turtlebot3",),):  # teleop_twist_keyboard's: tests/teleop/test_nodes.py
        proc = subprocess.run(
            [sys.executable, "-m", "visnav.cli.main", "teleop", *args],
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            env=env,
            timeout=60,
            check=False,
        )
        assert proc.returncode == 1
        assert proc.stderr.startswith("error: visnav teleop"), proc.stderr
        assert "not a terminal" in proc.stderr
        assert "Traceback" not in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1


def test_teleop_arguments_are_checked(domain: int) -> None:
    from visnav.cli.main import main

    assert main(["teleop", "--turtlebot3", "--speed", "0.3"]) == 1
    assert main(["teleop", "--model", "waffle"]) == 1
    assert main(["teleop", "speed=0.3"]) == 1
