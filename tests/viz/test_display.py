"""Images to display RGB (no Rerun needed): depth scaling, encodings, PNG writing."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from visnav.msgs import numpy_to_image
from visnav.perception.image_transport import compress, compress_depth
from visnav.viz.display import (
    colormap_lut,
    depth_to_metres,
    image_to_display,
    message_to_display,
    scale_to_uint8,
    write_png,
)
from visnav.viz.errors import VizError


def test_depth_32f_scaled_min_to_max_invalid_black() -> None:
    depth = np.array([[1.0, 2.0, 3.0, np.nan, 0.0, np.inf]], np.float32)
    rgb = image_to_display(depth, "32FC1")
    assert rgb.shape == (1, 6, 3)
    assert rgb.dtype == np.uint8
    assert rgb[0, :, 0].tolist() == [0, 128, 255, 0, 0, 0]
    assert (rgb[..., 0] == rgb[..., 2]).all()  # gray


def test_depth_16u_is_millimetres_and_range_is_honoured() -> None:
    mm = np.array([[500, 1000, 4000, 0]], np.uint16)
    assert np.allclose(depth_to_metres(mm, "16UC1")[0, :3], [0.5, 1.0, 4.0])
    rgb = image_to_display(mm, "16UC1", value_range=(0.0, 2.0))
    assert rgb[0, :, 0].tolist() == [64, 128, 255, 0]


def test_colormap_turbo_differs_from_gray() -> None:
    depth = np.linspace(1.0, 5.0, 20, dtype=np.float32).reshape(4, 5)
    turbo = image_to_display(depth, "32FC1", colormap="turbo")
    assert not (turbo[..., 0] == turbo[..., 2]).all()
    assert tuple(colormap_lut("turbo")[0]) != tuple(colormap_lut("turbo")[255])
    with pytest.raises(VizError, match="colour map 'nope'"):
        colormap_lut("nope")


@pytest.mark.parametrize(
    ("encoding", "array", "expected_rgb"),
    [
        ("rgb8", np.array([[[10, 20, 30]]], np.uint8), (10, 20, 30)),
        ("bgr8", np.array([[[10, 20, 30]]], np.uint8), (30, 20, 10)),
        ("rgba8", np.array([[[10, 20, 30, 40]]], np.uint8), (10, 20, 30)),
        ("mono8", np.array([[77]], np.uint8), (77, 77, 77)),
        ("mono16", np.array([[65535]], np.uint16), (255, 255, 255)),
        ("bgr16", np.array([[[0, 0, 65535]]], np.uint16), (255, 0, 0)),
        ("8UC3", np.array([[[10, 20, 30]]], np.uint8), (30, 20, 10)),
    ],
)
def test_encodings_to_rgb(encoding: str, array: np.ndarray, expected_rgb: tuple[int, ...]) -> None:
    assert tuple(image_to_display(array, encoding)[0, 0]) == expected_rgb


def test_bayer_and_yuv_are_converted() -> None:
    bayer = np.zeros((4, 4), np.uint8)
    bayer[0::2, 0::2] = 200  # R sites of RGGB
    rgb = image_to_display(bayer, "bayer_rggb8")
    assert rgb.shape == (4, 4, 3)
    assert rgb[..., 0].mean() > rgb[..., 2].mean()
    yuyv = np.full((2, 4, 2), 128, np.uint8)
    assert image_to_display(yuyv, "yuyv").shape == (2, 4, 3)
    assert image_to_display(yuyv, "uyvy").shape == (2, 4, 3)


def test_one_channel_float_image_is_scaled() -> None:
    arr = np.array([[-1.0, 1.0]], np.float64)
    assert image_to_display(arr, "64FC1")[0, :, 0].tolist() == [0, 255]


def test_unshowable_encoding_is_refused() -> None:
    with pytest.raises(VizError, match="cannot be shown"):
        image_to_display(np.zeros((2, 2, 2), np.float32), "32FC2")
    with pytest.raises(VizError, match="empty or reversed"):
        scale_to_uint8(np.zeros((2, 2)), (1.0, 1.0))


def test_compressed_messages_decode() -> None:
    img = numpy_to_image(np.full((8, 8, 3), (200, 20, 20), np.uint8), "rgb8")
    rgb = message_to_display(compress(img, format="png"))
    assert tuple(rgb[0, 0]) == (200, 20, 20)
    depth = numpy_to_image(np.full((4, 4), 2.0, np.float32), "32FC1")
    gray = message_to_display(compress_depth(depth), value_range=(0.0, 4.0))
    assert abs(int(gray[0, 0, 0]) - 128) <= 1


def test_write_png_round_trip_and_errors(tmp_path: Path) -> None:
    rgb = np.zeros((3, 4, 3), np.uint8)
    rgb[..., 0] = 255
    out = write_png(tmp_path / "x.png", rgb)
    back = cv2.imread(str(out))
    assert back is not None
    assert tuple(back[0, 0]) == (0, 0, 255)  # BGR on disk: red
    with pytest.raises(VizError, match=r"must end in \.png"):
        write_png(tmp_path / "x.jpg", rgb)
    with pytest.raises(VizError, match="does not exist"):
        write_png(tmp_path / "missing" / "x.png", rgb)


@settings(max_examples=50, deadline=None)
@given(
    arrays(
        np.float32,
        st.tuples(st.integers(1, 8), st.integers(1, 8)),
        elements=st.floats(0.25, 100.0, width=32),
    )
)
def test_depth_scaling_is_monotone(depth: np.ndarray) -> None:
    gray = image_to_display(depth, "32FC1")[..., 0].astype(int).ravel()
    order = np.argsort(depth.ravel(), kind="stable")
    assert (np.diff(gray[order]) >= 0).all()
    if depth.max() > depth.min():
        assert gray.min() == 0
        assert gray.max() == 255
