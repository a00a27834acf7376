from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from visnav.msgs import CompressedImage, Header, Image, Time
from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.perception.image_transport import (
    ImageTransportError,
    ImageTransportPublisher,
    compress,
    compress_depth,
    convert_encoding,
    decompress,
    decompress_depth,
    depth_quantization_params,
    image_transport_subscription,
    split_transport_topic,
    transport_topic,
)

HEADER = Header(stamp=Time(sec=12, nanosec=345), frame_id="camera_optical")


def smooth_rgb(h: int = 48, w: int = 64, seed: int = 0) -> np.ndarray:
    """A smooth colour image (gradients + blobs): JPEG-friendly and not trivial."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    chans = []
    for _ in range(3):
        fx, fy = rng.uniform(0.02, 0.12, 2).tolist()
        ph = rng.uniform(0, 6.28)
        chans.append(127.5 + 100 * np.sin(fx * x + fy * y + ph))
    return np.clip(np.stack(chans, axis=2), 0, 255).astype(np.uint8)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def image(array: np.ndarray, encoding: str) -> Image:
    return numpy_to_image(array, encoding, header=HEADER)


# ------------------------------------------------------------------ topics


@pytest.mark.parametrize(
    ("topic", "expected"),
    [
        ("image_raw/compressed", ("image_raw", "compressed")),
        ("/cam/depth/image_raw/compressedDepth", ("/cam/depth/image_raw", "compressedDepth")),
        ("camera/image_raw", ("camera/image_raw", "raw")),
        ("camera/image_raw/theora", ("camera/image_raw", "theora")),
        ("compressed", ("compressed", "raw")),  # a bare name is a base topic
        ("cam/compressed/", ("cam", "compressed")),
    ],
)
def test_split_transport_topic(topic: str, expected: tuple[str, str]) -> None:
    assert split_transport_topic(topic) == expected


def test_transport_topic_and_empty() -> None:
    assert transport_topic("cam/image_raw", "compressed") == "cam/image_raw/compressed"
    assert transport_topic("cam/image_raw", "raw") == "cam/image_raw"
    with pytest.raises(ImageTransportError, match="topic is ''"):
        split_transport_topic("")


# -------------------------------------------------------------- compressed


@pytest.mark.parametrize(
    ("encoding", "fmt", "expected"),
    [
        ("rgb8", "jpeg", "rgb8; jpeg compressed bgr8"),
        ("bgr8", "jpeg", "bgr8; jpeg compressed bgr8"),
        ("mono8", "jpeg", "mono8; jpeg compressed "),
        ("rgb8", "png", "rgb8; png compressed bgr8"),
        ("rgb16", "png", "rgb16; png compressed bgr16"),
        ("rgb16", "jpeg", "rgb16; jpeg compressed bgr8"),
        ("mono16", "png", "mono16; png compressed "),
        ("bayer_rggb8", "png", "bayer_rggb8; png compressed "),
    ],
)
def test_format_strings_as_ros_writes_them(encoding: str, fmt: str, expected: str) -> None:
    shape = (8, 10) if encoding.startswith(("mono", "bayer")) else (8, 10, 3)
    dtype = np.uint16 if encoding.endswith("16") else np.uint8
    msg = compress(image(np.zeros(shape, dtype), encoding), format=fmt)
    assert msg.format == expected
    assert msg.header.stamp == HEADER.stamp
    assert msg.header.frame_id == "camera_optical"


@pytest.mark.parametrize(
    "encoding", ["rgb8", "bgr8", "rgb16", "bgr16", "mono8", "mono16", "bayer_gbrg8"]
)
def test_png_round_trip_is_exact(encoding: str) -> None:
    rng = np.random.default_rng(1)
    channels = 1 if encoding.startswith(("mono", "bayer")) else 3
    dtype = np.uint16 if encoding.endswith("16") else np.uint8
    shape = (17, 23) if channels == 1 else (17, 23, 3)
    pixels = rng.integers(0, np.iinfo(dtype).max, size=shape, dtype=dtype, endpoint=True)
    msg = compress(image(pixels, encoding), format="png", png_level=3)
    assert msg.data[:8].tobytes() == b"\x89PNG\r\n\x1a\n"
    back = decompress(msg)
    assert back.encoding == encoding
    assert back.header.stamp == HEADER.stamp
    np.testing.assert_array_equal(image_to_numpy(back), pixels)


def test_png_rgba_drops_alpha_as_ros() -> None:
    pixels = np.dstack([smooth_rgb(), np.full((48, 64), 7, np.uint8)])
    back = decompress(compress(image(pixels, "rgba8"), format="png"))
    assert back.encoding == "rgba8"
    out = image_to_numpy(back)
    np.testing.assert_array_equal(out[..., :3], pixels[..., :3])
    assert (out[..., 3] == 255).all()


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "mono8"])
def test_jpeg_round_trip_psnr(encoding: str) -> None:
    rgb = smooth_rgb()
    pixels = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY) if encoding == "mono8" else rgb
    msg = compress(image(pixels, encoding), jpeg_quality=80)
    assert msg.data[:2].tobytes() == b"\xff\xd8"  # JPEG SOI
    back = decompress(msg)
    assert back.encoding == encoding
    out = image_to_numpy(back)
    assert out.shape == pixels.shape
    assert psnr(out, pixels) > 33.0
    # Channel order is preserved (a swapped R/B would give a far lower PSNR).
    if encoding != "mono8":
        assert psnr(out, pixels[..., ::-1]) < psnr(out, pixels) - 5


def test_jpeg_quality_changes_size_and_error() -> None:
    pixels = smooth_rgb(seed=3)
    low = compress(image(pixels, "rgb8"), jpeg_quality=10)
    high = compress(image(pixels, "rgb8"), jpeg_quality=95)
    assert len(low.data) < len(high.data)
    assert psnr(image_to_numpy(decompress(low)), pixels) < psnr(
        image_to_numpy(decompress(high)), pixels
    )


def test_jpeg_rgb16_scaled_back_by_256() -> None:
    pixels8 = smooth_rgb()
    pixels16 = pixels8.astype(np.uint16) * 257
    back = decompress(compress(image(pixels16, "rgb16"), jpeg_quality=95))
    assert back.encoding == "rgb16"
    out = image_to_numpy(back)
    assert out.dtype == np.uint16
    assert psnr((out // 256).astype(np.uint8), pixels8) > 35.0


def test_decode_legacy_format_without_encoding() -> None:
    bgr = smooth_rgb()
    ok, buf = cv2.imencode(".png", bgr)
    assert ok
    msg = CompressedImage(header=HEADER, format="png", data=buf.reshape(-1))
    back = decompress(msg)
    assert back.encoding == "bgr8"
    np.testing.assert_array_equal(image_to_numpy(back), bgr)
    ok, buf = cv2.imencode(".jpg", bgr[..., 0])
    assert (
        decompress(CompressedImage(header=HEADER, format="jpeg", data=buf.reshape(-1))).encoding
        == "mono8"
    )


def test_decode_rgb_payload_when_not_marked_bgr() -> None:
    # A format without "compressed bgr": the data holds RGB in OpenCV's BGR slots.
    rgb = smooth_rgb()
    ok, buf = cv2.imencode(".png", rgb)  # RGB bytes written as if BGR
    assert ok
    msg = CompressedImage(header=HEADER, format="rgb8; png compressed rgb8", data=buf.reshape(-1))
    np.testing.assert_array_equal(image_to_numpy(decompress(msg)), rgb)
    msg.format = "bgr8; png compressed rgb8"
    np.testing.assert_array_equal(image_to_numpy(decompress(msg)), rgb[..., ::-1])


def test_decompress_desired_encoding() -> None:
    rgb = smooth_rgb()
    msg = compress(image(rgb, "rgb8"), format="png")
    bgr = decompress(msg, desired_encoding="bgr8")
    assert bgr.encoding == "bgr8"
    np.testing.assert_array_equal(image_to_numpy(bgr), rgb[..., ::-1])
    mono = decompress(msg, desired_encoding="mono8")
    np.testing.assert_array_equal(image_to_numpy(mono), cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
    assert decompress(msg, desired_encoding="passthrough").encoding == "rgb8"
    with pytest.raises(ImageTransportError, match="cannot convert encoding 'rgb8' to '32FC1'"):
        decompress(msg, desired_encoding="32FC1")


def test_convert_encoding_depths_and_bayer() -> None:
    px = np.array([[[0, 128, 255]]], np.uint8)
    np.testing.assert_array_equal(convert_encoding(px, "rgb8", "bgr16"), [[[65535, 32896, 0]]])
    back = convert_encoding(convert_encoding(px, "rgb8", "rgb16"), "rgb16", "rgb8")
    np.testing.assert_array_equal(back, px)
    np.testing.assert_array_equal(convert_encoding(px, "rgb8", "bgra8"), [[[255, 128, 0, 255]]])
    bayer = np.zeros((4, 4), np.uint8)
    bayer[0::2, 0::2] = 200  # R sites of an RGGB mosaic
    rgb = convert_encoding(bayer, "bayer_rggb8", "rgb8")
    assert rgb.shape == (4, 4, 3)
    assert rgb[1:3, 1:3, 0].mean() > 100
    assert rgb[1:3, 1:3, 2].max() == 0


@settings(max_examples=40, deadline=None)
@given(
    pixels=hnp.arrays(
        np.uint8,
        st.tuples(st.integers(1, 12), st.integers(1, 12), st.just(3)),
    ),
    encoding=st.sampled_from(["rgb8", "bgr8"]),
)
def test_png_round_trip_property(pixels: np.ndarray, encoding: str) -> None:
    out = image_to_numpy(decompress(compress(image(pixels, encoding), format="png")))
    np.testing.assert_array_equal(out, pixels)


@pytest.mark.parametrize(
    ("array", "encoding", "kwargs", "match"),
    [
        (np.zeros((4, 4), np.float32), "32FC1", {}, "use the compressedDepth transport"),
        (np.zeros((4, 4), np.uint16), "mono16", {}, "use format='png'"),
        (np.zeros((4, 4), np.int8), "8SC1", {}, "8/16-bit unsigned"),
        (np.zeros((4, 4, 3), np.uint8), "rgb8", {"format": "webp"}, "format is 'webp'"),
        (np.zeros((4, 4, 3), np.uint8), "rgb8", {"jpeg_quality": 0}, "jpeg_quality is 0"),
        (np.zeros((4, 4, 3), np.uint8), "rgb8", {"format": "png", "png_level": 10}, "png_level"),
    ],
)
def test_compress_bad_input(
    array: np.ndarray, encoding: str, kwargs: dict[str, Any], match: str
) -> None:
    with pytest.raises(ImageTransportError, match=match):
        compress(image(array, encoding), **kwargs)


def test_compress_malformed_image() -> None:
    msg = image(np.zeros((4, 4, 3), np.uint8), "rgb8")
    msg.height = 5
    with pytest.raises(ImageTransportError, match=r"Image\.data has 48 bytes"):
        compress(msg)


def test_decompress_bad_input() -> None:
    with pytest.raises(ImageTransportError, match="not a decodable JPEG/PNG stream"):
        decompress(
            CompressedImage(
                header=HEADER,
                format="rgb8; jpeg compressed bgr8",
                data=np.arange(50, dtype=np.uint8),
            )
        )
    with pytest.raises(ImageTransportError, match="data is empty"):
        decompress(
            CompressedImage(
                header=HEADER, format="rgb8; jpeg compressed bgr8", data=np.zeros(0, np.uint8)
            )
        )
    gray = compress(image(np.zeros((4, 4), np.uint8), "mono8"), format="png")
    gray.format = "rgb8; png compressed bgr8"
    with pytest.raises(
        ImageTransportError, match=r"says 'rgb8' \(3 x uint8\), but the data decodes to 1 x uint8"
    ):
        decompress(gray)


# --------------------------------------------------------- compressedDepth


def test_compressed_depth_header_bytes_hand_computed() -> None:
    depth = np.full((3, 4), 2.0, np.float32)
    msg = compress_depth(image(depth, "32FC1"))
    assert msg.format == "32FC1; compressedDepth png"
    # int32 format 0 (INV_DEPTH); float32 A = 100 * 101 = 10100 = 0x461DD000;
    # float32 B = 1 - 10100 / 10 = -1009 = 0xC47C4000; all little endian.
    assert msg.data[:12].tobytes() == bytes.fromhex("0000000000d01d4600407cc4")
    assert msg.data[12:20].tobytes() == b"\x89PNG\r\n\x1a\n"
    # 10100 / 2 - 1009 = 4041 in every pixel.
    png = cv2.imdecode(msg.data[12:], cv2.IMREAD_UNCHANGED)
    assert png.dtype == np.uint16
    assert (png == 4041).all()


def test_compressed_depth_16uc1_exact_and_depth_max() -> None:
    rng = np.random.default_rng(2)
    mm = rng.integers(0, 10_000, size=(20, 30), dtype=np.uint16, endpoint=True)
    msg = compress_depth(image(mm, "16UC1"))
    assert msg.format == "16UC1; compressedDepth png"
    assert msg.data[:12].tobytes() == bytes(12)  # format 0, params 0
    back = decompress_depth(msg)
    assert back.encoding == "16UC1"
    assert back.header.frame_id == "camera_optical"
    np.testing.assert_array_equal(image_to_numpy(back), mm)
    # Above depth_max (10 m = 10000 mm by default) ROS stores 0.
    far = np.array([[10_000, 10_001, 65_535]], np.uint16)
    np.testing.assert_array_equal(
        image_to_numpy(decompress_depth(compress_depth(image(far, "16UC1")))), [[10_000, 0, 0]]
    )
    np.testing.assert_array_equal(
        image_to_numpy(decompress_depth(compress_depth(image(far, "16UC1"), depth_max=70.0))), far
    )


def test_compressed_depth_32fc1_within_quantisation() -> None:
    rng = np.random.default_rng(3)
    depth = rng.uniform(0.2, 9.9, size=(30, 40)).astype(np.float32)
    depth[0, 0] = np.nan
    depth[0, 1] = 12.0  # beyond depth_max
    depth[0, 2] = 0.0
    depth[0, 3] = np.inf
    back = decompress_depth(compress_depth(image(depth, "32FC1")))
    assert back.encoding == "32FC1"
    out = image_to_numpy(back)
    assert np.isnan(out[0, :4]).all()
    a, _ = depth_quantization_params(10.0, 100.0)
    d, o = depth[1:].astype(np.float64), out[1:].astype(np.float64)
    # v = floor(A / d + B) => decoded A / (v - B) >= d, and the step is d^2 / (A - d).
    assert (o >= d - 1e-5 * d).all()
    assert (o - d <= d**2 / (a - d) + 1e-5 * d).all()
    assert np.abs(o - d).max() < 0.01  # about 1 cm at 10 m with the defaults


@settings(max_examples=30, deadline=None)
@given(
    depth=hnp.arrays(
        np.float32,
        st.tuples(st.integers(1, 6), st.integers(1, 6)),
        elements=st.floats(0.25, 9.5, width=32),
    ),
    quantization=st.floats(20.0, 150.0),
)
def test_compressed_depth_quantisation_property(depth: np.ndarray, quantization: float) -> None:
    out = image_to_numpy(
        decompress_depth(compress_depth(image(depth, "32FC1"), depth_quantization=quantization))
    )
    a, b = depth_quantization_params(10.0, quantization)
    d = depth.astype(np.float64)
    nearest = a / (65536 - b)  # closer depths need an inverse depth above 65535
    assert np.isnan(out[d < 0.999 * nearest]).all()
    ok = d > 1.001 * nearest
    assert np.isfinite(out[ok]).all()
    assert (np.abs(out[ok] - d[ok]) <= d[ok] ** 2 / (a - d[ok]) + 1e-4 * d[ok]).all()


def test_too_close_depth_is_invalid_not_wrapped() -> None:
    depth = np.array([[0.05, 0.2]], np.float32)  # 0.05 m would need v > 65535
    out = image_to_numpy(decompress_depth(compress_depth(image(depth, "32FC1"))))
    assert np.isnan(out[0, 0])
    assert abs(out[0, 1] - 0.2) < 1e-3


def test_decode_compressed_depth_written_by_ros() -> None:
    """A message laid out byte by byte as compressed_depth_image_transport writes it."""
    a, b = 50.0 * 51.0, 1.0 - 50.0 * 51.0 / 5.0  # depth_quantization 50, depth_max 5
    inv = np.array([[0, 1000], [2000, 3000]], np.uint16)
    ok, png = cv2.imencode(".png", inv)
    assert ok
    data = struct.pack("<iff", 0, a, b) + png.tobytes()
    msg = CompressedImage(
        header=HEADER, format="32FC1; compressedDepth png", data=np.frombuffer(data, np.uint8)
    )
    out = image_to_numpy(decompress(msg))  # decompress dispatches on the format
    assert np.isnan(out[0, 0])
    expected = np.float32(a) / (inv[inv > 0].astype(np.float32) - np.float32(b))
    np.testing.assert_allclose(out[inv > 0], expected, rtol=1e-6)
    # Older ROS wrote "16UC1; compressedDepth" and left the float params uninitialised.
    mm = np.array([[0, 1234], [65535, 7]], np.uint16)
    ok, png = cv2.imencode(".png", mm)
    data = struct.pack("<iff", 0, 123.0, float("nan")) + png.tobytes()
    old = CompressedImage(
        header=HEADER, format="16UC1; compressedDepth", data=np.frombuffer(data, np.uint8)
    )
    np.testing.assert_array_equal(image_to_numpy(decompress_depth(old)), mm)


@pytest.mark.parametrize(
    ("fmt", "data", "match"),
    [
        ("32FC1; compressedDepth rvl", bytes(40), "expected 1 to"),
        ("32FC1; compressedDepth jpeg", bytes(40), "not a compressedDepth PNG"),
        ("rgb8; compressedDepth png", bytes(40), "not 'rgb8'"),
        ("32FC1; compressedDepth png", bytes(12), "has 12 bytes"),
        ("32FC1; compressedDepth png", bytes(30), "not a decodable"),
    ],
)
def test_decompress_depth_bad_input(fmt: str, data: bytes, match: str) -> None:
    with pytest.raises(ImageTransportError, match=match):
        decompress_depth(
            CompressedImage(header=HEADER, format=fmt, data=np.frombuffer(data, np.uint8))
        )


def test_compress_depth_rejects_colour_and_bad_params() -> None:
    with pytest.raises(
        ImageTransportError, match=r"Image\.encoding is 'rgb8': compressedDepth needs a depth image"
    ):
        compress_depth(image(np.zeros((2, 2, 3), np.uint8), "rgb8"))
    depth = image(np.ones((2, 2), np.float32), "32FC1")
    with pytest.raises(ImageTransportError, match="depth_max is 0"):
        compress_depth(depth, depth_max=0)
    with pytest.raises(ImageTransportError, match="depth_quantization is nan"):
        compress_depth(depth, depth_quantization=float("nan"))


# ------------------------------------------------------------- node level


class FakePublisher:
    def __init__(self, msg_type: Any, topic: str, subscribers: int) -> None:
        self.msg_type, self.topic, self.subscribers = msg_type, topic, subscribers
        self.sent: list[Any] = []

    def publish(self, msg: Any) -> None:
        self.sent.append(msg)

    def get_subscription_count(self) -> int:
        return self.subscribers


class FakeLogger:
    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def error(self, text: str) -> None:
        self.lines.append(("error", text))

    def debug(self, text: str) -> None:
        self.lines.append(("debug", text))


class FakeNode:
    def __init__(self, subscribers: int = 1) -> None:
        self.pubs: dict[str, FakePublisher] = {}
        self.subs: dict[str, tuple[Any, Callable[[Any], None], Any]] = {}
        self.logger = FakeLogger()
        self.subscribers = subscribers

    def create_publisher(self, msg_type: Any, topic: str, qos: Any) -> FakePublisher:
        self.pubs[topic] = FakePublisher(msg_type, topic, self.subscribers)
        return self.pubs[topic]

    def create_subscription(
        self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: Any
    ) -> str:
        self.subs[topic] = (msg_type, callback, qos)
        return f"sub:{topic}"

    def get_logger(self) -> FakeLogger:
        return self.logger


def test_publisher_topics_types_and_payloads() -> None:
    node = FakeNode()
    pub = ImageTransportPublisher(node, "cam/image_raw", 5, ("raw", "compressed"), format="png")
    assert pub.topics == {"raw": "cam/image_raw", "compressed": "cam/image_raw/compressed"}
    assert node.pubs["cam/image_raw"].msg_type is Image
    assert node.pubs["cam/image_raw/compressed"].msg_type is CompressedImage
    img = image(smooth_rgb(), "rgb8")
    pub.publish(img)
    assert node.pubs["cam/image_raw"].sent == [img]
    sent = node.pubs["cam/image_raw/compressed"].sent[0]
    assert sent.format == "rgb8; png compressed bgr8"
    np.testing.assert_array_equal(image_to_numpy(decompress(sent)), smooth_rgb())


def test_publisher_skips_transports_nobody_listens_to() -> None:
    node = FakeNode(subscribers=0)
    pub = ImageTransportPublisher(node, "cam/image_raw")
    pub.publish(image(smooth_rgb(), "rgb8"))
    assert len(node.pubs["cam/image_raw"].sent) == 1  # raw is always published
    assert node.pubs["cam/image_raw/compressed"].sent == []


def test_publisher_logs_once_when_a_transport_cannot_encode() -> None:
    node = FakeNode()
    pub = ImageTransportPublisher(
        node, "depth/image_raw", 1, ("raw", "compressed", "compressedDepth")
    )
    depth = image(np.full((4, 4), 1.5, np.float32), "32FC1")
    pub.publish(depth)
    pub.publish(depth)
    assert len(node.pubs["depth/image_raw"].sent) == 2
    assert len(node.pubs["depth/image_raw/compressedDepth"].sent) == 2
    assert node.pubs["depth/image_raw/compressed"].sent == []
    levels = [level for level, _ in node.logger.lines]
    assert levels == ["error", "debug"]
    assert "depth/image_raw/compressed" in node.logger.lines[0][1]


def test_publisher_bad_arguments() -> None:
    with pytest.raises(ImageTransportError, match="transports is"):
        ImageTransportPublisher(FakeNode(), "img", 1, ("raw", "theora"))
    with pytest.raises(ImageTransportError, match="jpeg_quality is 101"):
        ImageTransportPublisher(FakeNode(), "img", jpeg_quality=101)


def test_subscription_picks_transport_by_name_and_decodes() -> None:
    node = FakeNode()
    got: list[Image] = []
    handle = image_transport_subscription(node, "cam/image_raw/compressed", got.append, 3)
    assert handle == "sub:cam/image_raw/compressed"
    msg_type, callback, qos = node.subs["cam/image_raw/compressed"]
    assert (msg_type, qos) == (CompressedImage, 3)
    rgb = smooth_rgb()
    callback(compress(image(rgb, "rgb8"), format="png"))
    assert got[0].encoding == "rgb8"
    np.testing.assert_array_equal(image_to_numpy(got[0]), rgb)
    # Undecodable data is logged and skipped, not raised into the executor.
    callback(
        CompressedImage(
            header=HEADER, format="rgb8; png compressed bgr8", data=np.arange(9, dtype=np.uint8)
        )
    )
    assert len(got) == 1
    assert node.logger.lines[0][0] == "error"


def test_subscription_explicit_transport_depth_and_raw() -> None:
    node = FakeNode()
    got: list[Image] = []
    image_transport_subscription(node, "depth/image_raw", got.append, transport="compressedDepth")
    _, callback, _ = node.subs["depth/image_raw/compressedDepth"]
    mm = np.arange(12, dtype=np.uint16).reshape(3, 4)
    callback(compress_depth(image(mm, "16UC1")))
    np.testing.assert_array_equal(image_to_numpy(got[0]), mm)
    image_transport_subscription(node, "cam/image_raw", got.append, desired_encoding="bgr8")
    msg_type, callback, _ = node.subs["cam/image_raw"]
    assert msg_type is Image
    callback(image(smooth_rgb(), "rgb8"))
    assert got[1].encoding == "bgr8"
    np.testing.assert_array_equal(image_to_numpy(got[1]), smooth_rgb()[..., ::-1])
    with pytest.raises(ImageTransportError, match="transport 'theora'"):
        image_transport_subscription(node, "cam/image_raw/theora", got.append)


# -------------------------------------------------------------- real graph


def test_publisher_and_subscription_on_the_graph() -> None:
    from visnav.graph import Context, Node

    with Context(transport="local") as ctx:
        node = Node("camera", namespace="/cam", context=ctx)
        pub = ImageTransportPublisher(node, "image_raw", 5, ("raw", "compressed"), format="png")
        raw_in: list[Image] = []
        png_in: list[Image] = []
        image_transport_subscription(node, "image_raw", raw_in.append, 5)
        image_transport_subscription(node, "/cam/image_raw/compressed", png_in.append, 5)
        rgb = smooth_rgb()
        pub.publish(image(rgb, "rgb8"))
        ctx.spin_until(lambda: bool(raw_in and png_in), 2.0)
        assert png_in[0].encoding == "rgb8"
        assert png_in[0].header.frame_id == "camera_optical"
        np.testing.assert_array_equal(image_to_numpy(png_in[0]), rgb)
        np.testing.assert_array_equal(image_to_numpy(raw_in[0]), rgb)
