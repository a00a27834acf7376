"""Benchmark: the usb_cam / cv_camera driver's cost per frame vs OpenCV's own read loop.

A 640x480 MJPG ``.avi`` (written here by ``cv2.VideoWriter``, 60 frames) is read

* by OpenCV alone: ``VideoCapture.read()`` (grab + decode), the reference;
* by the driver's capture path (what ``UsbCamNode``'s timer callback runs per frame):
  ``VideoSource.read`` (grab, stamp, decode) +
  ``frame_to_image`` (BGR -> rgb8 ``sensor_msgs/Image``, as usb_cam publishes) +
  publishing image and camera_info on an in-process graph with a subscriber, with and
  without the JPEG ``compressed``
  transport (encoded only while it has a subscriber).

Each row is the median over repeated passes of the whole file (ms per frame) and its
ratio to the OpenCV reference measured in the same run.

Run: python bench/bench_camera.py
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, CompressedImage, Header, Image, make
from visnav.msgs.time import ns_to_time
from visnav.perception.camera_driver import VideoSource, frame_to_image, parse_source
from visnav.perception.image_transport import ImageTransportPublisher

W, H, FRAMES, REPEATS = 640, 480, 60, 7


def _video(path: Path) -> Path:
    rng = np.random.default_rng(0)
    base = rng.integers(0, 255, (H, W, 3), dtype=np.uint8)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 30.0, (W, H))
    for i in range(FRAMES):
        writer.write(np.roll(base, 8 * i, axis=1))
    writer.release()
    return path


def _median_ms_per_frame(run: Callable[[], int]) -> float:
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        n = run()
        times.append((time.perf_counter() - t0) / max(n, 1) * 1e3)
    return statistics.median(times)


def _opencv(path: Path) -> int:
    cap = cv2.VideoCapture(str(path))
    n = 0
    while True:
        ok, _ = cap.read()
        if not ok:
            break
        n += 1
    cap.release()
    return n


def _driver(ctx: Context, path: Path, *, compressed: bool) -> Callable[[], int]:
    """The per-frame path on a graph built once (publishers and subscribers outside the timing)."""
    node = Node(f"bench_cam_{int(compressed)}", context=ctx)
    ns = f"/{node.get_name()}"
    probe = Node(f"probe_{int(compressed)}", context=ctx)
    got: list[object] = []
    probe.create_subscription(Image, f"{ns}/image_raw", got.append, 100)
    probe.create_subscription(CameraInfo, f"{ns}/camera_info", got.append, 100)
    if compressed:
        probe.create_subscription(CompressedImage, f"{ns}/image_raw/compressed", got.append, 100)
    pub = ImageTransportPublisher(node, "~/image_raw", 5)
    info_pub = node.create_publisher(CameraInfo, "~/camera_info", 5)
    info = make(CameraInfo, width=W, height=H)

    def run() -> int:
        video = VideoSource(parse_source(str(path)))
        n = 0
        while (frame := video.read(node.get_clock().now_ns)) is not None:
            header = Header(stamp=ns_to_time(frame.stamp_ns), frame_id="cam")
            pub.publish(frame_to_image(frame.pixels, "rgb8", header))
            info.header = header
            info_pub.publish(info)
            ctx.spin_some()
            n += 1
        video.release()
        got.clear()
        return n

    return run


def main() -> None:
    """Print the table."""
    with tempfile.TemporaryDirectory() as tmp:
        path = _video(Path(tmp) / "bench.avi")
        with Context(transport="local") as ctx:
            raw_run = _driver(ctx, path, compressed=False)
            jpeg_run = _driver(ctx, path, compressed=True)
            ref = _median_ms_per_frame(lambda: _opencv(path))
            raw = _median_ms_per_frame(raw_run)
            jpeg = _median_ms_per_frame(jpeg_run)
    print(f"{W}x{H} MJPG, {FRAMES} frames, median of {REPEATS} passes (ms per frame)")
    print(f"{'path':<52} {'ms/frame':>9} {'x OpenCV':>9}")
    for label, value in (
        ("OpenCV VideoCapture.read (reference)", ref),
        ("driver: read + rgb8 Image + publish image, info", raw),
        ("driver: ... + compressed (JPEG) transport", jpeg),
    ):
        print(f"{label:<52} {value:>9.2f} {value / ref:>9.2f}")
    print(f"driver ceiling: {1e3 / raw:.0f} fps raw, {1e3 / jpeg:.0f} fps with compressed")


if __name__ == "__main__":
    main()
