"""Images as a person sees them: any ``sensor_msgs/Image`` encoding to 8-bit RGB.

The conversion ``rqt_image_view`` (through cv_bridge's ``cvtColorForDisplay``) makes,
without a display: colour and Bayer encodings become RGB, 16-bit colour is scaled to
8 bits, and depth (``32FC1`` metres, ``16UC1`` millimetres) and other one-channel
numeric images are scaled linearly from a range (default: the image's own valid
minimum .. maximum) to black .. white, or through a colour map. Invalid depth (NaN,
infinite, zero) is black.

This module does not need Rerun: ``visnav image view --snapshot`` uses it on
machines without the viewer extra.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import image_to_numpy, is_bayer, is_color, is_mono, yuv422_yuy2_to_rgb
from visnav.msgs.types import CompressedImage, Image
from visnav.perception.image_transport import convert_encoding, decompress
from visnav.viz.errors import VizError

__all__ = [
    "COLORMAPS",
    "colormap_lut",
    "depth_to_metres",
    "image_to_display",
    "message_to_display",
    "scale_to_uint8",
    "write_png",
]

COLORMAPS: dict[str, int] = {
    "gray": -1,
    "turbo": cv2.COLORMAP_TURBO,
    "jet": cv2.COLORMAP_JET,
    "viridis": cv2.COLORMAP_VIRIDIS,
    "inferno": cv2.COLORMAP_INFERNO,
    "bone": cv2.COLORMAP_BONE,
}
"""Colour maps for one-channel images, by name (``gray`` is no colour map)."""


@functools.lru_cache(maxsize=len(COLORMAPS))
def colormap_lut(name: str) -> NDArray[np.uint8]:
    """Return a colour map as a read-only (256, 3) uint8 RGB lookup table.

    Raises:
        VizError: an unknown colour map name.
    """
    if name not in COLORMAPS:
        text = f"colour map {name!r} is unknown: choose one of {', '.join(COLORMAPS)}"
        raise VizError(text)
    ramp = np.arange(256, dtype=np.uint8).reshape(256, 1)
    if COLORMAPS[name] < 0:
        lut: NDArray[Any] = np.repeat(ramp, 3, axis=1)
    else:
        lut = np.asarray(cv2.applyColorMap(ramp, COLORMAPS[name])).reshape(256, 3)[:, ::-1]
    out = np.ascontiguousarray(lut, dtype=np.uint8)
    out.flags.writeable = False
    return out


def depth_to_metres(array: NDArray[Any], encoding: str) -> NDArray[np.float32]:
    """Return a REP 118 depth image in metres, float32, invalid pixels NaN.

    Args:
        array: the pixels (``32FC1`` metres or ``16UC1`` millimetres).
        encoding: their encoding.

    Raises:
        VizError: another encoding.
    """
    if encoding == "32FC1":
        out = np.array(array, dtype=np.float32)
        out[~np.isfinite(out) | (out <= 0)] = np.nan
        return out
    if encoding == "16UC1":
        mm: NDArray[np.float32] = array.astype(np.float32) * np.float32(0.001)
        mm[array == 0] = np.nan
        return mm
    text = f"encoding {encoding!r} is not a depth image: expected 32FC1 (m) or 16UC1 (mm)"
    raise VizError(text)


def scale_to_uint8(
    values: NDArray[Any],
    value_range: tuple[float, float] | None = None,
    *,
    colormap: str = "gray",
) -> NDArray[np.uint8]:
    """Scale a one-channel array linearly to 0..255 and colour it: (H, W, 3) RGB uint8.

    Args:
        values: the array; NaN and infinite values are invalid (black).
        value_range: the values shown as black .. white (first and last colour);
            default the finite minimum .. maximum.
        colormap: a name from :data:`COLORMAPS`.

    Raises:
        VizError: an empty or reversed range, or an unknown colour map.
    """
    lut = colormap_lut(colormap)
    data = np.asarray(values, dtype=np.float32)
    valid = np.isfinite(data)
    if value_range is None:
        if valid.any():
            lo, hi = float(data[valid].min()), float(data[valid].max())
        else:
            lo, hi = 0.0, 1.0
        if hi <= lo:
            hi = lo + 1.0
    else:
        lo, hi = float(value_range[0]), float(value_range[1])
        if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
            text = f"value range {value_range!r} is empty or reversed: expected MIN < MAX"
            raise VizError(text)
    with np.errstate(invalid="ignore"):
        scaled = (np.clip(data, lo, hi) - np.float32(lo)) * np.float32(255.0 / (hi - lo))
    index = np.where(valid, np.rint(scaled), 0).astype(np.uint8)
    rgb: NDArray[np.uint8] = lut[index]
    rgb[~valid] = 0
    return rgb


def image_to_display(
    array: NDArray[Any],
    encoding: str,
    *,
    value_range: tuple[float, float] | None = None,
    colormap: str = "gray",
) -> NDArray[np.uint8]:
    """Convert image pixels of any ROS encoding to (H, W, 3) uint8 RGB for display.

    Args:
        array: the pixels as :func:`visnav.msgs.image.image_to_numpy` returns them.
        encoding: their ROS encoding.
        value_range: for depth and other one-channel numeric images, the values shown
            as black .. white (metres for depth); default the image's valid min .. max.
        colormap: the colour map of one-channel numeric images (:data:`COLORMAPS`).

    Raises:
        VizError: an encoding that cannot be shown (named with the fix).
    """
    if encoding in ("32FC1", "16UC1"):
        return scale_to_uint8(depth_to_metres(array, encoding), value_range, colormap=colormap)
    if encoding == "mono8" and colormap == "gray" and value_range is None:
        return np.ascontiguousarray(np.repeat(array[..., None], 3, axis=2))
    if is_color(encoding) or is_mono(encoding) or is_bayer(encoding):
        rgb: NDArray[np.uint8] = convert_encoding(array, encoding, "rgb8")
        return rgb
    if encoding in ("yuv422_yuy2", "yuyv"):
        return yuv422_yuy2_to_rgb(array)
    if encoding in ("yuv422", "uyvy"):
        return np.asarray(cv2.cvtColor(np.ascontiguousarray(array), cv2.COLOR_YUV2RGB_UYVY))
    if array.ndim == 2 or (array.ndim == 3 and array.shape[2] == 1):
        return scale_to_uint8(array.reshape(array.shape[:2]), value_range, colormap=colormap)
    if array.ndim == 3 and array.shape[2] in (3, 4) and array.dtype == np.uint8:
        return np.ascontiguousarray(array[..., 2::-1])  # cv_bridge: 8UC3/8UC4 are BGR(A)
    text = (
        f"encoding {encoding!r} (array {array.dtype} {array.shape}) cannot be shown: "
        "expected a colour, mono, Bayer, YUV 4:2:2, depth or one-channel encoding"
    )
    raise VizError(text)


def message_to_display(
    msg: Image | CompressedImage,
    *,
    value_range: tuple[float, float] | None = None,
    colormap: str = "gray",
) -> NDArray[np.uint8]:
    """Decode an Image or CompressedImage (compressed / compressedDepth) to RGB uint8.

    Arguments as :func:`image_to_display`.

    Raises:
        VizError: an encoding that cannot be shown.
        ImageTransportError: undecodable compressed data.
        MessageError: an inconsistent Image message.
    """
    # By type name, not isinstance: messages read from bags come from other type stores.
    if getattr(msg, "__msgtype__", "") == "sensor_msgs/msg/CompressedImage":
        image = decompress(cast("CompressedImage", msg))
    else:
        image = cast("Image", msg)
    return image_to_display(
        image_to_numpy(image), image.encoding, value_range=value_range, colormap=colormap
    )


def write_png(path: str | Path, rgb: NDArray[np.uint8]) -> Path:
    """Write an (H, W, 3) RGB uint8 image as PNG; return the path.

    Raises:
        VizError: the file cannot be written (the directory is missing, ...).
    """
    out = Path(path)
    if out.suffix.lower() != ".png":
        text = f"snapshot path {str(out)!r} must end in .png"
        raise VizError(text)
    if not out.parent.is_dir():
        text = f"cannot write {str(out)!r}: directory {str(out.parent)!r} does not exist"
        raise VizError(text)
    ok = cv2.imwrite(str(out), np.ascontiguousarray(rgb[..., ::-1]))
    if not ok:
        text = f"cannot write {str(out)!r}: OpenCV refused the file (permissions? disk full?)"
        raise VizError(text)
    return out
