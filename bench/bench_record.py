"""Recording under load (issue 13): does ``visnav bag record -a`` lose anything?

Run: ``python bench/bench_record.py [SECONDS]`` (default 8 s per configuration;
``BENCH_REPEATS=N``, ``BENCH_CONFIGS=mcap/none,ros1/bz2`` to choose).

A publisher process sends, for SECONDS: 640x480 rgb8 images at 30 Hz (random pixels, so
incompressible: the worst case for the compressors), a 100 Hz small topic (``/fast``,
``std_msgs/String``) and ``/clock`` at 500 Hz (the simulator publishes it every physics
step), all keep-last 10 as the simulator's publishers are. ``visnav bag record -a`` runs
in a third process (the CLI, across Zenoh), once per format/compression, and is stopped
with SIGINT. The reference is what the publisher sent (counted by sequence numbers in the
payloads): the figure is recorded / sent per topic (target 1.00, 0 drops, for none, lz4 and
zstd), and the drops the recorder reported (``bag record`` prints them, ``bag info`` reads
them from the bag). Repeated REPEATS times; medians are printed.

``python bench/bench_record.py --callback`` measures instead the recorder callback's data path
per message in one process (thread CPU time, so other load matters little): a raw subscription's
``SerializedMessage.to_bytes()`` (what the recorder does) against deserializing the remote CDR
and serializing it again (what it did before), for a 640x480 rgb8 Image and a Clock.

With ``BENCH_BEFORE_SRC=DIR`` (a ``src`` tree of an older visnav, e.g. from
``git archive <commit> src | tar -x -C /tmp/old``), each configuration is also recorded by
that version's ``bag record`` in the same run (interleaved), as the before/after reference.
"""

from __future__ import annotations

import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REPEATS = int(os.environ.get("BENCH_REPEATS", "3"))
CONFIGS = (
    ("mcap", "none"),
    ("mcap", "lz4"),
    ("mcap", "zstd"),
    ("ros1", "none"),
    ("ros1", "lz4"),
    ("ros1", "bz2"),
)
RATES = {"/image": 30.0, "/fast": 100.0, "/clock": 500.0}


def publish(seconds: float) -> None:
    """The publisher process: wait for the recorder, publish, print the counts sent."""
    from visnav.graph import Context, Node
    from visnav.msgs import Header, Image, String, make, ns_to_time
    from visnav.msgs.serde import get_message_class

    clock_cls = get_message_class("rosgraph_msgs/msg/Clock")
    rng = np.random.default_rng(0)
    pixels = [rng.integers(0, 256, 640 * 480 * 3, dtype=np.uint8) for _ in range(4)]
    with Context() as ctx:
        node = Node("load", context=ctx)
        pubs: dict[str, Any] = {
            "/image": node.create_publisher(Image, "/image", 10),
            "/fast": node.create_publisher(String, "/fast", 10),
            "/clock": node.create_publisher(clock_cls, "/clock", 10),
        }
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and any(
            p.get_subscription_count() == 0 for p in pubs.values()
        ):
            time.sleep(0.02)
        time.sleep(0.5)  # the recorder subscribes to each topic as it appears
        sent = dict.fromkeys(RATES, 0)
        t0 = time.monotonic()
        due = dict.fromkeys(RATES, t0)
        while True:
            now = time.monotonic()
            if now - t0 >= seconds:
                break
            topic = min(due, key=lambda k: due[k])
            if due[topic] > now:
                time.sleep(due[topic] - now)
            i = sent[topic]
            stamp = ns_to_time(i)
            if topic == "/image":
                msg: Any = make(
                    Image,
                    header=Header(stamp=stamp, frame_id="camera"),
                    height=480,
                    width=640,
                    encoding="rgb8",
                    step=640 * 3,
                    data=pixels[i % 4],
                )
            elif topic == "/fast":
                msg = String(data=str(i))
            else:
                msg = make(clock_cls, clock=stamp)
            pubs[topic].publish(msg)
            sent[topic] += 1
            due[topic] += 1.0 / RATES[topic]
        time.sleep(1.0)
        print(" ".join(f"{k}={v}" for k, v in sent.items()), flush=True)


