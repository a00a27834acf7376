"""`visnav action send_goal /navigate_to_pose ...` drives the car of `visnav launch car`."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(600)
def test_send_goal_drives_the_launched_car_to_succeeded(domain: int, tmp_path: Path) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    args = ["mission:=false", "slam:=false", "ideal_sensors:=true", "duration:=300.0"]
    launch = subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", "launch", "car", *args],
        env=env,
        cwd=tmp_path,  # its runs/<time> folder
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        # the car spawns at (-6, -1.5) facing +y; (-6, 0) is the corridor's west node
        goal = "{pose: {header: {frame_id: map}, pose: {position: {x: -6.0, y: 0.0}}}}"
        started = time.monotonic()
        out = subprocess.run(
            [
                sys.executable, "-m", "visnav.cli.main", "action", "send_goal",
                "/navigate_to_pose", "nav2_msgs/action/NavigateToPose", goal,
                "--feedback", "--timeout", "120",
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=400,
            check=False,
        )  # fmt: skip
        elapsed = time.monotonic() - started
        assert out.returncode == 0, out.stderr[-2000:]
        text = out.stdout
        assert "Goal accepted with ID: " in text
        assert "Feedback:\n    current_pose:" in text
        assert "distance_remaining:" in text
        assert text.rstrip().endswith("Goal finished with status: SUCCEEDED"), text[-3000:]
        assert launch.poll() is None, "the launch ended before the goal did"
        print(f"send_goal took {elapsed:.1f} s")
    finally:
        launch.terminate()
        try:
            launch.wait(30)
        except subprocess.TimeoutExpired:
            launch.kill()
            launch.wait(10)
