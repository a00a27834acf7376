"""Broadcasters, listener and the tf CLI, in one process and across processes."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import Header, Quaternion, Transform, TransformStamped, Vector3, ns_to_time
from visnav.tf import Buffer, LookupException
from visnav.tf.ros import StaticTransformBroadcaster, TransformBroadcaster, TransformListener
from visnav.tf.tree import format_tree, format_tree_dot


def _tf(parent: str, child: str, x: float, t_ns: int, yaw: float = 0.0) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=ns_to_time(t_ns), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=0.0, z=0.0),
            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        ),
    )


def test_broadcast_listen_and_tree_in_process() -> None:
    with Context(transport="local") as ctx:
        pub_node = Node("robot_state", context=ctx)
        listener_node = Node("listener", context=ctx)
        buffer = Buffer()
        TransformListener(buffer, listener_node)
        StaticTransformBroadcaster(pub_node).send_transform(
            [_tf("base_link", "camera_link", 0.2, 0), _tf("camera_link", "camera_optical", 0.0, 0)]
        )
        br = TransformBroadcaster(pub_node)
        for k in range(3):
            br.send_transform(_tf("odom", "base_link", float(k), k * 100_000_000))
        ctx.spin_some()
        T = buffer.lookup_transform_matrix("odom", "camera_link", 150_000_000)
        assert np.allclose(T[:3, 3], [1.5 + 0.2, 0, 0])
        infos = buffer.frame_infos()
        assert infos["base_link"].authority == "/robot_state"
        text = format_tree(infos)
        assert text.splitlines()[0] == "odom"
        assert "└── base_link  [" in text
        assert "camera_optical  [static, by /robot_state]" in text
        assert '"odom" -> "base_link"' in format_tree_dot(infos)
        with pytest.raises(LookupException, match="camera_link"):
            buffer.lookup_transform("odom", "camera_lnk")


def test_static_broadcaster_keeps_all_children_for_late_listener() -> None:
    with Context(transport="local") as ctx:
        node = Node("static_pub", context=ctx)
        sb = StaticTransformBroadcaster(node)
        sb.send_transform(_tf("base_link", "laser", 0.1, 0))
        sb.send_transform(_tf("base_link", "camera", 0.3, 0))
        sb.send_transform(_tf("base_link", "laser", 0.15, 0))  # replaces the first
        buffer = Buffer()
        TransformListener(buffer, Node("late", context=ctx))
        ctx.spin_some()
        assert sorted(buffer.get_frames()) == ["base_link", "camera", "laser"]
        assert buffer.lookup_transform("base_link", "laser").transform.translation.x == 0.15


def test_listener_spin_thread_across_processes(domain: int) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    cli = [sys.executable, "-m", "visnav.cli.main"]
    static = subprocess.Popen(
        [
            *cli,
            "tf",
            "static",
            "0.1",
            "0",
            "0.2",
            "1.5707963",
            "0",
            "0",
            "base_link",
            "camera_link",
            "--duration",
            "20",
        ],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert static.stdout is not None
        assert "publishing static transform base_link -> camera_link" in static.stdout.readline()
        with Context(domain) as ctx:
            buffer = Buffer()
            listener = TransformListener(buffer, Node("probe", context=ctx), spin_thread=True)
            t: Any = buffer.lookup_transform("base_link", "camera_link", 0, timeout=10.0)
            listener.unregister()
        assert t.transform.translation.z == pytest.approx(0.2)
        assert t.transform.rotation.z == pytest.approx(math.sin(math.pi / 4), abs=1e-6)
        echo = subprocess.run(
            [*cli, "tf", "echo", "base_link", "camera_link", "--once"],
            env=env,
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
        assert echo.returncode == 0, echo.stderr
        lines = echo.stdout.splitlines()
        assert lines[1] == "- Translation: [0.100, 0.000, 0.200]"
        assert lines[4] == "- Rotation: in RPY (degree) [0.000, -0.000, 90.000]"
        tree = subprocess.run(
            [*cli, "tf", "tree", "--duration", "1.5"],
            env=env,
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
        assert tree.stdout.splitlines()[0] == "base_link"
        assert "camera_link  [static, by /static_transform_publisher_" in tree.stdout
    finally:
        static.kill()
        static.wait(timeout=10)


def test_tf_static_argument_errors(domain: int) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    out = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "tf", "static", "1", "2", "base", "cam"],
        env=env,
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert out.returncode == 1
    assert out.stderr.startswith("error: tf static got 4 values: expected 'x y z yaw pitch roll")


def test_listener_clears_dynamic_tf_when_ros_time_jumps_back(
    caplog: pytest.LogCaptureFixture,
) -> None:
    # tf2_ros: "Detected jump back in time of X s. Clearing TF buffer." (bag loop, sim reset);
    # static transforms survive (tf2's StaticCache ignores clear()).
    with Context(transport="local") as ctx:
        pub_node = Node("robot", context=ctx)
        listener_node = Node("listener", context=ctx, use_sim_time=True)
        clock = listener_node.get_clock()
        buffer = Buffer()
        TransformListener(buffer, listener_node)
        StaticTransformBroadcaster(pub_node).send_transform(_tf("base_link", "camera", 0.2, 0))
        br = TransformBroadcaster(pub_node)
        for k in range(1, 4):
            clock.set_sim_time_ns(k * 1_000_000_000)
            br.send_transform(_tf("odom", "base_link", float(k), k * 1_000_000_000))
            ctx.spin_some()
        assert buffer.can_transform("odom", "camera", 2_500_000_000)
        clock.set_sim_time_ns(500_000_000)  # the bag starts over
        br.send_transform(_tf("odom", "base_link", 9.0, 500_000_000))
        ctx.spin_some()
        assert "Detected jump back in time of 2.5" in caplog.text
        assert "Clearing TF buffer" in caplog.text
        # Only the sample after the jump is left: the old 1..3 s history is gone.
        assert not buffer.can_transform("odom", "base_link", 2_500_000_000)
        moved = buffer.lookup_transform("odom", "camera")
        assert moved.transform.translation.x == pytest.approx(9.2)
        assert buffer.lookup_transform("base_link", "camera").transform.translation.x == 0.2
