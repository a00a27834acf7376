"""Graph benchmarks (issue 2): in-process latency, cross-process throughput, topic hz accuracy.

Run: ``python bench/bench_graph.py`` (``--flood-only``: only the flood figure). Prints
medians of repeated runs and, for the cross-process case, the ratio to raw Zenoh
put/subscribe of the same bytes measured in the same run. Each run uses its own private
domain. The flood figure: a publisher with no pause against a keep-last(2) subscription
whose callback burns 2 ms of CPU, default subscription (the reference) against a paced one
(``paced=True``), interleaved.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from typing import Any

import numpy as np

N_CROSS = 3000
PAYLOAD = 640 * 480 * 3
REPEATS = 5


def _image() -> Any:
    from visnav.msgs import Header, Image, make, ns_to_time

    return make(
        Image,
        header=Header(stamp=ns_to_time(0), frame_id="camera"),
        height=480,
        width=640,
        encoding="rgb8",
        step=640 * 3,
        data=np.zeros(PAYLOAD, np.uint8),
    )


def bench_in_process(n: int = 20000) -> dict[str, float]:
    """Median publish -> callback latency of a 640x480 rgb8 Image in one context."""
    from visnav.graph import Context, Node
    from visnav.msgs import Image

    lat: list[int] = []
    with Context(transport="local") as ctx:
        node = Node("bench", context=ctx)
        pub = node.create_publisher(Image, "/image", 10)
        t_pub = [0]
        node.create_subscription(
            Image, "/image", lambda m: lat.append(time.perf_counter_ns() - t_pub[0]), 10
        )
        img = _image()
        for _ in range(n):
            t_pub[0] = time.perf_counter_ns()
            pub.publish(img)
            ctx.spin_once(0)
    lat_us = np.array(lat[100:]) / 1000
    return {"median_us": float(np.median(lat_us)), "p95_us": float(np.percentile(lat_us, 95))}


def _sender(mode: str, domain: int, n: int) -> None:
    """Subprocess role: wait for a subscriber, then send n payloads as fast as possible."""
    if mode in ("zenoh", "zenoh-shm"):
        import zenoh
        from zenoh import shm

        from visnav.graph.transport import TransportConfig

        conf = TransportConfig.from_env(domain).zenoh_config()
        session = zenoh.open(zenoh.Config.from_json5(json.dumps(conf)))
        pub = session.declare_publisher(
            "bench/raw", congestion_control=zenoh.CongestionControl.DROP
        )
        while not pub.matching_status.matching:
            time.sleep(0.01)
        time.sleep(0.3)
        payload = b"\x00" * (PAYLOAD + 60)
        provider = shm.ShmProvider.default_backend(64 * 1024 * 1024)
        for _ in range(n):
            if mode == "zenoh-shm":
                buf = provider.alloc(len(payload), policy=shm.BlockOn(shm.GarbageCollect()))
                buf[:] = payload
                pub.put(buf)
            else:
                pub.put(payload)
        time.sleep(1.0)
        session.close()
        return
    from visnav.graph import Context, Node
    from visnav.msgs import Image

    with Context(domain) as ctx:
        node = Node("sender", context=ctx)
        p = node.create_publisher(Image, "/image", 10)
        p._zpub._pub.congestion_control  # noqa: B018 - ensure declared
        while p.get_subscription_count() < 1:
            ctx.spin_once(0.01)
        while not p._zpub.has_subscribers:
            time.sleep(0.01)
        time.sleep(0.3)
        img = _image()
        for _ in range(n):
            p.publish(img)
        time.sleep(1.0)


def _receive(mode: str, domain: int, n: int) -> float:
    """Start a sender process and return the received message rate (msg/s)."""
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    times: list[float] = []
    if mode in ("zenoh", "zenoh-shm"):
        import zenoh

        from visnav.graph.transport import TransportConfig

        conf = TransportConfig.from_env(domain).zenoh_config()
        session = zenoh.open(zenoh.Config.from_json5(json.dumps(conf)))
        sub = session.declare_subscriber(
            "bench/raw", lambda s: (s.payload.to_bytes(), times.append(time.perf_counter()))
        )
        proc = subprocess.Popen(
            [sys.executable, __file__, "--sender", mode, str(domain), str(n)], env=env
        )
        deadline = time.monotonic() + 60
        while len(times) < n and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.01)
        proc.wait(timeout=30)
        sub.undeclare()
        session.close()
    else:
        from visnav.graph import Context, Node
        from visnav.msgs import Image

        with Context(domain) as ctx:
            node = Node("receiver", context=ctx)
            node.create_subscription(
                Image, "/image", lambda m: times.append(time.perf_counter()), 100
            )
            proc = subprocess.Popen(
                [sys.executable, __file__, "--sender", mode, str(domain), str(n)], env=env
            )
            deadline = time.monotonic() + 60
            while len(times) < n and time.monotonic() < deadline and proc.poll() is None:
                ctx.spin_once(0.01)
            ctx.spin_some()
            proc.wait(timeout=30)
    if len(times) < 10:
        return 0.0
    return (len(times) - 1) / (times[-1] - times[0])


def bench_cross_process() -> dict[str, Any]:
    base = 3_000_000 + (os.getpid() % 1000) * 100
    raw, raw_shm, ours = [], [], []
    for r in range(REPEATS):  # interleaved, so machine noise hits all three alike
        raw.append(_receive("zenoh", base + 3 * r, N_CROSS))
        raw_shm.append(_receive("zenoh-shm", base + 3 * r + 1, N_CROSS))
        ours.append(_receive("visnav", base + 3 * r + 2, N_CROSS))
    return {
        "zenoh_msgs_per_s": statistics.median(raw),
        "zenoh_shm_msgs_per_s": statistics.median(raw_shm),
        "visnav_msgs_per_s": statistics.median(ours),
        "ratio": statistics.median(ours) / statistics.median(raw),
        "ratio_shm": statistics.median(ours) / statistics.median(raw_shm),
        "runs_zenoh": [round(x) for x in raw],
        "runs_zenoh_shm": [round(x) for x in raw_shm],
        "runs_visnav": [round(x) for x in ours],
    }


FLOOD_CALLBACK_S = 0.002
"""CPU time each callback of the flood benchmark's subscriber burns (a consumer slower than the flood)."""


