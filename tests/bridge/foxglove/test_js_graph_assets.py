"""``assets`` and ``connectionGraph`` with the real ``@foxglove/ws-protocol`` client under node.

The client (js/graph_assets.js) offers only ``foxglove.websocket.v1``, fetches the
TurtleBot3 burger's base mesh by its ``package://`` URI (as Foxglove's 3D panel does for a
``robot_description``), a traversal URI and a URI outside the default allowlist, and
subscribes to the connection graph; a topic appears after its first update and must come
in a later one.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from visnav.bridge.foxglove import FoxgloveServer
from visnav.graph import Node
from visnav.msgs.serde import get_message_class

from .conftest import Spun
from .test_js_client import JS_DIR, js_client  # noqa: F401  (the fixture installs npm packages)

SCRIPT = JS_DIR / "graph_assets.js"
TB3 = Path(__file__).resolve().parents[2] / "data" / "turtlebot3"
BURGER = "package://turtlebot3_description/meshes/bases/burger_base.stl"


@pytest.mark.slow
def test_ws_protocol_client_fetches_a_mesh_and_gets_graph_updates(
    js_client: Path,  # noqa: F811
    graph: Spun,
    make_server: Callable[..., FoxgloveServer],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(TB3))
    String = get_message_class("std_msgs/msg/String")
    robot = Node("robot", context=graph.ctx)
    robot.create_publisher(String, "/status", 1)
    server = make_server()
    uris = [BURGER, "package://turtlebot3_description/../../etc/passwd", "file:///etc/passwd"]
    env = {**os.environ, "FG_ASSETS": ",".join(uris), "FG_WAIT_TOPIC": "/appeared"}
    proc = subprocess.Popen(
        ["node", str(SCRIPT), server.url],
        cwd=JS_DIR,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines: list[dict[str, Any]] = []
    timer = threading.Timer(40, proc.kill)
    timer.start()
    try:
        assert proc.stdout is not None
        for raw in proc.stdout:
            if not raw.startswith("{"):
                continue
            line = json.loads(raw)
            lines.append(line)
            if line.get("graph") and sum(1 for d in lines if d.get("graph")) == 1:
                robot.create_publisher(String, "/appeared", 1)
        code = proc.wait(timeout=10)
    finally:
        timer.cancel()
        proc.kill()
    assert code == 0, (lines, proc.stderr.read() if proc.stderr else "")
    assert lines[0] == {"open": True, "protocol": "foxglove.websocket.v1"}
    caps = next(d["capabilities"] for d in lines if "capabilities" in d)
    assert "assets" in caps
    assert "connectionGraph" in caps
    answers = {d["asset"]: d for d in lines if "asset" in d}
    mesh = (TB3 / "turtlebot3_description/meshes/bases/burger_base.stl").read_bytes()
    assert answers[1] == {
        "asset": 1,
        "status": 0,
        "bytes": len(mesh),
        "sha256": hashlib.sha256(mesh).hexdigest(),
    }
    assert answers[2]["status"] == 1
    assert "'..'" in answers[2]["error"]
    assert answers[3]["status"] == 1
    assert "allowlist" in answers[3]["error"]
    updates = [d for d in lines if d.get("graph")]
    first = {t["name"]: t["publisherIds"] for t in updates[0]["publishedTopics"]}
    assert first["/status"] == ["/robot"]
    assert "/appeared" not in first
    later = [t for u in updates[1:] for t in u["publishedTopics"] if t["name"] == "/appeared"]
    assert later == [{"name": "/appeared", "publisherIds": ["/robot"]}]
