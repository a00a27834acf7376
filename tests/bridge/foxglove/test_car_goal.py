"""End to end: Foxglove's "Publish pose" reaches move_base of a launched car, which gets there.

``visnav launch car`` (no mission) and ``visnav foxglove`` run as the user would start them;
the ``@foxglove/ws-protocol`` client (only ``foxglove.websocket.v1``) decodes the car's camera
image and ``/map`` with their advertised schemas, then publishes a goal on
``/move_base_simple/goal``; move_base's ``/move_base/status`` must report it SUCCEEDED.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from visnav.graph import Context, Node
from visnav.msgs.serde import get_message_class

from .test_js_client import goal_dict, js_client, run_js_client

__all__ = ["js_client"]  # the fixture, imported for this module's test

SUCCEEDED = 3


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_foxglove_goal_drives_the_launched_car_to_succeeded(
    js_client: Path, domain: int, tmp_path: Path
) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    args = ["mission:=false", "slam:=false", "ideal_sensors:=true", "duration:=300.0"]
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "visnav.cli.main", "launch", "car", *args],
            env=env,
            cwd=tmp_path,  # its runs/<time> folder
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    ]
    try:
        fox = subprocess.Popen(
            [sys.executable, "-m", "visnav.cli.main", "foxglove", "--port", "0"],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        procs.append(fox)
        assert fox.stdout is not None
        first = fox.stdout.readline()
        url = next(w for w in first.split() if w.startswith("ws://"))
        statuses: list[Any] = []
        with Context(domain) as ctx:
            probe = Node("probe", context=ctx)
            status_cls = get_message_class("actionlib_msgs/msg/GoalStatusArray")
            probe.create_subscription(status_cls, "/move_base/status", statuses.append, 10)
            started = time.monotonic()
            # the car spawns at (-6, -1.5) facing +y; (-6, 0) is the corridor's west node
            lines = run_js_client(
                url,
                goal=goal_dict(-6.0, 0.0),
                timeout_s=240.0,
                FG_TOPICS="/depth_camera/image_raw,/map",
            )
            decoded = {d["topic"]: d for d in lines if "kind" in d}
            assert decoded["/depth_camera/image_raw"]["kind"] == "Image"
            assert decoded["/depth_camera/image_raw"]["width"] > 0
            assert decoded["/map"]["kind"] == "OccupancyGrid"
            assert decoded["/map"]["cells"] > 0

            def reached() -> bool:
                last = statuses[-1].status_list if statuses else []
                return any(int(s.status) == SUCCEEDED for s in last)

            ctx.spin_until(reached, 240.0)
            elapsed = time.monotonic() - started
        last = statuses[-1].status_list if statuses else []
        assert reached(), [(int(s.status), s.text) for s in last]
        for proc in procs:
            assert proc.poll() is None, "a process ended before the goal was reached"
        print(f"image + map decoded and goal reached in {elapsed:.1f} s")
    finally:
        for proc in procs:
            proc.terminate()
        for proc in procs:
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(10)
