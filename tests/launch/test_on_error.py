"""``on_error: log|restart|shutdown``: one node's callback fault stays in that node by default."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.launch import Launcher, load_launch
from visnav.launch.errors import LaunchParseError
from visnav.msgs import CameraInfo, Header, Image, make, ns_to_time


def write(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return path


def test_by_default_a_raising_shared_node_is_logged_and_the_launch_goes_on(
    domain: int, test_nodes_path: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    del test_nodes_path
    f = write(
        tmp_path / "bomb.yaml",
        """
        launch:
          - node: {exec: launch_test_nodes:Talker, process: own, params: {rate: 5}}
          - node: {exec: launch_test_nodes:Bomb, params: {delay: 0.2}}
          - node: {exec: launch_test_nodes:Listener, process: shared}
        """,
    )
    launcher = Launcher(load_launch(f), domain=domain, sigterm_timeout=2.0)
    stop = threading.Event()
    result: list[int] = []
    caplog.set_level(logging.ERROR)
    runner = threading.Thread(target=lambda: result.append(launcher.run(stop)), daemon=True)
    runner.start()

    def heard() -> bool:
        nodes = [n for n in launcher.shared_nodes if n.get_name() == "listener"]
        return bool(nodes and nodes[0].received)

    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and not (
        heard() and launcher.context.faults.count("/bomb") >= 3
    ):
        time.sleep(0.05)
    stop.set()
    runner.join(15.0)
    assert result == [0]
    assert launcher.context.faults.count("/bomb") >= 3
    raised = [r.getMessage() for r in caplog.records if "RuntimeError: boom" in r.getMessage()]
    assert len(raised) == 1  # rate limited: one line per 5 s
    assert "timer (every 0.2 s)" in raised[0]
    assert "the node keeps running" in raised[0]
    # the other nodes kept working: the listener heard the own talker
    listener = next(n for n in launcher.shared_nodes if n.get_name() == "listener")
    assert listener.received
    assert [e.kind for e in launcher.events] == ["started", "stopped"]


@pytest.mark.slow
@pytest.mark.ci
def test_on_error_restart_restarts_an_own_node_as_respawn_does(
    domain: int, test_nodes_path: Path, tmp_path: Path
) -> None:
    del test_nodes_path
    f = write(
        tmp_path / "restart.yaml",
        """
        launch:
          - node:
              exec: launch_test_nodes:Bomb
              on_error: restart
              respawn_delay: 0.05
              respawn_max_retries: 1
              params: {delay: 0.1}
        """,
    )
    description = load_launch(f)
    assert description.nodes[0].process == "own"  # implied, as by respawn
    launcher = Launcher(description, domain=domain)
    started = time.monotonic()
    assert launcher.run() == 1  # returns when the node gave up
    assert time.monotonic() - started < 20.0
    kinds = [e.kind for e in launcher.events]
    assert kinds == ["started", "exited", "respawning", "started", "exited", "gave_up"]
    assert [e.returncode for e in launcher.events if e.kind == "exited"] == [1, 1]


def test_on_error_shutdown_on_an_own_node_stops_the_launch(
    domain: int, test_nodes_path: Path, tmp_path: Path
) -> None:
    del test_nodes_path
    f = write(
        tmp_path / "stop.yaml",
        """
        launch:
          - node: {exec: launch_test_nodes:Bomb, process: own, on_error: shutdown,
                   params: {delay: 0.1}}
          - node: {exec: launch_test_nodes:Talker, process: own, params: {rate: 5}}
        """,
    )
    launcher = Launcher(load_launch(f), domain=domain, sigterm_timeout=2.0)
    assert launcher.run() == 1
    bomb = [e for e in launcher.events if e.name == "/bomb"]
    assert [e.kind for e in bomb][:2] == ["started", "exited"]
    assert bomb[1].returncode == 1
    talker = [e.kind for e in launcher.events if e.name == "/talker"]
    assert talker == ["started", "stopped"]


def test_an_own_node_with_on_error_log_survives_its_callback_errors(
    domain: int, test_nodes_path: Path, tmp_path: Path
) -> None:
    del test_nodes_path
    f = write(
        tmp_path / "own.yaml",
        "launch:\n  - node: {exec: launch_test_nodes:Bomb, process: own, params: {delay: 0.1}}\n",
    )
    launcher = Launcher(load_launch(f), domain=domain, sigterm_timeout=2.0)
    assert launcher.run(duration_s=2.0) == 0
    assert [e.kind for e in launcher.events] == ["started", "stopped"]


@pytest.mark.parametrize(
    ("node", "match"),
    [
        ("{exec: launch_test_nodes:Bomb, on_error: ignore}", "on_error is 'ignore': expected one"),
        (
            "{exec: launch_test_nodes:Bomb, on_error: restart, process: shared}",
            "on_error: restart needs its own process",
        ),
    ],
)
def test_bad_on_error_is_refused(
    test_nodes_path: Path, tmp_path: Path, node: str, match: str
) -> None:
    del test_nodes_path
    f = write(tmp_path / "bad.yaml", f"launch:\n  - node: {node}\n")
    with pytest.raises(LaunchParseError, match=match) as info:
        load_launch(f)
    assert "bad.yaml:2" in str(info.value)


def test_on_error_is_printed_and_travels_to_the_runner(
    test_nodes_path: Path, tmp_path: Path
) -> None:
    del test_nodes_path
    f = write(
        tmp_path / "p.yaml",
        "launch:\n  - node: {exec: launch_test_nodes:Bomb, process: own, on_error: shutdown}\n",
    )
    description = load_launch(f)
    assert "on_error=shutdown" in description.format()
    assert '"on_error": "shutdown"' in description.dumps()


def _image(stamp_ns: int, value: int) -> Any:
    return make(
        Image,
        header=Header(stamp=ns_to_time(stamp_ns), frame_id="c"),
        height=4,
        width=6,
        encoding="rgb8",
        step=18,
        data=np.full(72, value, np.uint8),
    )


def _info(stamp_ns: int) -> Any:
    return make(
        CameraInfo,
        header=Header(stamp=ns_to_time(stamp_ns), frame_id="c"),
        height=4,
        width=6,
        distortion_model="plumb_bob",
        d=np.zeros(5),
        k=np.array([5.0, 0, 3, 0, 5, 2, 0, 0, 1]),
        r=np.eye(3).ravel(),
        p=np.array([5.0, 0, 3, 0, 0, 5, 2, 0, 0, 0, 1, 0]),
    )


@pytest.mark.slow
@pytest.mark.ci
def test_image_proc_survives_an_empty_image_from_topic_pub(
    domain: int, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Issue 13's repro: a 0x0 rgb8 image to /cam/image_raw once stopped the whole launch."""
    f = write(tmp_path / "cam.yaml", "launch:\n  - node: {exec: image_proc, namespace: /cam}\n")
    launcher = Launcher(load_launch(f), domain=domain, sigterm_timeout=2.0)
    stop = threading.Event()
    result: list[int] = []
    runner = threading.Thread(target=lambda: result.append(launcher.run(stop)), daemon=True)
    caplog.set_level(logging.WARNING)
    runner.start()
    mono: list[Any] = []
    try:
        with Context(domain) as ctx:
            node = Node("probe", context=ctx)
            info_pub = node.create_publisher(CameraInfo, "/cam/camera_info", 5)
            image_pub = node.create_publisher(Image, "/cam/image_raw", 5)
            node.create_subscription(Image, "/cam/image_mono", mono.append, 10)
            # image_proc subscribes to image_raw before camera_info: wait for both, or the
            # camera_info below can be published before this process knows its subscriber
            for what, seen in (
                ("image_raw", lambda: image_pub.get_subscription_count() > 0),
                ("camera_info", lambda: info_pub.get_subscription_count() > 0),
                ("image_mono", lambda: node.count_publishers("/cam/image_mono") > 0),
            ):
                assert ctx.spin_until(seen, 30.0), f"image_proc's {what} never appeared"
            info_pub.publish(_info(0))  # pairs with the empty image (stamp 0)
            env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
            pub = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "visnav.cli.main",
                    "topic",
                    "pub",
                    "-1",
                    "--max-wait-time-secs",  # a failure to match is an error, not a hang
                    "30",
                    "/cam/image_raw",
                    "sensor_msgs/msg/Image",
                    "{header: {frame_id: c}, encoding: rgb8}",
                ],
                env=env,
                capture_output=True,
                text=True,
                timeout=60,
                check=False,
            )
            assert pub.returncode == 0, pub.stderr
            deadline = time.monotonic() + 20.0
            while time.monotonic() < deadline and "0x0" not in caplog.text:
                ctx.spin_once(0.05)
            assert "Image.width x Image.height is 0x0" in caplog.text
            for k in range(1, 30):
                info_pub.publish(_info(k))
                image_pub.publish(_image(k, 3 * k))
                if ctx.spin_until(lambda: bool(mono), 0.2):
                    break
            assert mono, "image_proc stopped processing after the bad image"
            assert runner.is_alive()
    finally:
        stop.set()
        runner.join(15.0)
    assert result == [0]
    assert "cv2.error" not in caplog.text
    assert "stopping" not in caplog.text
