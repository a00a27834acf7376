"""Images as Rerun archetypes for display: JPEG colour, 16-bit depth, encodings' colour models."""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import image_to_numpy
from visnav.viz._rerun import rr
from visnav.viz.display import image_to_display
from visnav.viz.errors import VizError

__all__ = [
    "COLOR_MODELS",
    "DEPTH_METER",
    "PIXEL_FORMATS",
    "depth_archetype",
    "image_archetype",
    "jpeg_archetype",
]

COLOR_MODELS: dict[str, Literal["L", "RGB", "RGBA", "BGR", "BGRA"]] = {
    "rgb8": "RGB",
    "bgr8": "BGR",
    "rgba8": "RGBA",
    "bgra8": "BGRA",
    "rgb16": "RGB",
    "bgr16": "BGR",
    "rgba16": "RGBA",
    "bgra16": "BGRA",
    "mono8": "L",
    "mono16": "L",
    "8UC1": "L",
}
PIXEL_FORMATS = {
    "bayer_rggb8": "BayerRGGB8",
    "bayer_bggr8": "BayerBGGR8",
    "bayer_gbrg8": "BayerGBRG8",
    "bayer_grbg8": "BayerGRBG8",
    "yuv422_yuy2": "YUY2",
    "yuyv": "YUY2",
}
DEPTH_METER = {"32FC1": 1.0, "16UC1": 1000.0}


def jpeg_archetype(rgb: NDArray[np.uint8], quality: int) -> Any:
    """An RGB (or grey) image as a JPEG ``EncodedImage`` (OpenCV releases the GIL)."""
    import cv2  # noqa: PLC0415 (OpenCV is a dependency; loaded with the first image)

    bgr = rgb[..., ::-1] if rgb.ndim == 3 else rgb
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(bgr), [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        text = f"OpenCV could not JPEG-encode a {rgb.shape} {rgb.dtype} image"
        raise VizError(text)
    return rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg")


def depth_archetype(array: NDArray[Any], encoding: str) -> Any:
    """Depth as 16-bit millimetres (half the bytes of 32FC1; 0 = no return)."""
    if encoding == "32FC1":
        mm = np.nan_to_num(np.asarray(array, dtype=np.float32) * 1000.0, nan=0.0, posinf=0.0)
        return rr.DepthImage(np.clip(mm, 0, 65535).astype(np.uint16), meter=1000.0)
    return rr.DepthImage(array, meter=DEPTH_METER.get(encoding, 1.0))


def image_archetype(msg: Any, jpeg_quality: int | None = None) -> Any:
    """A ``sensor_msgs/Image`` for display: JPEG colour (or raw), 16-bit depth, Bayer/YUV as is."""
    encoding = msg.encoding
    if encoding in PIXEL_FORMATS:
        data = np.asarray(image_to_numpy(msg))
        return rr.Image(
            bytes=np.ascontiguousarray(data).tobytes(),
            width=int(msg.width),
            height=int(msg.height),
            pixel_format=getattr(rr.PixelFormat, PIXEL_FORMATS[encoding]),
        )
    array = image_to_numpy(msg)
    if encoding in DEPTH_METER:
        return depth_archetype(array, encoding)
    if jpeg_quality is not None:
        return jpeg_archetype(image_to_display(array, encoding), jpeg_quality)
    if encoding in COLOR_MODELS:
        return rr.Image(array, color_model=COLOR_MODELS[encoding])
    return rr.Image(image_to_display(array, encoding), color_model="RGB")
