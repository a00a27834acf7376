"""Images in bags through compressed transport: recorder, write queue, player, helpers."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.bag import BagPlayer, BagReader, BagRecorder, BagWriter
from visnav.bag.image_compression import ImageCompression, decode_image, image_topics
from visnav.bag.write_queue import WriteQueue
from visnav.graph import Context, Node
from visnav.msgs import Header, Image, serialize
from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.msgs.serde import deserialize
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import CompressedImage
from visnav.perception.transport_codecs import ImageTransportError

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
H, W = 48, 64


def _colour(i: int) -> Image:
    y, x = np.mgrid[0:H, 0:W]
    rgb = np.stack([x * 4, y * 5, (x + y + 10 * i) % 256], axis=-1).astype(np.uint8)
    header = Header(stamp=ns_to_time(1_000_000_000 + i), frame_id="cam_optical")
    return numpy_to_image(rgb, "rgb8", header=header)


def _depth(i: int) -> Image:
    y, x = np.mgrid[0:H, 0:W]
    depth = (0.5 + 0.05 * x + 0.01 * y + 0.001 * i).astype(np.float32)
    depth[0, 0] = np.nan
    depth[1, 1] = 12.0  # beyond depth_max (10 m): invalid after the round trip
    header = Header(stamp=ns_to_time(1_000_000_000 + i), frame_id="depth_optical")
    return numpy_to_image(depth, "32FC1", header=header)


def test_transport_choice_by_encoding() -> None:
    pick = ImageCompression.transport_for
    assert pick("rgb8") == pick("bgr8") == pick("mono8") == pick("mono16") == "compressed"
    assert pick("bayer_rggb8") == "compressed"
    assert pick("32FC1") == pick("16UC1") == "compressedDepth"
    assert pick("64FC1") == pick("32FC3") == pick("8SC1") == "raw"
    assert ImageCompression.topic("/cam/image_raw", "compressed") == "/cam/image_raw/compressed"
    assert ImageCompression.topic("/d/image_raw", "raw") == "/d/image_raw"


def test_colour_round_trip_is_jpeg_in_ros_format() -> None:
    image = _colour(0)
    msg = ImageCompression().encode(image, "compressed")
    assert msg.format == "rgb8; jpeg compressed bgr8"
    assert bytes(msg.data[:2]) == b"\xff\xd8"  # JPEG SOI
    assert msg.header.stamp == image.header.stamp
    assert msg.header.frame_id == "cam_optical"
    back = decode_image(msg)
    assert back.encoding == "rgb8"
    assert (back.height, back.width) == (H, W)
    diff = np.abs(image_to_numpy(back).astype(int) - image_to_numpy(image).astype(int))
    assert diff.mean() < 3.0  # JPEG q80 on a smooth image
    # channel order kept: a red image stays red
    red = numpy_to_image(np.full((H, W, 3), (200, 10, 10), np.uint8), "rgb8")
    red_back = image_to_numpy(decode_image(ImageCompression().encode(red, "compressed")))
    assert red_back[..., 0].mean() > 180
    assert red_back[..., 2].mean() < 30


def test_depth_round_trip_is_compressed_depth_in_ros_format() -> None:
    image = _depth(0)
    msg = ImageCompression().encode(image, "compressedDepth")
    assert msg.format == "32FC1; compressedDepth png"
    data = bytes(msg.data)
    fmt, a, b = struct.unpack("<iff", data[:12])  # ConfigHeader
    assert fmt == 0
    assert a == pytest.approx(100.0 * 101.0)
    assert b == pytest.approx(1.0 - a / 10.0)
    assert data[12:20] == b"\x89PNG\r\n\x1a\n"
    back = image_to_numpy(decode_image(msg))
    want = image_to_numpy(image)
    assert np.isnan(back[0, 0])
    assert np.isnan(back[1, 1])  # deeper than depth_max
    ok = np.isfinite(want) & (want < 10.0)
    err = np.abs(back[ok] - want[ok])
    assert err.max() <= (want[ok] ** 2 / a).max() * 1.01  # one quantisation step
    millimetres = np.nan_to_num(want * 1000).astype(np.uint16)
    mm_msg = ImageCompression().encode(numpy_to_image(millimetres, "16UC1"), "compressedDepth")
    assert mm_msg.format == "16UC1; compressedDepth png"
    assert struct.unpack("<iff", bytes(mm_msg.data[:12])) == (0, 0.0, 0.0)
    millimetres[1, 1] = 0  # 12 m > depth_max: 0, as the plugin's max-depth filter
    assert np.array_equal(image_to_numpy(decode_image(mm_msg)), millimetres)


def test_encode_cdr_and_bad_input() -> None:
    policy = ImageCompression()
    out = deserialize(policy.encode_cdr(serialize(_colour(1)), "compressed"), COMPRESSED)
    assert isinstance(out, CompressedImage)
    assert out.format.startswith("rgb8; jpeg")
    with pytest.raises(ImageTransportError, match="compressedDepth needs a depth image"):
        policy.encode(_colour(0), "compressedDepth")
    with pytest.raises(ImageTransportError, match="jpeg_quality"):
        ImageCompression(jpeg_quality=0)
    with pytest.raises(ImageTransportError, match="expected sensor_msgs/Image"):
        decode_image("not an image")


def test_image_topics_maps_base_names() -> None:
    topics = {
        "/cam/image_raw/compressed": COMPRESSED,
        "/d/depth/image_raw/compressedDepth": COMPRESSED,
        "/both/image_raw": IMAGE,
        "/both/image_raw/compressed": COMPRESSED,
        "/odd": COMPRESSED,
        "/cam/camera_info": "sensor_msgs/msg/CameraInfo",
    }
    assert image_topics(topics) == {
        "/cam/image_raw": "/cam/image_raw/compressed",
        "/d/depth/image_raw": "/d/depth/image_raw/compressedDepth",
        "/both/image_raw": "/both/image_raw",  # raw wins
        "/odd": "/odd",
    }


def test_write_queue_job_error_drops_only_that_message(tmp_path: Path) -> None:
    writer = BagWriter(tmp_path / "q")
    handle = writer.add_topic("/s", "std_msgs/msg/String")
    queue = WriteQueue(writer)
    from visnav.msgs import String

    def bad() -> bytes:
        raise ImageTransportError("cannot encode")

    assert queue.put_job(handle, 1, lambda: serialize(String(data="a")), 1, size=10)
    assert queue.put_job(handle, 2, bad, 2, size=10)
    assert queue.put(handle, 3, serialize(String(data="c")), 3)
    queue.close()
    writer.close()
    assert queue.dropped == {handle: 1}
    assert queue.job_errors == {handle: "cannot encode"}
    assert queue.pending_bytes == 0
    with BagReader(writer.path) as reader:
        assert [m.msg.data for m in reader.messages()] == ["a", "c"]


def test_recorder_stores_images_through_compressed_transport(
    tmp_path: Path, local_ctx: Context
) -> None:
    node = Node("camera", context=local_ctx)
    colour = node.create_publisher(Image, "/cam/image_raw", 10)
    depth = node.create_publisher(Image, "/cam/depth/image_raw", 10)
    odd = node.create_publisher(Image, "/cam/odd", 10)
    rec = BagRecorder(local_ctx, None, tmp_path / "bag", image_transport=ImageCompression())
    rec.start()
    local_ctx.spin_some()
    sent = []
    for i in range(4):
        c, d = _colour(i), _depth(i)
        colour.publish(c)
        depth.publish(d)
        odd.publish(numpy_to_image(np.zeros((2, 3), np.float64), "64FC1"))
        sent.append((c, d))
        local_ctx.spin_some()
        rec.poll()
    path = rec.stop()
    assert {t: (r.type_name, r.count) for t, r in rec.topics.items()} == {
        "/cam/image_raw/compressed": (COMPRESSED, 4),
        "/cam/depth/image_raw/compressedDepth": (COMPRESSED, 4),
        "/cam/odd": (IMAGE, 4),  # not compressible: raw
    }
    with BagReader(path) as reader:
        assert {n: m.type_name for n, m in reader.topics.items()} == {
            "/cam/image_raw/compressed": COMPRESSED,
            "/cam/depth/image_raw/compressedDepth": COMPRESSED,
            "/cam/odd": IMAGE,
        }
        got: dict[str, list[Any]] = {}
        for m in reader.messages():
            got.setdefault(m.topic, []).append(m.msg)
    for (c, d), jpeg, png in zip(
        sent,
        got["/cam/image_raw/compressed"],
        got["/cam/depth/image_raw/compressedDepth"],
        strict=True,
    ):
        assert jpeg.header.stamp == c.header.stamp
        assert png.format == "32FC1; compressedDepth png"
        assert decode_image(png).header.stamp == d.header.stamp
        diff = image_to_numpy(decode_image(jpeg)).astype(int) - image_to_numpy(c).astype(int)
        assert np.abs(diff).mean() < 3.0


def test_player_decompress_republishes_images(tmp_path: Path, local_ctx: Context) -> None:
    with BagWriter(tmp_path / "b") as w:
        h = w.add_topic("/cam/image_raw/compressed", COMPRESSED)
        for i in range(3):
            msg = ImageCompression().encode(_colour(i), "compressed")
            w.write(h, 1_000_000_000 + i * 10_000_000, serialize(msg))
    node = Node("sub", context=local_ctx)
    raw: list[Image] = []
    comp: list[CompressedImage] = []
    node.create_subscription(Image, "/cam/image_raw", raw.append, 10)
    node.create_subscription(CompressedImage, "/cam/image_raw/compressed", comp.append, 10)
    player = BagPlayer(local_ctx, w.path, rate=10.0, decompress=True)
    player.start()
    assert local_ctx.spin_until(lambda: player.done, 5.0)
    local_ctx.spin_some()
    player.wait()
    assert len(comp) == 3
    assert [m.encoding for m in raw] == ["rgb8"] * 3
    assert player.stats.published == {"/cam/image_raw/compressed": 3, "/cam/image_raw": 3}
    plain = BagPlayer(local_ctx, w.path, rate=10.0)
    plain.play()
    assert plain.stats.published == {"/cam/image_raw/compressed": 3}  # as rosbag play


def test_recorder_counts_frames_its_transport_cannot_encode(
    tmp_path: Path, local_ctx: Context, caplog: pytest.LogCaptureFixture
) -> None:
    """The transport is chosen from the first frame; a later depth frame on a colour topic
    cannot be JPEG-compressed: dropped, counted in the bag's drops and logged."""
    node = Node("camera", context=local_ctx)
    pub = node.create_publisher(Image, "/cam/image_raw", 10)
    rec = BagRecorder(local_ctx, None, tmp_path / "bag", image_transport=ImageCompression())
    rec.start()
    local_ctx.spin_some()
    for image in (_colour(0), _depth(1), _colour(2)):
        pub.publish(image)
        local_ctx.spin_some()
        rec.poll()
    with caplog.at_level("WARNING", logger="visnav.bag"):
        path = rec.stop()
    assert rec.drops() == {"/cam/image_raw/compressed": 1}
    assert "'/cam/image_raw/compressed': 1 image(s) not stored" in caplog.text
    with BagReader(path) as reader:
        stamps = [m.msg.header.stamp.nanosec for m in reader.messages()]
    assert stamps == [0, 2]


