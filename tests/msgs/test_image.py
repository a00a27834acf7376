"""Tests of visnav.msgs.image: Image <-> numpy with cv_bridge's encodings."""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.msgs import (
    Header,
    Image,
    MessageError,
    Time,
    deserialize,
    serialize,
    typestore,
)
from visnav.msgs.image import (
    bytes_per_pixel,
    encoding_dtype,
    has_alpha,
    image_to_numpy,
    is_bayer,
    is_color,
    is_depth,
    is_mono,
    num_channels,
    numpy_to_image,
    yuv422_yuy2_to_rgb,
)

# encoding -> (dtype, channels) as cv_bridge defines them
EXPECTED: dict[str, tuple[str, int]] = {
    "rgb8": ("u1", 3),
    "bgr8": ("u1", 3),
    "rgba8": ("u1", 4),
    "bgra8": ("u1", 4),
    "rgb16": ("u2", 3),
    "bgr16": ("u2", 3),
    "rgba16": ("u2", 4),
    "bgra16": ("u2", 4),
    "mono8": ("u1", 1),
    "mono16": ("u2", 1),
    "yuv422": ("u1", 2),
    "yuv422_yuy2": ("u1", 2),
    "bayer_rggb8": ("u1", 1),
    "bayer_bggr8": ("u1", 1),
    "bayer_gbrg8": ("u1", 1),
    "bayer_grbg8": ("u1", 1),
    "bayer_rggb16": ("u2", 1),
    "bayer_bggr16": ("u2", 1),
    "bayer_gbrg16": ("u2", 1),
    "bayer_grbg16": ("u2", 1),
    **{
        f"{depth}C{n}": (code, n)
        for depth, code in {
            "8U": "u1",
            "8S": "i1",
            "16U": "u2",
            "16S": "i2",
            "32S": "i4",
            "32F": "f4",
            "64F": "f8",
        }.items()
        for n in range(1, 5)
    },
    "32F": ("f4", 1),
    "8UC7": ("u1", 7),
}
ENCODINGS = sorted(EXPECTED)
NATIVE_BIG = sys.byteorder == "big"


def random_pixels(encoding: str, height: int, width: int, seed: int) -> np.ndarray:
    """Random bit patterns of the encoding's dtype (floats may be NaN/inf: compared bitwise)."""
    code, channels = EXPECTED[encoding]
    dtype = np.dtype(code)
    shape = (height, width) if channels == 1 else (height, width, channels)
    n_bytes = int(np.prod(shape)) * dtype.itemsize
    raw = np.random.default_rng(seed).integers(0, 256, n_bytes, dtype=np.uint8)
    return raw.view(dtype).reshape(shape)


def reference_bytes(arr: np.ndarray, step: int, *, big: bool) -> bytes:
    """Slow reference of the wire layout: each row in the given byte order, then zero pad."""
    dtype = arr.dtype.newbyteorder(">" if big else "<")
    rows = []
    for row in arr:
        raw = np.ascontiguousarray(row, dtype=dtype).tobytes()
        rows.append(raw + bytes(step - len(raw)))
    return b"".join(rows)


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def header() -> Header:
    return Header(stamp=Time(sec=12, nanosec=345), frame_id="camera_optical")


# ---------------------------------------------------------------- encodings


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_encoding_tables_match_cv_bridge(encoding: str) -> None:
    code, channels = EXPECTED[encoding]
    assert encoding_dtype(encoding) == np.dtype(code)
    assert encoding_dtype(encoding).isnative
    assert num_channels(encoding) == channels
    assert bytes_per_pixel(encoding) == np.dtype(code).itemsize * channels


def test_encoding_predicates() -> None:
    assert is_color("rgb8")
    assert is_color("bgra16")
    assert not is_color("mono8")
    assert not is_color("8UC3")
    assert is_mono("mono16")
    assert not is_mono("16UC1")
    assert is_bayer("bayer_grbg16")
    assert not is_bayer("bayer_xxxx8")
    assert has_alpha("rgba8")
    assert not has_alpha("rgb8")
    assert is_depth("32FC1")
    assert is_depth("16UC1")
    assert not is_depth("mono16")


@pytest.mark.parametrize(
    ("bad", "hint"),
    [("RGB8", "'rgb8'"), ("rbg8", "'rgb8'"), ("32FC", "'32FC1'"), ("mono_8", "'mono8'")],
)
def test_unknown_encoding_suggests_close_names(bad: str, hint: str) -> None:
    with pytest.raises(MessageError, match="not a known image encoding") as info:
        bytes_per_pixel(bad)
    assert hint in str(info.value)
    assert repr(bad) in str(info.value)


