"""doctor on visnav's own healthy stacks: the car, the drone and a TurtleBot3 give no warning.

Each stack runs as a user starts it (``visnav launch``, a process of its own) in a private
graph domain; doctor listens to it live once it is up. Goals, plans, paths and markers are
event topics, the simulator's 1 kHz ``/gazebo/model_states`` arrives in bursts, SLAM's
map cloud is in ``map``: none of that is a fault.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from visnav.doctor import Severity, doctor_live
from visnav.graph import Context, Node
from visnav.msgs import Odometry

TB3 = Path(__file__).resolve().parents[1] / "data" / "turtlebot3"


def _launch(domain: int, cwd: Path, *args: str, **env: str) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "visnav.cli.main", "launch", *args]
    full_env = {**os.environ, "VISNAV_DOMAIN": str(domain), **env}
    return subprocess.Popen(cmd, env=full_env, cwd=cwd, text=True, stderr=subprocess.PIPE)


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize(
    ("stack", "odometry", "settle_s"),
    [("car", "/odom", 25.0), ("drone", "/drone/odom", 15.0), ("turtlebot3", "/odom", 5.0)],
)
def test_a_healthy_stack_has_no_warning(
    domain: int, stack: str, odometry: str, settle_s: float, tmp_path: Path
) -> None:
    if stack == "turtlebot3":
        proc = _launch(
            domain,
            tmp_path,
            str(TB3 / "turtlebot3_gazebo" / "launch" / "turtlebot3_world.launch"),
            "--package",
            f"turtlebot3_description={TB3 / 'turtlebot3_description'}",
            "--package",
            f"turtlebot3_gazebo={TB3 / 'turtlebot3_gazebo'}",
            TURTLEBOT3_MODEL="burger",
            GAZEBO_MODEL_PATH=str(TB3.parent / "gazebo_models"),
        )
    else:
        proc = _launch(domain, tmp_path, stack, "duration:=300")
    try:
        with Context(domain) as ctx:
            node = Node("wait_for_odometry", context=ctx)
            got: list[Odometry] = []
            node.create_subscription(Odometry, odometry, got.append, 10)
            assert ctx.spin_until(lambda: bool(got), 240.0), f"{stack}: no {odometry}"
            # sim time passes: the stack gets past its start-up (first map, first plan)
            start = got[-1].header.stamp.sec
            ctx.spin_until(lambda: got[-1].header.stamp.sec - start >= settle_s, 300.0)
            report = doctor_live(context=ctx, duration_s=8.0)
        bad = report.by_severity(Severity.ERROR) + report.by_severity(Severity.WARNING)
        assert not bad, report.format()
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=90)
    assert "Traceback" not in err, err