def test_bag_record_compress_images_from_another_process(tmp_path: Path, domain: int) -> None:
    """``visnav bag record --compress-images``: images published in another process (Zenoh)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "rec"
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    cmd = [sys.executable, "-m", "visnav.cli.main", "bag", "record", "/cam/image_raw"]
    proc = subprocess.Popen(
        [*cmd, "--compress-images", "-o", str(out)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("Recording to")
        with Context(domain) as ctx:
            pub = Node("camera", context=ctx).create_publisher(Image, "/cam/image_raw", 10)
            deadline = time.monotonic() + 5.0
            while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
                time.sleep(0.02)
            time.sleep(0.1)
            for i in range(3):
                pub.publish(_colour(i))
                time.sleep(0.05)
            time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0
    with BagReader(out) as reader:
        assert {n: m.type_name for n, m in reader.topics.items()} == {
            "/cam/image_raw/compressed": COMPRESSED
        }
        msgs = [m.msg for m in reader.messages()]
    assert [m.header.stamp.nanosec for m in msgs] == [0, 1, 2]
    assert all(m.format == "rgb8; jpeg compressed bgr8" for m in msgs)


@pytest.mark.parametrize(("metres", "step_mm"), [(1.0, 0.099), (3.0, 0.892), (5.0, 2.48)])
def test_depth_quantisation_error_at_1_3_5_m(metres: float, step_mm: float) -> None:
    """compressedDepth's defaults (A = 100 * 101) keep depth to d^2 / (A - d): far below the
    Kinect's own noise (1.5 mm at 1 m, 4 cm at 5 m); decoded depth is never nearer."""
    depth = np.linspace(metres - 0.02, metres + 0.02, H * W, dtype=np.float32).reshape(H, W)
    msg = ImageCompression().encode(numpy_to_image(depth, "32FC1"), "compressedDepth")
    out = image_to_numpy(decode_image(msg)).astype(np.float64)
    d = depth.astype(np.float64)
    err = out - d
    step = d**2 / (10100.0 - d)  # one inverse-depth count at d
    assert step_mm == pytest.approx(metres**2 / (10100.0 - metres) * 1e3, rel=0.01)
    assert err.min() >= -1e-6 * metres  # truncation: never nearer than measured
    assert (err <= step + 1e-6 * d).all()
    assert err.max() >= 0.8 * step.max()  # the step is really this coarse
    assert abs(err.mean() - step.mean() / 2) < 0.1 * step.mean()  # on average half a step
