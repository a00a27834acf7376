"""``visnav topic hz`` / ``delay`` count in sim time when a node publishes ``/clock``.

A publisher in this process runs a simulated clock at twice the wall-clock speed: ``/clock``
every 10 ms of sim time and a 20 Hz (sim) ``PointStamped`` stamped with the sim time. As
rostopic hz under ``/use_sim_time``, ``visnav topic hz`` reports the sim rate (20 Hz) and
the wall-clock rate (~40 Hz) beside it; ``--wall`` measures in wall time.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import pytest

from visnav.graph import Context, Node
from visnav.msgs import Clock, Header, Point, PointStamped
from visnav.msgs.time import ns_to_time

# Each test runs the CLI in a process for a few wall seconds.
pytestmark = [pytest.mark.slow, pytest.mark.ci]

SIM_STEP_NS = 10_000_000  # /clock every 10 ms of sim time
SPEED = 2.0  # sim seconds per wall second
TOPIC_EVERY = 5  # steps: 20 Hz in sim time, 40 Hz in wall time


@pytest.fixture
def sim_publisher(domain: int) -> Iterator[None]:
    """Publish /clock and /probe at 2x wall speed until the test ends."""
    stop = threading.Event()
    with Context(domain) as ctx:
        node = Node("fake_sim", context=ctx)
        clock_pub = node.create_publisher(Clock, "/clock", 10)
        probe_pub = node.create_publisher(PointStamped, "/probe", 10)

        def run() -> None:
            start = time.monotonic()
            step = 0
            while not stop.is_set():
                step += 1
                stamp = ns_to_time(step * SIM_STEP_NS)
                clock_pub.publish(Clock(clock=stamp))
                if step % TOPIC_EVERY == 0:
                    header = Header(stamp=stamp, frame_id="probe")
                    probe_pub.publish(PointStamped(header=header, point=Point(x=0.0, y=0.0, z=0.0)))
                # Paced against a schedule, so the average stays 2x even when a sleep overshoots.
                delay = start + step * SIM_STEP_NS / 1e9 / SPEED - time.monotonic()
                if delay > 0:
                    time.sleep(delay)

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join(5.0)


def cli(domain: int, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    return subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def last(pattern: str, text: str) -> float:
    found = re.findall(pattern, text)
    assert found, text
    return float(found[-1])


@pytest.mark.usefixtures("sim_publisher")
def test_hz_counts_in_sim_time_with_the_wall_rate_beside(domain: int) -> None:
    done = cli(domain, "topic", "hz", "/probe", "--duration", "4")
    assert done.returncode == 0, done.stderr
    assert last(r"average rate: ([\d.]+)", done.stdout) == pytest.approx(20.0, rel=0.03)
    assert "in sim time (/clock)" in done.stdout
    wall = last(r"wall-clock rate: ([\d.]+)", done.stdout)
    assert wall == pytest.approx(40.0, rel=0.15)


@pytest.mark.usefixtures("sim_publisher")
def test_hz_wall_measures_wall_time(domain: int) -> None:
    done = cli(domain, "topic", "hz", "/probe", "--wall", "--duration", "3")
    assert done.returncode == 0, done.stderr
    assert last(r"average rate: ([\d.]+)", done.stdout) == pytest.approx(40.0, rel=0.15)
    assert "sim time" not in done.stdout


@pytest.mark.usefixtures("sim_publisher")
def test_delay_counts_in_sim_time(domain: int) -> None:
    # Stamped with the sim time they are published at: a delay of a few /clock steps
    # (the receive time is the last /clock seen, which may still be the previous step).
    done = cli(domain, "topic", "delay", "/probe", "--duration", "2")
    assert done.returncode == 0, done.stderr
    assert abs(last(r"average delay: (-?[\d.]+)", done.stdout)) < 0.05
    assert "in sim time (/clock)" in done.stdout
    # In wall time the sim stamps (seconds since 0) are ~56 years old.
    wall = cli(domain, "topic", "delay", "/probe", "--wall", "--duration", "2")
    assert last(r"average delay: (-?[\d.]+)", wall.stdout) > 1e9


@pytest.mark.usefixtures("sim_publisher")
def test_echo_offset_counts_in_sim_time(domain: int) -> None:
    # rostopic echo --offset: times print as seconds from now; now is the sim time.
    done = cli(domain, "topic", "echo", "/probe", "--once", "--offset", "--field", "header")
    assert done.returncode == 0, done.stderr
    assert abs(last(r"stamp: (-?[\d.e-]+)", done.stdout)) < 0.05
    field = cli(domain, "topic", "echo", "/probe", "--once", "--offset", "--field", "header.stamp")
    assert abs(float(field.stdout.split()[0])) < 0.05
    wall = cli(domain, "topic", "echo", "/probe", "--once", "--offset", "--wall")
    assert last(r"stamp: (-?[\d.e+-]+)", wall.stdout) < -1e9
    plain = cli(domain, "topic", "echo", "/probe", "--once", "--field", "header.stamp")
    assert "sec:" in plain.stdout
