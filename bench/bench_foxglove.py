"""Throughput and latency of an image topic through the Foxglove server vs a raw graph subscription.

One run, three processes in a private graph domain (Zenoh, as a live robot would be):

* a publisher process sends 640x480 rgb8 ``sensor_msgs/Image`` (921,600-byte payload) on
  ``/camera/image_raw``, stamping ``header.stamp`` with the wall clock just before publishing;
* this process serves the graph with :class:`~visnav.bridge.foxglove.FoxgloveServer` AND
  holds the reference: a raw (``raw=True``) graph subscription to the same topic;
* a client process connects with the Foxglove protocol (``foxglove.websocket.v1``, Python
  ``websockets``), subscribes and reads the header stamp out of each CDR payload.

Latency = receive wall time - header stamp (same machine clock). Two phases: ``paced`` (30 Hz,
a camera's rate: latency) and ``flood`` (as fast as the publisher can: throughput). Each phase
is repeated; medians are printed with the ratio server / raw.

Run: ``python bench/bench_foxglove.py [--repeats 3] [--seconds 4]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import struct
import subprocess
import sys
import threading
import time
from typing import Any

import numpy as np

_STAMP = struct.Struct("<iI")  # header.stamp sec, nanosec after the 4-byte CDR header


def _stamp_ns(cdr: bytes | memoryview) -> int:
    sec, nsec = _STAMP.unpack_from(cdr, 4)
    return int(sec) * 1_000_000_000 + int(nsec)


def publisher(rate_hz: float, seconds: float) -> None:
    """Publish images (run in a child process)."""
    from visnav.graph import Context, Node
    from visnav.msgs.image import numpy_to_image
    from visnav.msgs.time import ns_to_time

    with Context() as ctx:
        node = Node("bench_camera", context=ctx)
        msg = numpy_to_image(np.zeros((480, 640, 3), np.uint8), "rgb8")
        pub = node.create_publisher(type(msg), "/camera/image_raw", 10)
        print("ready", flush=True)
        sys.stdin.readline()  # go
        end = time.monotonic() + seconds
        period = 1.0 / rate_hz if rate_hz > 0 else 0.0
        next_t = time.monotonic()
        sent = 0
        while time.monotonic() < end:
            msg.header.stamp = ns_to_time(time.time_ns())
            pub.publish(msg)
            sent += 1
            if period:
                next_t += period
                time.sleep(max(0.0, next_t - time.monotonic()))
        print(json.dumps({"sent": sent}), flush=True)
        time.sleep(0.5)


def ws_client(url: str, seconds: float) -> None:
    """Subscribe through the Foxglove server and report latencies (run in a child process)."""
    from websockets.asyncio.client import connect

    async def go() -> dict[str, Any]:
        lat: list[float] = []
        count = 0
        async with connect(url, subprotocols=["foxglove.websocket.v1"], max_size=None) as ws:  # type: ignore[list-item]
            cid = None
            while cid is None:
                msg = json.loads(await ws.recv())
                if msg.get("op") == "advertise":
                    for ch in msg["channels"]:
                        if ch["topic"] == "/camera/image_raw":
                            cid = ch["id"]
            sub = {"op": "subscribe", "subscriptions": [{"id": 1, "channelId": cid}]}
            await ws.send(json.dumps(sub))
            print("ready", flush=True)
            end = None
            while True:
                timeout = 5.0 if end is None else max(0.01, end - time.monotonic())
                try:
                    frame = await asyncio.wait_for(ws.recv(), timeout)
                except TimeoutError:
                    break
                if not isinstance(frame, bytes) or frame[0] != 1:
                    continue
                now = time.time_ns()
                if end is None:
                    end = time.monotonic() + seconds + 1.0
                count += 1
                lat.append((now - _stamp_ns(memoryview(frame)[13:])) / 1e6)
        return {"count": count, "latency_ms": lat}

    print(json.dumps(asyncio.run(go())), flush=True)


def _spawn(*args: str, env: dict[str, str]) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, __file__, *args],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline().strip()
    if line != "ready":
        msg = f"{args[0]} did not start: {line!r}"
        raise RuntimeError(msg)
    return proc


def _phase(
    server_url: str, rate_hz: float, seconds: float, env: dict[str, str], raw: Any
) -> dict[str, Any]:
    pub = _spawn("--role", "publisher", "--rate", str(rate_hz), "--seconds", str(seconds), env=env)
    time.sleep(1.0)  # discovery
    client = _spawn("--role", "client", "--url", server_url, "--seconds", str(seconds), env=env)
    time.sleep(0.5)
    raw.reset()
    assert pub.stdin is not None
    assert pub.stdout is not None
    assert client.stdout is not None
    pub.stdin.write("go\n")
    pub.stdin.flush()
    sent = json.loads(pub.stdout.readline())["sent"]
    out = json.loads(client.stdout.readline())
    pub.wait(timeout=10)
    client.wait(timeout=10)
    time.sleep(0.3)
    return {
        "sent": sent,
        "raw_count": raw.count,
        "raw_latency_ms": list(raw.latency_ms),
        "fg_count": out["count"],
        "fg_latency_ms": out["latency_ms"],
    }


class _RawProbe:
    def __init__(self) -> None:
        self.count = 0
        self.latency_ms: list[float] = []
        self._lock = threading.Lock()

    def reset(self) -> None:
        with self._lock:
            self.count = 0
            self.latency_ms = []

    def __call__(self, msg: Any) -> None:
        now = time.time_ns()
        data = msg.to_bytes()
        with self._lock:
            self.count += 1
            self.latency_ms.append((now - _stamp_ns(data)) / 1e6)


def main() -> None:
    """Run the benchmark and print its table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--role", default="main", choices=["main", "publisher", "client"])
    parser.add_argument("--rate", type=float, default=0.0)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--url", default="")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    if args.role == "publisher":
        publisher(args.rate, args.seconds)
        return
    if args.role == "client":
        ws_client(args.url, args.seconds)
        return

    from visnav.bridge.foxglove import FoxgloveOptions, FoxgloveServer
    from visnav.graph import Context, Node
    from visnav.msgs.serde import get_message_class

    domain = str(700_000 + os.getpid() % 10_000)
    env = {**os.environ, "VISNAV_DOMAIN": domain}
    os.environ["VISNAV_DOMAIN"] = domain
    image_cls = get_message_class("sensor_msgs/msg/Image")
    probe = _RawProbe()
    with Context() as ctx:
        node = Node("bench_foxglove", context=ctx)
        node.create_subscription(image_cls, "/camera/image_raw", probe, 10, raw=True)
        server = FoxgloveServer(node, FoxgloveOptions(port=0))
        server.start()
        stop = threading.Event()

        def spin() -> None:
            while not stop.is_set():
                ctx.spin_once(0.05)

        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        try:
            results: dict[str, list[dict[str, Any]]] = {"paced 30 Hz": [], "flood": []}
            for _ in range(args.repeats):
                results["paced 30 Hz"].append(_phase(server.url, 30.0, args.seconds, env, probe))
                results["flood"].append(_phase(server.url, 0.0, args.seconds, env, probe))
        finally:
            stop.set()
            spinner.join()
            server.close()
    _report(results, args.seconds)


