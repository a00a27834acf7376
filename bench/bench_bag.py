"""Bag benchmarks (issue 5): recording throughput and playback timing.

Run: ``python bench/bench_bag.py`` (``--writer-only``: only the BagWriter figures, with and
without MCAP chunk CRCs; ``--play-only``: only playback). Prints medians of repeated runs.

* Recording: 640x480 rgb8 Images (random, so incompressible) published in-process and recorded by ``BagRecorder``
  (delivery, executor, CDR serialization, MCAP/ROS 1 writing, close), against the bare
  ``rosbags`` writer fed the same message objects (``serialize_cdr`` + ``Writer.write``) in
  the same run; plus the writers alone on pre-serialized bytes. Target: ratio >= 0.8.
* Playback: a 2 s bag (30 Hz images + 100 Hz strings) played at rate 1 by ``visnav bag play``
  in another process (and by ``BagPlayer`` in-process); the receive time of each message in
  a subscriber, relative to the first, minus the recorded offset. Target: median |error|
  <= 2 ms.
"""

from __future__ import annotations

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

N_IMAGES = 150
REPEATS = 7


def _images(k: int = 4) -> list[Any]:
    from visnav.msgs import Header, Image, make, ns_to_time

    rng = np.random.default_rng(0)
    return [
        make(
            Image,
            header=Header(stamp=ns_to_time(i), frame_id="camera"),
            height=480,
            width=640,
            encoding="rgb8",
            step=640 * 3,
            data=rng.integers(0, 256, 640 * 480 * 3, dtype=np.uint8),
        )
        for i in range(k)
    ]


def rec_visnav(tmp: Path, imgs: list[Any], fmt: str, compression: str) -> float:
    from visnav.bag import BagRecorder
    from visnav.graph import Context, Node
    from visnav.msgs import Image

    with Context(transport="local") as ctx:
        pub = Node("cam", context=ctx).create_publisher(Image, "/image", 10)
        rec = BagRecorder(ctx, ["/image"], tmp / "visnav", fmt=fmt, compression=compression)
        rec.start()
        t = time.perf_counter()
        for i in range(N_IMAGES):
            pub.publish(imgs[i % len(imgs)])
            ctx.spin_some()
        path = rec.stop()
        dt = time.perf_counter() - t
    assert rec.message_count == N_IMAGES, rec.message_count
    _rm(path)
    return N_IMAGES / dt


def rec_rosbags(tmp: Path, imgs: list[Any], fmt: str, compression: str) -> float:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    from visnav.bag.typeconv import ros1_definition
    from visnav.msgs.serde import typestore

    store = typestore()
    name = "sensor_msgs/msg/Image"
    t = time.perf_counter()
    if fmt == "mcap":
        path = tmp / "rosbags"
        w2 = Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP)
        if compression == "zstd":
            w2.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with w2:
            conn = w2.add_connection("/image", name, typestore=store)
            for i in range(N_IMAGES):
                msg = imgs[i % len(imgs)]
                w2.write(conn, time.time_ns(), store.serialize_cdr(msg, name))
    else:
        path = tmp / "rosbags.bag"
        w1 = Writer1(path)
        if compression == "lz4":
            w1.set_compression(Writer1.CompressionFormat.LZ4)
        msgdef, md5 = ros1_definition(name)
        with w1:
            conn = w1.add_connection("/image", name, msgdef=msgdef, md5sum=md5)
            for i in range(N_IMAGES):
                msg = imgs[i % len(imgs)]
                w1.write(
                    conn, time.time_ns(), store.cdr_to_ros1(store.serialize_cdr(msg, name), name)
                )
    dt = time.perf_counter() - t
    _rm(path)
    return N_IMAGES / dt


def writer_only(tmp: Path, raw: list[bytes], which: str) -> float:
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    from visnav.bag import BagWriter
    from visnav.msgs.serde import typestore

    name = "sensor_msgs/msg/Image"
    t = time.perf_counter()
    if which in ("visnav", "visnav-nocrc"):
        with BagWriter(tmp / "w", crc=which == "visnav") as w:
            h = w.add_topic("/image", name)
            for i in range(N_IMAGES):
                w.write(h, i, raw[i % len(raw)])
        path = w.path
    else:
        path = tmp / "w"
        with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as w2:
            conn = w2.add_connection("/image", name, typestore=typestore())
            for i in range(N_IMAGES):
                w2.write(conn, i, raw[i % len(raw)])
    dt = time.perf_counter() - t
    _rm(path)
    return N_IMAGES / dt