def _flood_sender(domain: int, seconds: float) -> None:
    """Subprocess role: publish 921,600-byte Images with no pause for ``seconds``."""
    from visnav.graph import Context, Node
    from visnav.msgs import Image

    with Context(domain) as ctx:
        node = Node("flooder", context=ctx)
        p = node.create_publisher(Image, "/flood", 2)
        img = _image()
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            p.publish(img)


def _flood_receive(mode: str, domain: int, seconds: float = 4.0) -> dict[str, float]:
    """Receive a flood with a keep-last(2) subscription whose callback is slow.

    Returns callbacks per second, the receiving process's CPU (cores: all its threads,
    Zenoh's included) and that CPU less the callbacks' own work, over ``seconds`` after a
    1 s warm-up.
    """
    from visnav.graph import Context, Node
    from visnav.msgs import Image

    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    count = [0]

    def callback(_msg: Any) -> None:
        count[0] += 1
        end = time.thread_time() + FLOOD_CALLBACK_S
        while time.thread_time() < end:
            pass

    with Context(domain) as ctx:
        node = Node("receiver", context=ctx)
        kwargs = {"paced": True} if mode == "paced" else {}
        node.create_subscription(Image, "/flood", callback, 2, **kwargs)
        proc = subprocess.Popen(
            [sys.executable, __file__, "--flood-sender", str(domain), str(seconds + 12)], env=env
        )
        deadline = time.monotonic() + 10
        while count[0] == 0 and time.monotonic() < deadline:
            ctx.spin_once(0.05)
        warm = time.monotonic() + 1.0
        while time.monotonic() < warm:
            ctx.spin_once(0.05)
        count[0] = 0
        t0, c0 = time.monotonic(), time.process_time()
        while time.monotonic() - t0 < seconds:
            ctx.spin_once(0.05)
        t1, c1 = time.monotonic(), time.process_time()
        n = count[0]
        proc.kill()
        proc.wait(timeout=30)
    cores = (c1 - c0) / (t1 - t0)
    rate = n / (t1 - t0)
    return {"rate": rate, "cores": cores, "overhead": cores - rate * FLOOD_CALLBACK_S}


