"""RVL, compressedDepth's second codec: a stream built nibble by nibble, round trips, bad data."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.msgs.types import CompressedImage, Header, Time
from visnav.perception.rvl_codec import RvlError, compress_rvl, decompress_rvl
from visnav.perception.transport_codecs import (
    ImageTransportError,
    compress_depth,
    decompress,
    decompress_depth,
)

HEADER = Header(stamp=Time(sec=3, nanosec=4), frame_id="depth_optical")

# 2x3 pixels 0 0 1000 / 1001 0 7, coded by hand from the RVL description:
# zeros 2 -> nibble 2; nonzeros 2 -> 2; 1000: zigzag(1000) = 2000 = 3-bit groups 0,2,7,3
# (LSB first) -> nibbles 8 A F 3; 1001: zigzag(1) = 2 -> 2; zeros 1 -> 1; nonzeros 1 -> 1;
# 7: zigzag(7 - 1001) = 1987 = groups 3,0,7,3 -> B 8 F 3. Nibbles packed from the top of
# each 32-bit word: 0x228AF321, 0x1B8F3 then three padding nibbles: 0x1B8F3000, stored
# little endian after uint32 cols = 3, rows = 2.
PIXELS = np.array([[0, 0, 1000], [1001, 0, 7]], np.uint16)
STREAM = struct.pack("<II", 3, 2) + bytes.fromhex("21f38a22" + "00308f1b")


def test_hand_built_stream_decodes_and_encodes_byte_for_byte() -> None:
    np.testing.assert_array_equal(decompress_rvl(STREAM), PIXELS)
    assert compress_rvl(PIXELS) == STREAM


def test_ros_written_rvl_messages_decode() -> None:
    """``32FC1`` and ``16UC1`` messages laid out as compressed_depth_image_transport's rvl."""
    a, b = 10100.0, -1009.0  # depth_quantization 100, depth_max 10 (ROS defaults)
    data = struct.pack("<iff", 0, a, b) + STREAM
    msg = CompressedImage(
        header=HEADER, format="32FC1; compressedDepth rvl", data=np.frombuffer(data, np.uint8)
    )
    out = image_to_numpy(decompress(msg))
    assert out.dtype == np.float32
    assert np.isnan(out[PIXELS == 0]).all()
    expected = np.float32(a) / (PIXELS[PIXELS > 0].astype(np.float32) - np.float32(b))
    np.testing.assert_allclose(out[PIXELS > 0], expected, rtol=1e-6)
    mm = CompressedImage(
        header=HEADER,
        format="16UC1; compressedDepth rvl",
        data=np.frombuffer(bytes(12) + STREAM, np.uint8),
    )
    back = decompress_depth(mm)
    assert back.encoding == "16UC1"
    assert back.header.frame_id == "depth_optical"
    np.testing.assert_array_equal(image_to_numpy(back), PIXELS)


def test_compress_depth_rvl_round_trip() -> None:
    depth = np.array([[1.0, 3.0, np.nan], [5.0, 0.0, 2.5]], np.float32)
    msg = compress_depth(numpy_to_image(depth, "32FC1", header=HEADER), compression_format="rvl")
    assert msg.format == "32FC1; compressedDepth rvl"
    assert struct.unpack_from("<II", bytes(msg.data), 12) == (3, 2)
    out = image_to_numpy(decompress(msg))
    assert np.isnan(out[0, 2])
    assert np.isnan(out[1, 1])
    ok = np.isfinite(depth) & (depth > 0)
    np.testing.assert_allclose(out[ok], depth[ok], atol=3e-3)
    with pytest.raises(ImageTransportError, match="compression_format"):
        compress_depth(numpy_to_image(depth, "32FC1"), compression_format="jpeg")


@settings(max_examples=60, deadline=None)
@given(
    hnp.arrays(
        np.uint16,
        st.tuples(st.integers(1, 9), st.integers(1, 9)),
        elements=st.one_of(st.just(0), st.integers(0, 65535)),
    )
)
def test_round_trip_property(pixels: np.ndarray) -> None:
    np.testing.assert_array_equal(decompress_rvl(compress_rvl(pixels)), pixels)


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (b"\x01\x00", "expected uint32 cols"),
        (struct.pack("<II", 0, 5), "pixels"),
        (struct.pack("<II", 1 << 20, 1 << 20), "pixels"),
        (struct.pack("<II", 3, 2) + bytes.fromhex("21f38a22"), "ends before"),
        (struct.pack("<II", 2, 1) + bytes.fromhex("00000030"), "counts more pixels"),
    ],
)
def test_bad_streams_are_refused(data: bytes, match: str) -> None:
    with pytest.raises(RvlError, match=match):
        decompress_rvl(data)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=64), st.integers(1, 6), st.integers(1, 6))
def test_fuzzed_streams_decode_or_raise(body: bytes, cols: int, rows: int) -> None:
    try:
        out = decompress_rvl(struct.pack("<II", cols, rows) + body)
    except RvlError:
        return
    assert out.shape == (rows, cols)
