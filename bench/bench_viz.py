"""Viewer benchmark (issue 5): one camera frame through ``RerunSink``.

Run: ``python bench/bench_viz.py`` (needs ``pip install 'visnav[viz]'``). Prints medians.

Per frame: a 640x480 rgb8 Image, a 640x480 32FC1 depth Image, the organised 640x480 cloud
of that depth with rgb (307,200 points, decimated by the sink to <= 50,000) and a /tf
message (odom -> base_link), the camera hanging under base_link by static TF. The sink
converts, looks up ``T_map_frame`` at each stamp and logs to a recording saved to a
temporary .rrd. Target: median <= 10 ms per frame.

Reference, in the same run: the bare Rerun SDK logging the same pixels and an
already-decimated, already-transformed cloud (what the sink's output amounts to), so the
ratio shows what the conversions and TF placement cost.
"""

from __future__ import annotations

import math
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

FRAMES = 60
REPEATS = 5


def _messages(n: int) -> list[dict[str, Any]]:
    from visnav.msgs import (
        Header,
        TFMessage,
        TransformStamped,
        make,
        ns_to_time,
        numpy_to_image,
        xyz_to_cloud,
    )

    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)
    depth = rng.uniform(0.5, 5.0, (480, 640)).astype(np.float32)
    u, v = np.meshgrid(np.arange(640), np.arange(480))
    xyz = np.stack([(u - 320) / 525.0 * depth, (v - 240) / 525.0 * depth, depth], axis=-1)
    frames = []
    for i in range(n):
        t = 1_000_000_000 + i * 33_333_333
        header = Header(stamp=ns_to_time(t), frame_id="camera_optical")
        tf = make(TransformStamped, child_frame_id="base_link")
        tf.header = Header(stamp=ns_to_time(t), frame_id="odom")
        tf.transform.translation.x = 0.01 * i
        tf.transform.rotation.z, tf.transform.rotation.w = math.sin(0.005 * i), math.cos(0.005 * i)
        frames.append(
            {
                "/tf": TFMessage(transforms=[tf]),
                "/camera/image_raw": numpy_to_image(rgb, "rgb8", header=header),
                "/camera/depth/image_raw": numpy_to_image(depth, "32FC1", header=header),
                "/camera/depth/points": xyz_to_cloud(
                    xyz.astype(np.float32), header=header, rgb=rgb
                ),
            }
        )
    return frames


def _static() -> Any:
    from visnav.msgs import Header, TFMessage, TransformStamped, make

    out = []
    for parent, child, z in (("map", "odom", 0.0), ("base_link", "camera_optical", 0.5)):
        t = make(TransformStamped, child_frame_id=child)
        t.header = make(Header, frame_id=parent)
        t.transform.translation.z = z
        t.transform.rotation.w = 1.0
        out.append(t)
    return TFMessage(transforms=out)


def bench_sink(frames: list[dict[str, Any]], tmp: Path) -> list[float]:
    from visnav.viz import RerunSink, open_viewer

    times = []
    with open_viewer(save=tmp / "sink.rrd") as viewer:
        sink = RerunSink(viewer.recording, fixed_frame="map")
        sink.log("/tf_static", _static())
        for frame in frames:
            t = time.perf_counter()
            for topic, msg in frame.items():
                sink.log(topic, msg)
            times.append(time.perf_counter() - t)
        sink.close()
        assert sink.placer.dropped == {}, sink.stats()
    return times


def bench_bare(frames: list[dict[str, Any]], tmp: Path) -> list[float]:
    import rerun as rr

    from visnav.msgs import cloud_to_xyz, image_to_numpy

    rec = rr.RecordingStream("bench", recording_id="bare")
    rec.save(tmp / "bare.rrd")
    clouds = [cloud_to_xyz(f["/camera/depth/points"], skip_nans=False)[::7].copy() for f in frames]
    times = []
    for frame, pts in zip(frames, clouds, strict=True):
        t = time.perf_counter()
        stamp = frame["/camera/image_raw"].header.stamp
        rec.set_time("ros_time", timestamp=np.datetime64(stamp.sec * 10**9 + stamp.nanosec, "ns"))
        rec.log("world/tf/base_link", rr.Transform3D(translation=[0.0, 0.0, 0.0]))
        rec.log("world/cam", rr.Transform3D(translation=[0.0, 0.0, 0.5]))
        rec.log("world/cam/image", rr.Image(image_to_numpy(frame["/camera/image_raw"])))
        rec.log(
            "world/cam/depth",
            rr.DepthImage(image_to_numpy(frame["/camera/depth/image_raw"]), meter=1.0),
        )
        rec.log("world/points", rr.Points3D(pts))
        times.append(time.perf_counter() - t)
    rec.flush()
    rec.disconnect()
    return times


def main() -> None:
    frames = _messages(FRAMES)
    sink_runs, bare_runs = [], []
    with tempfile.TemporaryDirectory() as d:
        for r in range(REPEATS):
            run = Path(d) / str(r)
            run.mkdir()
            bare_runs.append(statistics.median(bench_bare(frames, run)))
            sink_runs.append(statistics.median(bench_sink(frames, run)))
    sink_ms = statistics.median(sink_runs) * 1e3
    bare_ms = statistics.median(bare_runs) * 1e3
    print(f"frames per run: {FRAMES}, runs: {REPEATS}")
    print(
        f"RerunSink: image + depth + cloud (307,200 -> <= 50,000 points) + TF: {sink_ms:.2f} ms median per frame (target <= 10 ms)"
    )
    print(f"bare rerun-sdk, same pixels, pre-decimated cloud: {bare_ms:.2f} ms median per frame")
    print(f"ratio sink / bare: {sink_ms / bare_ms:.2f}")


if __name__ == "__main__":
    main()
