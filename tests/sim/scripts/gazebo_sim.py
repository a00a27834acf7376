"""A simulation process for the gazebo services tests: TurtleBot3 burger ``tb3`` in the
empty world at (0.5, 0), world odometry, real time, on the default (Zenoh) transport.

Prints ``ready`` once built; runs until killed or argv[1] seconds of sim time (default 60).
"""

from __future__ import annotations

import sys
from pathlib import Path

from visnav.graph import Context
from visnav.sim.simulator import RobotSpawn, Simulator

TB3 = Path(__file__).resolve().parents[2] / "data" / "turtlebot3" / "turtlebot3_description"
duration = float(sys.argv[1]) if len(sys.argv) > 1 else 60.0

with Context() as ctx:
    robot = RobotSpawn(
        source=TB3 / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": TB3},
        spawn=(0.5, 0.0, 0.0, 0.0),
        name="tb3",
    )
    with Simulator("empty", [robot], context=ctx, realtime=True) as sim:
        print("ready", flush=True)
        sim.run(duration)
