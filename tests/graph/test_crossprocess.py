"""Two real processes in a private domain: discovery, typed delivery, latching, the CLI."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.graph.introspect import wait_for_discovery
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import Image, String, Twist

SCRIPTS = Path(__file__).parent / "scripts"


@pytest.fixture
def talker(start_script: Callable[..., subprocess.Popen[str]]) -> subprocess.Popen[str]:
    return start_script(SCRIPTS / "talker.py", "30")


def _cli(domain: int, *args: str, timeout: float = 20.0) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    return subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def test_discovery_and_typed_delivery_across_processes(
    domain: int, talker: subprocess.Popen[str]
) -> None:
    with Context(domain) as ctx:
        node = Node("listener", context=ctx)
        strings: list[str] = []
        images: list[Any] = []
        latched: list[str] = []
        node.create_subscription(String, "/robot/chatter", lambda m: strings.append(m.data), 10)
        node.create_subscription(Image, "/image", images.append, 5)
        node.create_subscription(
            String,
            "/latched",
            lambda m: latched.append(m.data),
            qos_profile_latched,
        )
        assert ctx.spin_until(lambda: len(strings) >= 3 and images and latched, 10.0)
        assert strings[0].startswith("hello ")
        img = images[0]
        assert isinstance(img, Image)
        assert (img.height, img.width, img.encoding) == (6, 8, "rgb8")
        assert np.array_equal(img.data, np.arange(144, dtype=np.uint8))
        assert latched == ["latched-hello"]
        wait_for_discovery(ctx)
        topics = dict(node.get_topic_names_and_types())
        assert topics["/robot/chatter"] == ["std_msgs/msg/String"]
        assert topics["/image"] == ["sensor_msgs/msg/Image"]
        assert ("talker", "/robot") in node.get_node_names_and_namespaces()
        pub = node.get_publishers_info_by_topic("/latched")[0]
        assert (pub.node_name, pub.durability, pub.depth) == ("talker", "transient_local", 1)


def test_domains_are_isolated(domain: int, talker: subprocess.Popen[str]) -> None:
    with Context(domain + 1) as ctx:
        node = Node("other", context=ctx)
        got: list[str] = []
        node.create_subscription(String, "/robot/chatter", lambda m: got.append(m.data), 10)
        ctx.spin_until(lambda: bool(got), 1.5)
        assert got == []
        assert "talker" not in node.get_node_names()


def test_cli_list_info_echo(domain: int, talker: subprocess.Popen[str]) -> None:
    out = _cli(domain, "topic", "list", "-t")
    assert out.returncode == 0, out.stderr
    assert "/robot/chatter [std_msgs/msg/String]" in out.stdout
    assert "/image [sensor_msgs/msg/Image]" in out.stdout
    echo = _cli(domain, "topic", "echo", "/robot/chatter", "--once")
    assert echo.returncode == 0, echo.stderr
    assert echo.stdout.startswith("data: hello ")
    field = _cli(domain, "topic", "echo", "/image", "--once", "--field", "header.frame_id")
    assert field.stdout.splitlines()[0] == "camera_optical_frame"
    nodes = _cli(domain, "node", "list")
    assert nodes.stdout.split() == ["/robot/talker"]
    info = _cli(domain, "node", "info", "/robot/talker")
    assert "/robot/chatter: std_msgs/msg/String" in info.stdout
    bad = _cli(domain, "topic", "echo", "/robot/chater", "--once")
    assert bad.returncode == 1
    assert bad.stderr.strip().splitlines() == [
        f"error: topic '/robot/chater' is not in the graph (domain {domain}); "
        "did you mean /robot/chatter?"
    ]
    bw = _cli(domain, "topic", "bw", "/image", "--duration", "2.5")
    assert "KB/s from" in bw.stdout, bw.stderr
    assert "Message size mean: 144 B" not in bw.stdout  # CDR adds header/encoding bytes
    delay = _cli(domain, "topic", "delay", "/image", "--duration", "2.5")
    delays = [float(x.split()[-1]) for x in delay.stdout.splitlines() if "average delay" in x]
    assert delays
    assert 0.0 <= delays[-1] < 0.5
    hz = _cli(domain, "topic", "hz", "/robot/chatter", "--duration", "2.5")
    rates = [float(line.split()[-1]) for line in hz.stdout.splitlines() if "average rate" in line]
    assert rates
    assert abs(rates[-1] - 50.0) < 2.5


def test_cli_pub_reaches_a_subscriber(domain: int) -> None:
    with Context(domain) as ctx:
        node = Node("sink", context=ctx)
        got: list[Any] = []
        node.create_subscription(Twist, "/cmd_vel", got.append, 10)
        env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "visnav.cli.main",
                "topic",
                "pub",
                "--once",
                "/cmd_vel",
                "geometry_msgs/msg/Twist",
                "{linear: {x: 0.5}, angular: {z: -1}}",
            ],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert ctx.spin_until(lambda: bool(got), 15.0)
        finally:
            proc.wait(timeout=15)
        assert proc.returncode == 0
        assert (got[0].linear.x, got[0].angular.z) == (0.5, -1.0)


def test_cli_errors_are_one_line(domain: int) -> None:
    bad = _cli(domain, "topic", "pub", "/x", "geometry_msgs/msg/Twst", "{}", "--once")
    assert bad.returncode == 1
    assert len(bad.stderr.strip().splitlines()) == 1
    assert bad.stderr.startswith("error: unknown message type 'geometry_msgs/msg/Twst'")
    assert "did you mean geometry_msgs/msg/Twist" in bad.stderr
    field = _cli(domain, "topic", "pub", "/x", "geometry_msgs/msg/Twist", "{linear: {q: 1}}")
    assert "has no field 'linear.q'" in field.stderr
    dbg = _cli(domain, "--debug", "topic", "pub", "/x", "geometry_msgs/msg/Twst", "{}")
    assert "Traceback" in dbg.stderr
    started = time.monotonic()
    assert _cli(domain, "--help").returncode == 0
    assert time.monotonic() - started < 10
