"""A real Foxglove protocol client: ``@foxglove/ws-protocol`` (npm) under node, offering ONLY
``foxglove.websocket.v1`` (what Lichtblick and the npm clients offer).

It subscribes to ``/camera/image_raw`` and ``/map``, decodes them with the advertised
``ros2msg`` schemas (``@foxglove/rosmsg`` + ``@foxglove/rosmsg2-serialization``, Foxglove's
own decoders) and publishes a goal. The packages are pinned in js/package-lock.json;
``npm ci --prefix tests/bridge/foxglove/js`` installs them (.ci/run does; this module does
it on first use when npm can reach its registry).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.bridge.foxglove import FoxgloveServer
from visnav.graph import DurabilityPolicy, Node, QoSProfile
from visnav.msgs.construct import default_message
from visnav.msgs.image import numpy_to_image
from visnav.msgs.serde import get_message_class, message_definition

from .conftest import Spun

JS_DIR = Path(__file__).parent / "js"
CLIENT = JS_DIR / "client.js"


def _install() -> str | None:
    """Install the pinned npm packages if missing; the reason they are unavailable, or None."""
    if shutil.which("node") is None or shutil.which("npm") is None:
        return "node/npm not installed (apt-get install nodejs npm)"
    if (JS_DIR / "node_modules" / "@foxglove" / "ws-protocol").is_dir():
        return None
    try:
        subprocess.run(
            ["npm", "ci", "--no-audit", "--no-fund"],
            cwd=JS_DIR,
            check=True,
            capture_output=True,
            timeout=300,
        )
    except (subprocess.SubprocessError, OSError) as exc:
        return f"npm ci in {JS_DIR} failed ({exc}); run it by hand"
    return None


@pytest.fixture(scope="module")
def js_client() -> Path:
    """The client script, its npm packages installed."""
    problem = _install()
    if problem is not None:
        pytest.skip(problem)
    return CLIENT


def run_js_client(
    url: str, *, goal: dict[str, Any], timeout_s: float = 30.0, **env: str
) -> list[dict[str, Any]]:
    """Run the node client against ``url``; its JSON output lines."""
    full_env = {
        **os.environ,
        "FG_GOAL": json.dumps(goal),
        "FG_GOAL_SCHEMA": message_definition("geometry_msgs/msg/PoseStamped"),
        "FG_TIMEOUT_MS": str(int(timeout_s * 1000)),
        **env,
    }
    proc = subprocess.run(
        ["node", str(CLIENT), url],
        cwd=JS_DIR,
        env=full_env,
        capture_output=True,
        text=True,
        timeout=timeout_s + 10,
        check=False,
    )
    lines = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    assert proc.returncode == 0, (proc.returncode, lines, proc.stderr[-2000:])
    return lines


def goal_dict(x: float, y: float) -> dict[str, Any]:
    """A PoseStamped in the map frame as the JS writer takes it."""
    return {
        "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "map"},
        "pose": {
            "position": {"x": x, "y": y, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        },
    }


@pytest.mark.slow
@pytest.mark.ci
def test_ws_protocol_client_decodes_image_and_map_and_publishes_a_goal(
    js_client: Path, graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    image_cls = get_message_class("sensor_msgs/msg/Image")
    grid_cls = get_message_class("nav_msgs/msg/OccupancyGrid")
    pose_cls = get_message_class("geometry_msgs/msg/PoseStamped")
    node = Node("robot", context=graph.ctx)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    grid = default_message("nav_msgs/msg/OccupancyGrid")
    grid.header.frame_id = "map"
    grid.info.width, grid.info.height, grid.info.resolution = 20, 10, 0.05
    grid.data = np.where(np.arange(200) % 7 == 0, 100, 0).astype(np.int8)
    node.create_publisher(grid_cls, "/map", latched).publish(grid)
    cam = node.create_publisher(image_cls, "/camera/image_raw", 5)
    goals: list[Any] = []
    node.create_subscription(pose_cls, "/move_base_simple/goal", goals.append, 1)
    stop = threading.Event()
    frame = np.arange(48 * 64 * 3, dtype=np.uint32).reshape(48, 64, 3).astype(np.uint8)

    def camera() -> None:
        while not stop.wait(0.05):
            msg = numpy_to_image(frame, "rgb8")
            msg.header.frame_id = "camera_optical"
            cam.publish(msg)

    thread = threading.Thread(target=camera, daemon=True)
    thread.start()
    server = make_server()
    try:
        lines = run_js_client(server.url, goal=goal_dict(1.5, -0.5))
    finally:
        stop.set()
        thread.join()
    assert lines[0] == {"open": True, "protocol": "foxglove.websocket.v1"}
    subscribed = {d["subscribed"]: d for d in lines if "subscribed" in d}
    assert subscribed["/map"]["schemaEncoding"] == "ros2msg"
    assert subscribed["/camera/image_raw"]["encoding"] == "cdr"
    decoded = {d["topic"]: d for d in lines if "kind" in d}
    img = decoded["/camera/image_raw"]
    assert (img["kind"], img["width"], img["height"], img["encoding"]) == ("Image", 64, 48, "rgb8")
    assert img["frame_id"] == "camera_optical"
    assert img["sum"] == int(frame.astype(np.int64).sum())
    m = decoded["/map"]
    assert (m["kind"], m["width"], m["height"], m["frame_id"]) == ("OccupancyGrid", 20, 10, "map")
    assert m["resolution"] == pytest.approx(0.05)
    assert m["occupied"] == int((grid.data > 50).sum())
    assert any(d.get("published") == "/move_base_simple/goal" for d in lines)
    deadline = time.monotonic() + 5
    while not goals and time.monotonic() < deadline:
        time.sleep(0.05)
    assert [(g.header.frame_id, g.pose.position.x, g.pose.position.y) for g in goals] == [
        ("map", 1.5, -0.5)
    ]
