"""image_proc algorithms: debayer patterns, mono/colour outputs, rectify."""

from __future__ import annotations

import numpy as np
import pytest

from visnav.msgs import Header, Time
from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.perception import (
    DEBAYER_BILINEAR,
    DEBAYER_EDGE_AWARE,
    DEBAYER_EDGE_AWARE_WEIGHTED,
    DEBAYER_VNG,
    CameraModelError,
    ImageProcError,
    PinholeCameraModel,
    Rectifier,
    debayer,
    image_color,
    image_mono,
    to_color,
    to_mono,
)

RGB = (200, 100, 50)
# Which colour each ROS pattern puts at (row, col) of a 2 x 2 cell.
PATTERNS = {
    "rggb": ("R", "G", "G", "B"),
    "bggr": ("B", "G", "G", "R"),
    "gbrg": ("G", "B", "R", "G"),
    "grbg": ("G", "R", "B", "G"),
}


def _mosaic(pattern: str, h: int = 16, w: int = 20, scale: int = 1) -> np.ndarray:
    value = dict(zip("RGB", RGB, strict=True))
    cell = np.array([value[c] * scale for c in PATTERNS[pattern]]).reshape(2, 2)
    dtype = np.uint16 if scale > 1 else np.uint8
    return np.tile(cell, (h // 2, w // 2)).astype(dtype)


def _header():
    return Header(stamp=Time(sec=4, nanosec=5), frame_id="camera_optical")


@pytest.mark.parametrize("pattern", list(PATTERNS))
@pytest.mark.parametrize(
    "algorithm", [DEBAYER_BILINEAR, DEBAYER_EDGE_AWARE, DEBAYER_EDGE_AWARE_WEIGHTED, DEBAYER_VNG]
)
@pytest.mark.parametrize("bits", [8, 16])
def test_debayer_maps_ros_patterns_to_the_right_colours(pattern, algorithm, bits):
    scale = 1 if bits == 8 else 256
    raw = _mosaic(pattern, scale=scale)
    bgr = debayer(raw, f"bayer_{pattern}{bits}", algorithm=algorithm)
    assert bgr.shape == (*raw.shape, 3)
    assert bgr.dtype == raw.dtype
    inner = bgr[4:-4, 4:-4].reshape(-1, 3).astype(float) / scale
    np.testing.assert_allclose(inner, np.tile(RGB[::-1], (inner.shape[0], 1)), atol=1.0)


def test_debayer_rejects_bad_input():
    with pytest.raises(ImageProcError, match="'rgb8'"):
        debayer(np.zeros((4, 4), np.uint8), "rgb8")
    with pytest.raises(ImageProcError, match="algorithm is 7"):
        debayer(np.zeros((4, 4), np.uint8), "bayer_rggb8", algorithm=7)


def test_mono_outputs():
    mono, enc = to_mono(_mosaic("grbg"), "bayer_grbg8")
    assert enc == "mono8"
    expected = 0.299 * RGB[0] + 0.587 * RGB[1] + 0.114 * RGB[2]
    assert np.abs(mono[4:-4, 4:-4].astype(float) - expected).max() <= 1.0
    mono16, enc16 = to_mono(_mosaic("rggb", scale=256), "bayer_rggb16")
    assert enc16 == "mono16"
    assert mono16.dtype == np.uint16
    rgb = np.zeros((4, 4, 3), np.uint8)
    rgb[...] = RGB
    grey, enc = to_mono(rgb, "rgb8")
    assert enc == "mono8"
    assert abs(int(grey[0, 0]) - expected) <= 1
    grey_bgr, _ = to_mono(rgb[..., ::-1].copy(), "bgr8")
    np.testing.assert_array_equal(grey_bgr, grey)
    with pytest.raises(ImageProcError, match="32FC1"):
        to_mono(np.zeros((4, 4), np.float32), "32FC1")


def test_colour_outputs():
    rgb = np.zeros((4, 6, 3), np.uint8)
    same, enc = to_color(rgb, "rgb8")
    assert same is rgb
    assert enc == "rgb8"
    mono = np.zeros((4, 6), np.uint8)
    assert to_color(mono, "mono8")[1] == "mono8"
    bgr, enc = to_color(_mosaic("bggr"), "bayer_bggr8", algorithm=DEBAYER_BILINEAR)
    assert enc == "bgr8"
    assert bgr.shape == (16, 20, 3)
    uyvy = np.full((4, 6, 2), 128, np.uint8)  # grey: U = V = 128, Y = 128
    colour, enc = to_color(uyvy, "yuv422")
    assert enc == "bgr8"
    # BT.601 video range: 1.164 * (Y - 16) on every channel.
    assert (colour == round(1.164 * (128 - 16))).all()
    with pytest.raises(ImageProcError, match="ambiguous"):
        to_color(np.zeros((4, 6, 3), np.uint8), "8UC3")


def test_message_functions():
    raw = numpy_to_image(_mosaic("rggb", scale=256), "bayer_rggb16", header=_header())
    colour = image_color(raw, algorithm=DEBAYER_BILINEAR)
    assert colour.encoding == "bgr16"
    assert colour.header.frame_id == "camera_optical"
    assert colour.header.stamp.sec == 4
    pixels = image_to_numpy(colour)
    np.testing.assert_allclose(pixels[6, 6] / 256, RGB[::-1], atol=1)
    mono = image_mono(raw)
    assert mono.encoding == "mono16"
    mono_msg = numpy_to_image(np.zeros((4, 4), np.uint8), "mono8", header=_header())
    assert image_mono(mono_msg) is mono_msg
    assert image_color(mono_msg) is mono_msg
    # VNG (ROS 2's default) on 16-bit Bayer falls back to bilinear.
    assert image_color(raw).encoding == "bgr16"


def test_rectifier(plumb_info, make_info):
    rectifier = Rectifier()
    rng = np.random.default_rng(2)
    image = numpy_to_image(
        rng.integers(0, 255, (480, 640, 3), dtype=np.uint8), "rgb8", header=_header()
    )
    info = plumb_info()
    rect = rectifier.rectify(image, info)
    assert rect.encoding == "rgb8"
    assert rect.header.frame_id == "camera_optical"
    expected = PinholeCameraModel.from_camera_info(info).rectify_image(image_to_numpy(image))
    np.testing.assert_array_equal(image_to_numpy(rect), expected)
    maps = rectifier.model.rectification_maps()
    rectifier.rectify(image, plumb_info(stamp=(80, 0)))
    assert rectifier.model.rectification_maps() is maps
    # No distortion: the same message comes back (image_proc passes it on).
    assert rectifier.rectify(image, make_info(d=[0.0] * 5)) is image
    with pytest.raises(ImageProcError, match="uncalibrated"):
        rectifier.rectify(image, make_info(k=[0.0] * 9, p=[1.0] * 12))
    with pytest.raises(CameraModelError, match="shape"):
        rectifier.rectify(numpy_to_image(np.zeros((10, 10), np.uint8), "mono8"), info)
