"""A /clock publisher process for cross-process clock tests (runs until killed or argv[1] s).

Publishes rosgraph_msgs/Clock at 100 Hz (wall), sim time 1000 s + 10 ms per tick, with the
simulator's QoS (reliable, keep-last 1, as ``visnav sim``).
"""

from __future__ import annotations

import sys

from visnav.graph import Context, Node, QoSProfile
from visnav.msgs import Clock, ns_to_time

duration = float(sys.argv[1]) if len(sys.argv) > 1 else 30.0
with Context() as ctx:
    node = Node("clock_pub", context=ctx)
    pub = node.create_publisher(Clock, "/clock", QoSProfile(depth=1))
    tick = [0]

    def step() -> None:
        tick[0] += 1
        pub.publish(Clock(clock=ns_to_time(1_000_000_000_000 + tick[0] * 10_000_000)))

    node.create_timer(0.01, step)
    print("ready", flush=True)
    ctx.spin(duration_s=duration)
