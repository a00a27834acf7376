"""A subscriber process for the soak test: ``subscriber.py viewer|slow SECONDS``.

``viewer`` subscribes what a viewer shows (camera image decoded to numpy, depth cloud, TF,
odometry, clock); ``slow`` takes the camera image with a 300 ms callback (keep-last 2, so
QoS lets it drop images). Every 10 s and at the end it prints one JSON line: its RSS and,
per topic, messages received, dropped by its keep-last queue, and missing (gaps in the
publishers' sequence numbers that are not waiting in the queue).
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from visnav.graph import Context, MessageInfo, Node
from visnav.msgs import Clock, Image, Odometry, PointCloud2, TFMessage
from visnav.msgs.image import image_to_numpy


def rss_bytes() -> int:
    return int(Path("/proc/self/statm").read_text().split()[1]) * 4096


class Counter:
    """Received messages and sequence gaps per publisher of one topic."""

    def __init__(self) -> None:
        self.received = 0
        self.gaps = 0
        self.last: dict[tuple[str, int], int] = {}

    def see(self, info: MessageInfo) -> None:
        self.received += 1
        key = (info.publisher_zid, info.publisher_entity_id)
        seq = info.publication_sequence_number
        prev = self.last.get(key)
        if prev is not None and seq > prev + 1:
            self.gaps += seq - prev - 1
        self.last[key] = seq


def main() -> None:
    mode, seconds = sys.argv[1], float(sys.argv[2])
    counters: dict[str, tuple[Counter, Any]] = {}
    with Context() as ctx:
        node = Node(f"soak_{mode}", context=ctx)

        def subscribe(msg_type: Any, topic: str, depth: int, work: Callable[[Any], None]) -> None:
            counter = Counter()

            def callback(msg: Any, info: MessageInfo) -> None:
                counter.see(info)
                work(msg)

            counters[topic] = (counter, node.create_subscription(msg_type, topic, callback, depth))

        if mode == "viewer":
            subscribe(Image, "/camera/image_raw", 5, lambda m: image_to_numpy(m).mean())
            subscribe(PointCloud2, "/depth_camera/points", 2, lambda m: None)
            subscribe(TFMessage, "/tf", 100, lambda m: None)
            subscribe(Odometry, "/odom", 50, lambda m: None)
            subscribe(Clock, "/clock", 100, lambda m: None)
        else:
            subscribe(Image, "/camera/image_raw", 2, lambda m: time.sleep(0.3))
        print("ready", flush=True)

        def lost(counter: Counter, sub: Any) -> int:
            """Gaps so far, with the ones behind the last received message: what is neither
            received nor waiting in the queue (a queue drops only when full, so a drop after
            the last received message leaves its newer messages pending)."""
            seqs: dict[tuple[str, int], list[int]] = {}
            for _, info, _ in sub.queue:
                key = (info.publisher_zid, info.publisher_entity_id)
                seqs.setdefault(key, []).append(info.publication_sequence_number)
            tail = 0
            for key, pending in seqs.items():
                last = counter.last.get(key)
                if last is not None:
                    tail += max(pending) - last - len(pending)
            return counter.gaps + tail

        def report(final: bool = False) -> None:
            with ctx._lock:  # a consistent view of queues and drop counts
                topics = {
                    t: {"received": c.received, "gaps": lost(c, s), "dropped": s.dropped}
                    for t, (c, s) in counters.items()
                }
            elapsed = time.monotonic() - start
            line = {"elapsed": elapsed, "rss": rss_bytes(), "final": final, "topics": topics}
            print(json.dumps(line), flush=True)

        start = time.monotonic()
        end = start + seconds
        next_report = start + 10.0
        while time.monotonic() < end:
            ctx.spin_once(0.1)
            if time.monotonic() >= next_report:
                next_report += 10.0
                report()
        report(final=True)


if __name__ == "__main__":
    main()