def _rm(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()


def bench_recording() -> None:
    from visnav.msgs import serialize

    imgs = _images()
    raw = [serialize(m) for m in imgs]
    with tempfile.TemporaryDirectory(prefix="bench_bag_") as d:
        tmp = Path(d)
        configs = (("mcap", "none"), ("mcap", "zstd"), ("ros1", "none"), ("ros1", "lz4"))
        if "--writer-only" in sys.argv:
            configs = ()
        # Warm up: throughput with 1 MB buffers depends on the allocator's state (glibc raises
        # its mmap threshold after large frees, then big buffers stop page-faulting), so both
        # sides run once first.
        for fmt, comp in configs:
            rec_visnav(tmp, imgs, fmt, comp)
            rec_rosbags(tmp, imgs, fmt, comp)
        for fmt, comp in configs:
            ours, ref = [], []
            for _ in range(REPEATS):  # interleaved, so both see the same machine load
                ours.append(rec_visnav(tmp, imgs, fmt, comp))
                ref.append(rec_rosbags(tmp, imgs, fmt, comp))
            mo, mr = statistics.median(ours), statistics.median(ref)
            print(
                f"record {fmt:4s}/{comp:4s} 640x480 rgb8: BagRecorder {mo:7.1f} img/s, "
                f"bare rosbags writer {mr:7.1f} img/s, ratio {mo / mr:.2f} (target >= 0.8)"
            )
        ours, nocrc, ref = [], [], []
        for _ in range(REPEATS):
            ours.append(writer_only(tmp, raw, "visnav"))
            nocrc.append(writer_only(tmp, raw, "visnav-nocrc"))
            ref.append(writer_only(tmp, raw, "rosbags"))
        mo, mn, mr = statistics.median(ours), statistics.median(nocrc), statistics.median(ref)
        print(
            f"writer only (pre-serialized, mcap/none): BagWriter (chunk CRCs) {mo:7.1f} img/s, "
            f"without CRCs {mn:7.1f} img/s (CRC cost ratio {mo / mn:.2f}), "
            f"rosbags Writer (no CRCs) {mr:7.1f} img/s, ratio {mo / mr:.2f}"
        )


def _timing_bag(path: Path) -> list[int]:
    """2 s: /image at 30 Hz (small images) and /chatter at 100 Hz; return the record times."""
    from visnav.bag import BagWriter
    from visnav.msgs import String, serialize

    img = serialize(_images(1)[0])
    t0 = 1_700_000_000_000_000_000
    events = [(t0 + round(i * 1e9 / 30), "/image") for i in range(60)]
    events += [(t0 + round(i * 1e9 / 100) + 3_000_000, "/chatter") for i in range(200)]
    events.sort()
    with BagWriter(path) as w:
        hi = w.add_topic("/image", "sensor_msgs/msg/Image")
        hc = w.add_topic("/chatter", "std_msgs/msg/String")
        for i, (t, topic) in enumerate(events):
            if topic == "/image":
                w.write(hi, t, img)
            else:
                w.write(hc, t, serialize(String(data=str(i))))
    return [t for t, _ in events]


def _timing_errors(recv: list[int], rec: list[int]) -> dict[str, float]:
    """Timing errors in ms: against the first message, after the best (median) alignment,
    and of consecutive intervals."""
    first = [abs((r - recv[0]) - (t - rec[0])) / 1e6 for r, t in zip(recv, rec, strict=True)]
    offset = statistics.median(r - t for r, t in zip(recv, rec, strict=True))
    aligned = [abs(r - t - offset) / 1e6 for r, t in zip(recv, rec, strict=True)]
    steps = [abs((recv[i] - recv[i - 1]) - (rec[i] - rec[i - 1])) / 1e6 for i in range(1, len(rec))]
    return {
        "first": statistics.median(first),
        "aligned": statistics.median(aligned),
        "aligned_p95": float(np.percentile(aligned, 95)),
        "interval": statistics.median(steps),
        "interval_p95": float(np.percentile(steps, 95)),
    }


def _subscribe(ctx: Any, recv: list[int]) -> None:
    from visnav.graph import Node
    from visnav.msgs import Image, String

    node = Node("timing_listener", context=ctx)
    node.create_subscription(
        Image, "/image", lambda m, info: recv.append(info.received_timestamp_ns), 100
    )
    node.create_subscription(
        String, "/chatter", lambda m, info: recv.append(info.received_timestamp_ns), 100
    )


def play_in_process(bag: Path, n: int) -> list[int]:
    from visnav.bag import BagPlayer
    from visnav.graph import Context

    recv: list[int] = []
    with Context(transport="local") as ctx:
        _subscribe(ctx, recv)
        player = BagPlayer(ctx, bag)
        player.start()
        ctx.spin_until(lambda: player.done, 10.0)
        ctx.spin_some()
        player.wait()
    assert len(recv) == n, len(recv)
    return recv


def play_cross_process(bag: Path, n: int, domain: int) -> list[int]:
    from visnav.graph import Context

    recv: list[int] = []
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    with Context(domain) as ctx:
        _subscribe(ctx, recv)
        proc = subprocess.Popen(
            [sys.executable, "-m", "visnav.cli.main", "bag", "play", str(bag), "--delay", "0.5"],
            env=env,
            stdout=subprocess.DEVNULL,
        )
        ctx.spin_until(lambda: len(recv) >= n, 15.0)
        proc.wait(15)
    assert len(recv) == n, len(recv)
    return recv


def bench_playback() -> None:
    with tempfile.TemporaryDirectory(prefix="bench_play_") as d:
        bag = Path(d) / "timing"
        rec = _timing_bag(bag)
        n = len(rec)
        for label, fn in (
            ("in-process BagPlayer", lambda i: play_in_process(bag, n)),
            (
                "visnav bag play (other process, Zenoh)",
                lambda i: play_cross_process(bag, n, 900_000 + os.getpid() % 50_000 + i),
            ),
        ):
            runs = [_timing_errors(fn(i), rec) for i in range(REPEATS)]
            m = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
            print(
                f"play --rate 1, {label}, {n} messages: median |error| vs first message "
                f"{m['first']:.3f} ms; median-aligned {m['aligned']:.3f} ms (p95 "
                f"{m['aligned_p95']:.3f}); consecutive intervals {m['interval']:.3f} ms (p95 "
                f"{m['interval_p95']:.3f}) (target median <= 2 ms)"
            )


if __name__ == "__main__":
    if "--play-only" not in sys.argv:
        bench_recording()
    if "--writer-only" not in sys.argv:
        bench_playback()
