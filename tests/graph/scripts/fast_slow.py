"""A publisher process for the executor tests: /fast and /slow String topics.

Usage: ``fast_slow.py SECONDS FAST_HZ SLOW_HZ``. Prints ``ready`` once a subscriber
of /slow is matched, then publishes both topics (keep-all, reliable: nothing is
dropped on the sending side) until SECONDS have passed.
"""

from __future__ import annotations

import sys
import time

from visnav.graph import Context, HistoryPolicy, Node, QoSProfile
from visnav.msgs import String

seconds, fast_hz, slow_hz = (float(a) for a in sys.argv[1:4])
qos = QoSProfile(depth=100, history=HistoryPolicy.KEEP_ALL)
with Context() as ctx:
    node = Node("fast_slow", context=ctx)
    fast = node.create_publisher(String, "/fast", qos)
    slow = node.create_publisher(String, "/slow", qos)
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline and not (
        slow.get_subscription_count() and fast.get_subscription_count()
    ):
        ctx.spin_once(0.02)
    print("ready", flush=True)
    node.create_timer(1.0 / fast_hz, lambda: fast.publish(String(data="f")))
    node.create_timer(1.0 / slow_hz, lambda: slow.publish(String(data="s")))
    ctx.spin(duration_s=seconds)
