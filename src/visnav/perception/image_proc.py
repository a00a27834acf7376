"""image_proc's algorithms: debayer (``image_mono``, ``image_color``) and rectify.

As image_proc's ``debayer`` and ``rectify`` components:

* ``image_mono``: mono images pass through; colour, Bayer and YUV 4:2:2 images
  are converted to ``mono8`` (8-bit sources) or ``mono16`` (16-bit sources) as
  cv_bridge does (``cv2.cvtColor``).
* ``image_color``: colour images (``rgb8``, ``bgra16``, ...) pass through
  unchanged, mono images pass through (image_proc warns), Bayer images are
  demosaiced with OpenCV into ``bgr8`` / ``bgr16``, ``yuv422`` (UYVY) becomes
  ``bgr8``; ``8UC3`` is rejected as ambiguous.
* Demosaicing algorithms are image_proc's ``debayer`` parameter values:
  :data:`DEBAYER_BILINEAR` (0), :data:`DEBAYER_EDGE_AWARE` (1),
  :data:`DEBAYER_EDGE_AWARE_WEIGHTED` (2), :data:`DEBAYER_VNG` (3, the ROS 2
  default). ROS names Bayer patterns by the first row, OpenCV by the second:
  ``bayer_rggb`` is OpenCV's ``BayerBG``, and so on.
* ``rectify``: a camera with ``K[0] == 0`` is uncalibrated (an error); a camera
  with no non-zero distortion coefficient gets the image message back unchanged;
  otherwise :meth:`PinholeCameraModel.rectify_image` with image_proc's
  ``interpolation`` parameter (default 1, bilinear).

Differences: both edge-aware modes use OpenCV's edge-aware demosaicing for every
pattern (image_proc has its own implementation for ``bayer_grbg8`` only and
falls back to bilinear otherwise); VNG on 16-bit Bayer, which OpenCV cannot do,
falls back to bilinear; ``yuv422_yuy2`` (YUYV) is accepted too; unsupported
input raises :class:`ImageProcError` where the node logs a warning.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import image_to_numpy, is_bayer, is_color, is_mono, numpy_to_image
from visnav.msgs.types import CameraInfo, Header, Image, Time
from visnav.perception.camera_model import PinholeCameraModel
from visnav.perception.errors import ImageProcError

__all__ = [
    "DEBAYER_BILINEAR",
    "DEBAYER_EDGE_AWARE",
    "DEBAYER_EDGE_AWARE_WEIGHTED",
    "DEBAYER_VNG",
    "Rectifier",
    "debayer",
    "image_color",
    "image_mono",
    "to_color",
    "to_mono",
]

DEBAYER_BILINEAR = 0
DEBAYER_EDGE_AWARE = 1
DEBAYER_EDGE_AWARE_WEIGHTED = 2
DEBAYER_VNG = 3

# ROS pattern (first row) -> OpenCV pattern (second row).
_BAYER_BGR = {
    "rggb": cv2.COLOR_BayerBG2BGR,
    "bggr": cv2.COLOR_BayerRG2BGR,
    "gbrg": cv2.COLOR_BayerGR2BGR,
    "grbg": cv2.COLOR_BayerGB2BGR,
}
_BAYER_GRAY = {
    "rggb": cv2.COLOR_BayerBG2GRAY,
    "bggr": cv2.COLOR_BayerRG2GRAY,
    "gbrg": cv2.COLOR_BayerGR2GRAY,
    "grbg": cv2.COLOR_BayerGB2GRAY,
}
_VNG_OFFSET = cv2.COLOR_BayerBG2BGR_VNG - cv2.COLOR_BayerBG2BGR
_EA_OFFSET = cv2.COLOR_BayerBG2BGR_EA - cv2.COLOR_BayerBG2BGR
_COLOR_GRAY = {
    "rgb8": cv2.COLOR_RGB2GRAY,
    "rgb16": cv2.COLOR_RGB2GRAY,
    "bgr8": cv2.COLOR_BGR2GRAY,
    "bgr16": cv2.COLOR_BGR2GRAY,
    "rgba8": cv2.COLOR_RGBA2GRAY,
    "rgba16": cv2.COLOR_RGBA2GRAY,
    "bgra8": cv2.COLOR_BGRA2GRAY,
    "bgra16": cv2.COLOR_BGRA2GRAY,
}
_YUV = {
    "yuv422": (cv2.COLOR_YUV2GRAY_UYVY, cv2.COLOR_YUV2BGR_UYVY),
    "uyvy": (cv2.COLOR_YUV2GRAY_UYVY, cv2.COLOR_YUV2BGR_UYVY),
    "yuv422_yuy2": (cv2.COLOR_YUV2GRAY_YUY2, cv2.COLOR_YUV2BGR_YUY2),
    "yuyv": (cv2.COLOR_YUV2GRAY_YUY2, cv2.COLOR_YUV2BGR_YUY2),
}


def _pattern(encoding: str) -> str:
    return encoding[len("bayer_") : len("bayer_") + 4]


def _unsupported(encoding: str, what: str) -> ImageProcError:
    if encoding == "8UC3":
        text = (
            "encoding '8UC3' is ambiguous (BGR? RGB? HSV?): the camera should publish 'bgr8' "
            "or 'rgb8'"
        )
    else:
        text = (
            f"encoding {encoding!r} cannot be turned into {what}: expected mono8/16, "
            "rgb(a)8/16, bgr(a)8/16, bayer_{rggb,bggr,gbrg,grbg}{8,16} or yuv422"
        )
    return ImageProcError(text)


def debayer(bayer: NDArray[Any], encoding: str, *, algorithm: int = DEBAYER_VNG) -> NDArray[Any]:
    """Demosaic a raw Bayer image into BGR (image_proc's debayer).

    Args:
        bayer: (H, W) uint8 or uint16 raw Bayer pixels.
        encoding: the ROS Bayer encoding, e.g. ``"bayer_rggb8"``.
        algorithm: one of the ``DEBAYER_*`` values.

    Returns:
        (H, W, 3) BGR with the input's dtype.

    Raises:
        ImageProcError: not a Bayer encoding, or an unknown algorithm.
    """
    if not is_bayer(encoding):
        raise _unsupported(encoding, "a debayered image")
    if algorithm not in (0, 1, 2, 3):
        text = (
            f"debayer algorithm is {algorithm!r}: expected 0 (bilinear), 1 (edge aware), "
            "2 (edge aware weighted) or 3 (VNG)"
        )
        raise ImageProcError(text)
    code = _BAYER_BGR[_pattern(encoding)]
    arr = np.asarray(bayer)
    if algorithm == DEBAYER_VNG and arr.dtype == np.uint8:
        code += _VNG_OFFSET
    elif algorithm in (DEBAYER_EDGE_AWARE, DEBAYER_EDGE_AWARE_WEIGHTED):
        code += _EA_OFFSET
    return np.asarray(cv2.cvtColor(arr, code))


def to_mono(image: NDArray[Any], encoding: str) -> tuple[NDArray[Any], str]:
    """Return ``(pixels, encoding)`` of the ``image_mono`` output for a raw image.

    Raises:
        ImageProcError: an encoding that has no grey version.
    """
    arr = np.asarray(image)
    if is_mono(encoding):
        return arr, encoding
    if is_bayer(encoding):
        gray = cv2.cvtColor(arr, _BAYER_GRAY[_pattern(encoding)])
    elif encoding in _COLOR_GRAY:
        gray = cv2.cvtColor(arr, _COLOR_GRAY[encoding])
    elif encoding in _YUV:
        gray = cv2.cvtColor(arr, _YUV[encoding][0])
    else:
        raise _unsupported(encoding, "mono8/mono16")
    out = np.asarray(gray)
    return out, "mono16" if out.dtype == np.uint16 else "mono8"


def to_color(
    image: NDArray[Any], encoding: str, *, algorithm: int = DEBAYER_VNG
) -> tuple[NDArray[Any], str]:
    """Return ``(pixels, encoding)`` of the ``image_color`` output for a raw image.

    Raises:
        ImageProcError: an encoding with no colour version (``8UC3`` is ambiguous).
    """
    arr = np.asarray(image)
    if is_mono(encoding) or is_color(encoding):
        return arr, encoding
    if is_bayer(encoding):
        bgr = debayer(arr, encoding, algorithm=algorithm)
        return bgr, "bgr16" if bgr.dtype == np.uint16 else "bgr8"
    if encoding in _YUV:
        return np.asarray(cv2.cvtColor(arr, _YUV[encoding][1])), "bgr8"
    raise _unsupported(encoding, "a colour image")


def _header(header: Header) -> Header:
    stamp = header.stamp
    return Header(
        stamp=Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec)), frame_id=header.frame_id
    )


def image_mono(raw_msg: Image) -> Image:
    """Return image_proc's ``image_mono`` for a raw image (the same message if already mono)."""
    if is_mono(raw_msg.encoding):
        return raw_msg
    pixels, encoding = to_mono(image_to_numpy(raw_msg), raw_msg.encoding)
    return numpy_to_image(pixels, encoding, header=_header(raw_msg.header))


def image_color(raw_msg: Image, *, algorithm: int = DEBAYER_VNG) -> Image:
    """Return image_proc's ``image_color`` (the same message if already colour or mono)."""
    if is_mono(raw_msg.encoding) or is_color(raw_msg.encoding):
        return raw_msg
    pixels, encoding = to_color(image_to_numpy(raw_msg), raw_msg.encoding, algorithm=algorithm)
    return numpy_to_image(pixels, encoding, header=_header(raw_msg.header))


class Rectifier:
    """image_proc's ``rectify``: ``image_mono`` -> ``image_rect``, colour -> ``image_rect_color``.

    Keeps one :class:`PinholeCameraModel`, so the maps are built once per calibration.

    Args:
        interpolation: a ``cv2.INTER_*`` flag (image_proc's ``interpolation``, default 1).
    """

    def __init__(self, *, interpolation: int = cv2.INTER_LINEAR) -> None:
        self.interpolation = interpolation
        self.model = PinholeCameraModel()

    def rectify(self, image_msg: Image, info_msg: CameraInfo) -> Image:
        """Return the rectified image (the input message itself if there is no distortion).

        Raises:
            ImageProcError: the camera is uncalibrated (``K[0] == 0``).
            CameraModelError: a camera_info the model cannot use, or an image of another size.
        """
        if float(info_msg.k[0]) == 0.0:
            text = (
                f"rectified image requested but the camera of frame "
                f"{info_msg.header.frame_id!r} is uncalibrated (CameraInfo.k[0] is 0); "
                "calibrate it (visnav calibrate) and load the result via camera_info_url"
            )
            raise ImageProcError(text)
        if not np.any(np.asarray(info_msg.d, dtype=np.float64)):
            return image_msg
        self.model.from_camera_info(info_msg)
        rect = self.model.rectify_image(image_to_numpy(image_msg), interpolation=self.interpolation)
        return numpy_to_image(rect, image_msg.encoding, header=_header(image_msg.header))