def _median(values: list[float]) -> float:
    return statistics.median(values) if values else float("nan")


def _report(results: dict[str, list[dict[str, Any]]], seconds: float) -> None:
    print("640x480 rgb8 Image (921,600 B) over Zenoh from another process; medians of runs")
    print(
        f"{'phase':<12} {'path':<18} {'msg/s':>8} {'MB/s':>8} {'lat p50 ms':>11} {'lat p95 ms':>11}"
    )
    for phase, runs in results.items():
        rows = {}
        for path, count_key, lat_key in (
            ("raw subscription", "raw_count", "raw_latency_ms"),
            ("Foxglove server", "fg_count", "fg_latency_ms"),
        ):
            rate = _median([r[count_key] / seconds for r in runs])
            p50 = _median([_median(r[lat_key]) for r in runs])
            p95 = _median(
                [float(np.percentile(r[lat_key], 95)) if r[lat_key] else float("nan") for r in runs]
            )
            rows[path] = (rate, p50, p95)
            print(
                f"{phase:<12} {path:<18} {rate:8.1f} {rate * 0.9216:8.1f} {p50:11.2f} {p95:11.2f}"
            )
        sent = _median([r["sent"] / seconds for r in runs])
        ratio = (
            rows["Foxglove server"][0] / rows["raw subscription"][0]
            if rows["raw subscription"][0]
            else float("nan")
        )
        print(f"{phase:<12} {'(published)':<18} {sent:8.1f}   server/raw rate ratio {ratio:.2f}")


if __name__ == "__main__":
    main()