def bench_flood(repeats: int = 3) -> dict[str, Any]:
    """Default vs paced keep-last subscription under a flood, interleaved repeats."""
    base = 5_000_000 + (os.getpid() % 1000) * 100
    runs: dict[str, list[dict[str, float]]] = {"default": [], "paced": []}
    for r in range(repeats):
        for k, mode in enumerate(runs):
            try:
                runs[mode].append(_flood_receive(mode, base + 2 * r + k))
            except TypeError:  # a visnav without paced subscriptions (a "before" run)
                runs[mode].append(dict.fromkeys(("rate", "cores", "overhead"), float("nan")))
    med = statistics.median
    return {
        mode: {key: med(run[key] for run in rs) for key in ("rate", "cores", "overhead")}
        for mode, rs in runs.items()
    }


def _hz_publisher(domain: int, seconds: float) -> None:
    from visnav.graph import Context, Node
    from visnav.msgs import String

    with Context(domain) as ctx:
        node = Node("pub30", context=ctx)
        p = node.create_publisher(String, "/hz", 10)
        node.create_timer(1 / 30, lambda: p.publish(String(data="x")))
        ctx.spin(duration_s=seconds)


def bench_topic_hz() -> dict[str, Any]:
    """Run ``visnav topic hz`` against a 30 Hz publisher in another process."""
    domain = 4_000_000 + os.getpid() % 1000
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    pub = subprocess.Popen([sys.executable, __file__, "--hz-publisher", str(domain), "14"], env=env)
    time.sleep(1.0)
    out = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "topic", "hz", "/hz", "--duration", "11"],
        env=env,
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    pub.wait(timeout=30)
    rates = [float(line.split()[-1]) for line in out.stdout.splitlines() if "average rate" in line]
    final = rates[-1] if rates else float("nan")
    return {"measured_hz": final, "true_hz": 30.0, "error_pct": abs(final - 30.0) / 30.0 * 100}


def _print_flood(r: dict[str, Any]) -> None:
    d, p = r["default"], r["paced"]

    def per_cb(x: dict[str, float]) -> float:
        return x["overhead"] / x["rate"] * 1e3 if x["rate"] else float("nan")

    print(
        f"flood of 921,600-byte Images into keep-last(2) with a {FLOOD_CALLBACK_S * 1e3:.0f} ms "
        f"callback: default {d['rate']:.0f} callbacks/s, receiver {d['cores']:.2f} cores, "
        f"{per_cb(d):.2f} ms CPU per callback besides its own; paced {p['rate']:.0f} "
        f"callbacks/s, {p['cores']:.2f} cores, {per_cb(p):.2f} ms; ratio paced/default: "
        f"callbacks/s {p['rate'] / d['rate']:.2f}, CPU per callback {per_cb(p) / per_cb(d):.2f}"
    )


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--sender":
        _sender(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
        return
    if len(sys.argv) > 1 and sys.argv[1] == "--hz-publisher":
        _hz_publisher(int(sys.argv[2]), float(sys.argv[3]))
        return
    if len(sys.argv) > 1 and sys.argv[1] == "--flood-sender":
        _flood_sender(int(sys.argv[2]), float(sys.argv[3]))
        return
    if len(sys.argv) > 1 and sys.argv[1] == "--flood-only":
        _print_flood(bench_flood())
        return
    r1 = bench_in_process()
    print(
        f"in-process publish->callback, 640x480 rgb8 Image: median {r1['median_us']:.2f} us "
        f"(p95 {r1['p95_us']:.2f} us)  [target <= 20 us]"
    )
    r2 = bench_cross_process()
    print(
        f"cross-process 921,600-byte Image: visnav {r2['visnav_msgs_per_s']:.0f} msg/s; raw zenoh put "
        f"{r2['zenoh_msgs_per_s']:.0f} msg/s (ratio {r2['ratio']:.2f}); raw zenoh shared-memory put "
        f"{r2['zenoh_shm_msgs_per_s']:.0f} msg/s (ratio {r2['ratio_shm']:.2f})  "
        "[targets >= 1000 msg/s, >= 0.7x]\n"
        f"  runs: visnav {r2['runs_visnav']} zenoh {r2['runs_zenoh']} zenoh-shm {r2['runs_zenoh_shm']}"
    )
    _print_flood(bench_flood())
    r3 = bench_topic_hz()
    print(
        f"topic hz on a 30 Hz publisher: {r3['measured_hz']:.3f} Hz, error {r3['error_pct']:.2f} %  "
        "[target <= 1 %]"
    )


if __name__ == "__main__":
    main()