@pytest.mark.parametrize("bad", ["", "jpeg", "8UC0", "8UC513", "16FC1"])
def test_unknown_encoding_rejected(bad: str) -> None:
    with pytest.raises(MessageError, match="not a known image encoding"):
        numpy_to_image(np.zeros((2, 2), np.uint8), bad)


# ---------------------------------------------------------------- round trips


@settings(max_examples=300, deadline=None)
@given(
    encoding=st.sampled_from(ENCODINGS),
    height=st.integers(0, 9),
    width=st.integers(0, 9),
    pad=st.integers(0, 9),
    big=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_round_trip_every_encoding(
    encoding: str, height: int, width: int, pad: int, big: bool, seed: int
) -> None:
    arr = random_pixels(encoding, height, width, seed)
    row = width * bytes_per_pixel(encoding)
    msg = numpy_to_image(arr, encoding, step=row + pad, is_bigendian=big, header=header())
    assert (msg.height, msg.width, msg.step) == (height, width, row + pad)
    assert msg.encoding == encoding
    assert msg.is_bigendian == int(big)
    assert isinstance(msg.data, np.ndarray)
    assert msg.data.dtype == np.uint8
    assert msg.data.ndim == 1
    assert msg.data.flags.c_contiguous
    assert msg.data.tobytes() == reference_bytes(arr, row + pad, big=big)
    assert msg.header.frame_id == "camera_optical"
    if height == 0 or width == 0:  # a message may carry no pixels; OpenCV cannot take it
        with pytest.raises(MessageError, match=rf"is {width}x{height} .*at least 1x1"):
            image_to_numpy(msg)
        return
    if width % 2 and encoding in {"yuv422", "uyvy", "yuv422_yuy2", "yuyv"}:
        with pytest.raises(MessageError, match="expected an even width"):
            image_to_numpy(msg)
        return
    back = image_to_numpy(msg)
    assert back.dtype.isnative
    assert same_bits(back, arr)


@settings(max_examples=40, deadline=None)
@given(
    encoding=st.sampled_from(ENCODINGS),
    height=st.integers(1, 6),
    width=st.integers(1, 6),
    pad=st.integers(0, 5),
    big=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_round_trip_through_cdr(
    encoding: str, height: int, width: int, pad: int, big: bool, seed: int
) -> None:
    if encoding in {"yuv422", "uyvy", "yuv422_yuy2", "yuyv"}:
        width += width % 2  # 4:2:2 needs an even width
    arr = random_pixels(encoding, height, width, seed)
    step = width * bytes_per_pixel(encoding) + pad
    msg = numpy_to_image(arr, encoding, step=step, is_bigendian=big)
    got = deserialize(serialize(msg), "sensor_msgs/msg/Image")
    assert same_bits(image_to_numpy(got), arr)


def test_cdr_matches_rosbags_serializer_of_hand_built_message() -> None:
    arr = np.arange(3 * 5 * 3, dtype=np.uint8).reshape(3, 5, 3)
    msg = numpy_to_image(arr, "rgb8", header=header())
    hand = Image(
        header=Header(stamp=Time(sec=12, nanosec=345), frame_id="camera_optical"),
        height=3,
        width=5,
        encoding="rgb8",
        is_bigendian=0,
        step=15,
        data=np.frombuffer(arr.tobytes(), dtype=np.uint8),
    )
    expected = bytes(typestore().serialize_cdr(hand, "sensor_msgs/msg/Image"))
    assert serialize(msg) == expected
    # and 16-bit, big endian, padded
    depth = np.array([[1, 258], [65535, 4096]], dtype=np.uint16)
    msg16 = numpy_to_image(depth, "16UC1", step=6, is_bigendian=True)
    hand16 = Image(
        header=Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
        height=2,
        width=2,
        encoding="16UC1",
        is_bigendian=1,
        step=6,
        data=np.array([0, 1, 1, 2, 0, 0, 255, 255, 16, 0, 0, 0], dtype=np.uint8),
    )
    assert serialize(msg16) == bytes(typestore().serialize_cdr(hand16, "sensor_msgs/msg/Image"))


# ---------------------------------------------------------------- known bytes


def test_rgb8_pixel_layout() -> None:
    arr = np.zeros((2, 3, 3), np.uint8)
    arr[0, 1] = (10, 20, 30)
    arr[1, 2] = (40, 50, 60)
    data = numpy_to_image(arr, "rgb8").data
    assert list(data[3:6]) == [10, 20, 30]
    assert list(data[9 + 6 : 9 + 9]) == [40, 50, 60]


def test_float_and_16bit_byte_order() -> None:
    little = numpy_to_image(np.array([[1.0]], np.float32), "32FC1").data
    assert little.tobytes() == b"\x00\x00\x80\x3f"
    big = numpy_to_image(np.array([[1.0]], np.float32), "32FC1", is_bigendian=True).data
    assert big.tobytes() == b"\x3f\x80\x00\x00"
    assert numpy_to_image(np.array([[0x0102]], np.uint16), "mono16").data.tobytes() == b"\x02\x01"


def test_reads_hand_built_big_endian_message() -> None:
    msg = Image(
        header=header(),
        height=1,
        width=2,
        encoding="16UC1",
        is_bigendian=1,
        step=4,
        data=np.array([0x01, 0x02, 0xFF, 0x00], np.uint8),
    )
    out = image_to_numpy(msg)
    assert out.dtype == np.uint16
    assert out.dtype.isnative
    assert out.tolist() == [[0x0102, 0xFF00]]
    # the message is not modified
    assert msg.data.tolist() == [0x01, 0x02, 0xFF, 0x00]


def test_padded_step_reads_identical_pixels() -> None:
    rng = np.random.default_rng(7)
    arr = rng.integers(0, 256, (4, 5, 3), dtype=np.uint8)
    step = 5 * 3 + 7
    data = np.full(4 * step, 0xAB, np.uint8)  # garbage in the pad bytes
    for r in range(4):
        data[r * step : r * step + 15] = arr[r].reshape(-1)
    msg = Image(
        header=header(),
        height=4,
        width=5,
        encoding="bgr8",
        is_bigendian=0,
        step=step,
        data=data,
    )
    out = image_to_numpy(msg)
    np.testing.assert_array_equal(out, arr)
    assert out.flags.c_contiguous
    # also after a CDR round trip (data becomes a read-only view on the buffer)
    np.testing.assert_array_equal(
        image_to_numpy(deserialize(serialize(msg), "sensor_msgs/msg/Image")), arr
    )


def test_padded_step_not_multiple_of_element_size() -> None:
    depth = np.array([[1.5, -2.0, np.inf], [0.25, np.nan, 3.0]], np.float32)
    msg = numpy_to_image(depth, "32FC1", step=12 + 3)
    assert msg.data[12:15].tolist() == [0, 0, 0]
    out = image_to_numpy(msg)
    np.testing.assert_array_equal(out, depth)


def test_accepts_bytes_and_lists_as_data() -> None:
    msg = Image(
        header=header(),
        height=2,
        width=2,
        encoding="mono8",
        is_bigendian=0,
        step=2,
        data=b"\x01\x02\x03\x04",
    )
    assert image_to_numpy(msg).tolist() == [[1, 2], [3, 4]]
    msg.data = [5, 6, 7, 8]
    assert image_to_numpy(msg).tolist() == [[5, 6], [7, 8]]


# ---------------------------------------------------------------- copies and views


def test_read_is_zero_copy_without_padding_or_swap() -> None:
    arr = np.arange(12, dtype=np.uint16).reshape(3, 4)
    msg = numpy_to_image(arr, "mono16", is_bigendian=NATIVE_BIG)
    out = image_to_numpy(msg)
    assert np.shares_memory(out, msg.data)
    got = deserialize(serialize(msg), "sensor_msgs/msg/Image")
    view = image_to_numpy(got)
    assert np.shares_memory(view, got.data)
    assert not view.flags.writeable  # a view on the received bytes stays read-only


def test_read_copies_when_padded_or_swapped() -> None:
    arr = np.arange(12, dtype=np.uint16).reshape(3, 4)
    padded = numpy_to_image(arr, "mono16", step=10, is_bigendian=NATIVE_BIG)
    swapped = numpy_to_image(arr, "mono16", is_bigendian=not NATIVE_BIG)
    for msg in (padded, swapped):
        out = image_to_numpy(msg)
        assert not np.shares_memory(out, msg.data)
        assert out.flags.writeable
        np.testing.assert_array_equal(out, arr)


def test_write_copies_the_array() -> None:
    arr = np.zeros((2, 2), np.uint8)
    msg = numpy_to_image(arr, "mono8")
    arr[0, 0] = 9
    assert msg.data[0] == 0


def test_write_accepts_views_non_contiguous_and_swapped_input() -> None:
    big = np.arange(48, dtype=">u2").reshape(4, 4, 3)
    view = big[::2, ::-1]  # non-contiguous, non-native order
    msg = numpy_to_image(view, "rgb16")
    assert msg.is_bigendian == 0
    np.testing.assert_array_equal(image_to_numpy(msg), view)


def test_one_channel_shapes() -> None:
    arr = np.arange(6, dtype=np.uint8).reshape(2, 3, 1)
    msg = numpy_to_image(arr, "mono8")
    assert image_to_numpy(msg).shape == (2, 3)
    assert image_to_numpy(numpy_to_image(arr[..., 0], "8UC1")).shape == (2, 3)
    assert image_to_numpy(numpy_to_image(np.zeros((2, 3, 3), np.uint8), "8UC3")).shape == (2, 3, 3)


def test_default_header() -> None:
    msg = numpy_to_image(np.zeros((1, 1), np.uint8), "mono8")
    assert msg.header.frame_id == ""
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 0)


# ---------------------------------------------------------------- errors


def make(**overrides: Any) -> Image:
    fields: dict[str, Any] = {
        "header": header(),
        "height": 2,
        "width": 3,
        "encoding": "rgb8",
        "is_bigendian": 0,
        "step": 9,
        "data": np.zeros(18, np.uint8),
    }
    fields.update(overrides)
    return Image(**fields)


def test_error_data_length() -> None:
    with pytest.raises(MessageError, match=r"Image.data has 17 bytes: expected step \* height"):
        image_to_numpy(make(data=np.zeros(17, np.uint8)))
    with pytest.raises(MessageError, match="19 bytes"):
        image_to_numpy(make(data=np.zeros(19, np.uint8)))


def test_error_step_too_small() -> None:
    with pytest.raises(MessageError, match=r"Image.step is 8: expected at least .* = 9"):
        image_to_numpy(make(step=8, data=np.zeros(16, np.uint8)))


def test_error_unknown_encoding_on_read() -> None:
    with pytest.raises(MessageError, match=r"Image.encoding is 'rgb888'.*did you mean 'rgb8'"):
        image_to_numpy(make(encoding="rgb888"))


def test_error_data_dtype() -> None:
    with pytest.raises(MessageError, match=r"Image\.data has dtype uint16"):
        image_to_numpy(make(data=np.zeros(9, np.uint16)))


def test_error_wrong_dtype_on_write() -> None:
    with pytest.raises(MessageError, match=r"dtype float64: encoding '32FC1' needs float32"):
        numpy_to_image(np.zeros((2, 2)), "32FC1")
    with pytest.raises(MessageError, match=r"astype\(np.uint16\)"):
        numpy_to_image(np.zeros((2, 2), np.int16), "16UC1")
    with pytest.raises(MessageError, match="dtype bool"):
        numpy_to_image(np.zeros((2, 2), bool), "mono8")


def test_error_wrong_shape_on_write() -> None:
    with pytest.raises(MessageError, match=r"shape \(4, 4\): encoding 'rgb8' needs \(H, W, 3\)"):
        numpy_to_image(np.zeros((4, 4), np.uint8), "rgb8")
    with pytest.raises(MessageError, match=r"needs \(H, W, 4\)"):
        numpy_to_image(np.zeros((4, 4, 3), np.uint8), "bgra8")
    with pytest.raises(MessageError, match=r"needs \(H, W\) or \(H, W, 1\)"):
        numpy_to_image(np.zeros((4, 4, 2), np.uint8), "mono8")
    with pytest.raises(MessageError, match="shape"):
        numpy_to_image(np.zeros(4, np.uint8), "mono8")


def test_error_step_keyword_too_small() -> None:
    with pytest.raises(MessageError, match=r"step is 5: expected an int >= .* = 6"):
        numpy_to_image(np.zeros((2, 3), np.uint16), "mono16", step=5)


def test_message_error_is_value_error_and_visnav_error() -> None:
    with pytest.raises(ValueError, match="encoding"):
        numpy_to_image(np.zeros((1, 1), np.uint8), "nope")
    with pytest.raises(VisnavError):
        numpy_to_image(np.zeros((1, 1), np.uint8), "nope")


# ---------------------------------------------------------------- YUYV


def test_yuv422_yuy2_to_rgb_matches_opencv_round_trip() -> None:
    import cv2

    rgb = np.zeros((4, 8, 3), np.uint8)
    rgb[..., 0] = np.linspace(20, 230, 8, dtype=np.uint8)  # smooth ramps: chroma subsampling
    rgb[..., 1] = 120
    rgb[..., 2] = np.linspace(200, 40, 4, dtype=np.uint8)[:, None]
    yuyv = cv2.cvtColor(rgb, cv2.COLOR_RGB2YUV_YUY2)
    msg = numpy_to_image(yuyv, "yuv422_yuy2")
    assert msg.step == 16
    arr = image_to_numpy(msg)
    assert arr.shape == (4, 8, 2)
    back = yuv422_yuy2_to_rgb(arr)
    assert back.shape == (4, 8, 3)
    assert back.dtype == np.uint8
    assert np.abs(back.astype(int) - rgb.astype(int)).max() <= 16


def test_yuv422_yuy2_gray() -> None:
    yuyv = np.full((2, 2, 2), 128, np.uint8)
    np.testing.assert_allclose(yuv422_yuy2_to_rgb(yuyv), 128, atol=2)


def test_yuv422_yuy2_to_rgb_rejects_odd_width() -> None:
    with pytest.raises(MessageError, match="even W"):
        yuv422_yuy2_to_rgb(np.zeros((2, 3, 2), np.uint8))
