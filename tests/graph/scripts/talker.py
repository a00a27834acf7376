"""A talker process for cross-process tests: publishes until killed or for argv[1] seconds.

Publishes /chatter (String, 50 Hz), /image (Image 8x6 rgb8, 20 Hz) and a latched
/latched (String, transient local) once at start.
"""

from __future__ import annotations

import sys

import numpy as np

from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import Header, Image, String, make, ns_to_time

duration = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
with Context() as ctx:
    node = Node("talker", namespace="/robot", context=ctx)
    chatter = node.create_publisher(String, "chatter", 10)
    image = node.create_publisher(Image, "/image", 5)
    latched = node.create_publisher(String, "/latched", qos_profile_latched)
    latched.publish(String(data="latched-hello"))
    count = [0]

    def tick() -> None:
        count[0] += 1
        chatter.publish(String(data=f"hello {count[0]}"))

    def tick_image() -> None:
        now = node.get_clock().now_ns()
        data = np.arange(8 * 6 * 3, dtype=np.uint8)
        image.publish(
            make(
                Image,
                header=Header(stamp=ns_to_time(now), frame_id="camera_optical_frame"),
                height=6,
                width=8,
                encoding="rgb8",
                step=24,
                data=data,
            )
        )

    node.create_timer(0.02, tick)
    node.create_timer(0.05, tick_image)
    print("ready", flush=True)
    ctx.spin(duration_s=duration)