def run_once(
    tmp: Path, fmt: str, compression: str, seconds: float, domain: int, src: str | None = None
) -> dict[str, Any]:
    from visnav.bag import bag_info

    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    rec_env = env if src is None else {**env, "PYTHONPATH": src}
    out = tmp / (f"rec_{fmt}_{compression}.bag" if fmt == "ros1" else f"rec_{fmt}_{compression}")
    rec = subprocess.Popen(
        [
            *(sys.executable, "-m", "visnav.cli.main", "bag", "record", "-a", "-o", str(out)),
            *("--format", fmt, "--compression", compression),
        ],
        env=rec_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert rec.stdout is not None
    rec.stdout.readline()
    pub = subprocess.run(
        [sys.executable, __file__, "--publish", str(seconds)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    sent = {k: int(v) for k, v in (kv.split("=") for kv in pub.stdout.split())}
    t_stop = time.monotonic()
    rec.send_signal(signal.SIGINT)
    _, err = rec.communicate(timeout=900)
    stop_s = time.monotonic() - t_stop
    info = bag_info(out)
    recorded = {t.name: t.count for t in info.topics}
    warn = [line for line in err.splitlines() if "dropped" in line]
    size = info.size_bytes
    if out.is_dir():
        for f in out.iterdir():
            f.unlink()
        out.rmdir()
    else:
        out.unlink()
    return {
        "sent": sent,
        "recorded": recorded,
        "drops": info.drops,
        "stop_s": stop_s,
        "warn": warn,
        "mb": size / 1e6,
    }


def main(seconds: float) -> None:
    print(f"recording {seconds:.0f} s of 640x480 rgb8 @ 30 Hz + /fast @ 100 Hz + /clock @ 500 Hz")
    with tempfile.TemporaryDirectory(prefix="bench_record_") as d:
        tmp = Path(d)
        before = os.environ.get("BENCH_BEFORE_SRC")
        only = os.environ.get("BENCH_CONFIGS")  # e.g. "mcap/none,ros1/bz2"
        configs = [c for c in CONFIGS if not only or "/".join(c) in only.split(",")]
        for n, (fmt, comp) in enumerate(configs):
            runs, old = [], []
            for r in range(REPEATS):  # interleaved: both see the same machine load
                domain = 700_000 + os.getpid() % 50_000 * 10 + n * 3 + r
                runs.append(run_once(tmp, fmt, comp, seconds, domain))
                if before:
                    old.append(run_once(tmp, fmt, comp, seconds, domain + 500_000, before))
            if old:
                _print(f"{fmt:4s}/{comp:4s} BEFORE", old)
            _print(f"{fmt:4s}/{comp:4s}", runs)


def _print(label: str, runs: list[dict[str, Any]]) -> None:
    parts = []
    for topic in RATES:
        ratio = statistics.median(
            r["recorded"].get(topic, 0) / max(r["sent"][topic], 1) for r in runs
        )
        lost = statistics.median(r["sent"][topic] - r["recorded"].get(topic, 0) for r in runs)
        reported = statistics.median(r["drops"].get(topic, 0) for r in runs)
        parts.append(f"{topic} {ratio:.3f} (lost {lost:.0f}, reported {reported:.0f})")
    stop = statistics.median(r["stop_s"] for r in runs)
    mb = statistics.median(r["mb"] for r in runs)
    sent = "/".join(str(statistics.median(r["sent"][t] for r in runs)) for t in RATES)
    print(
        f"{label}: sent {sent}; recorded/sent " + ", ".join(parts) + f"; bag {mb:.0f} MB; "
        f"stop+close {stop:.1f} s (target 1.000, 0 lost for none/lz4/zstd)",
        flush=True,
    )


def callback_cost(repeats: int = 7, n: int = 200) -> None:
    """Per-message CPU cost of the recorder callback's data path: raw vs decode + encode."""
    import zenoh

    from visnav.graph.subscription import SerializedMessage
    from visnav.msgs import Header, Image, make, ns_to_time, serialize
    from visnav.msgs.serde import CdrSerializer, deserialize, get_message_class

    clock_cls = get_message_class("rosgraph_msgs/msg/Clock")
    pixels = np.random.default_rng(0).integers(0, 256, 640 * 480 * 3, dtype=np.uint8)
    image = make(
        Image,
        header=Header(stamp=ns_to_time(1), frame_id="camera"),
        height=480,
        width=640,
        encoding="rgb8",
        step=640 * 3,
        data=pixels,
    )
    samples = {
        "sensor_msgs/msg/Image": bytes(serialize(image)),
        "rosgraph_msgs/msg/Clock": bytes(serialize(make(clock_cls, clock=ns_to_time(7)))),
    }
    print(f"recorder callback data path, per message (thread CPU time, median of {repeats})")
    for type_name, cdr in samples.items():
        enc = CdrSerializer(type_name)

        payload = zenoh.ZBytes(cdr)  # what a remote sample hands the subscription

        def before(payload: Any = payload, type_name: str = type_name, enc: Any = enc) -> bytes:
            msg = deserialize(memoryview(payload.to_bytes()), type_name)  # as _run_remote
            return bytes(enc.serialize(msg))

        def now(payload: Any = payload, type_name: str = type_name) -> bytes:
            return SerializedMessage(payload, type_name).to_bytes()

        assert before() == now() == cdr
        figures = {}
        for label, fn in (("raw", now), ("decode+encode", before)):
            runs = []
            for _ in range(repeats):
                t0 = time.thread_time()
                for _ in range(n):
                    fn()
                runs.append((time.thread_time() - t0) / n * 1e6)
            figures[label] = statistics.median(runs)
        ratio = figures["raw"] / figures["decode+encode"]
        print(
            f"  {type_name} ({len(cdr)} B): raw {figures['raw']:.1f} us, decode+encode "
            f"(reference) {figures['decode+encode']:.1f} us, ratio {ratio:.2f}",
            flush=True,
        )


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--callback":
        callback_cost()
    elif len(sys.argv) > 2 and sys.argv[1] == "--publish":
        publish(float(sys.argv[2]))
    else:
        main(float(sys.argv[1]) if len(sys.argv) > 1 else 8.0)
