"""CameraInfo and point-array validation for :mod:`visnav.perception.camera_model` (internal).

Checks a ``sensor_msgs/CameraInfo`` once and returns the normalized calibration the
rectification maps depend on and the ROI; every problem is one
:class:`~visnav.perception.errors.CameraModelError` naming the field, the value and what
REP 104 expects.
"""

from __future__ import annotations

import difflib
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.perception.errors import CameraModelError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from visnav.msgs.types import CameraInfo

__all__ = [
    "DISTORTION_MODELS",
    "EQUIDISTANT",
    "OPENCV_D_LENGTHS",
    "PLUMB_BOB",
    "RATIONAL_POLYNOMIAL",
    "Calibration",
    "ParsedCameraInfo",
    "Roi",
    "RoiState",
    "as_points",
    "binned",
    "parse_camera_info",
    "shaped",
]

_LOG = logging.getLogger("visnav.perception.camera_model")

PLUMB_BOB = "plumb_bob"
RATIONAL_POLYNOMIAL = "rational_polynomial"
EQUIDISTANT = "equidistant"

#: Distortion models this camera model applies, with the length REP 104 gives ``D``.
DISTORTION_MODELS: dict[str, int] = {PLUMB_BOB: 5, RATIONAL_POLYNOMIAL: 8, EQUIDISTANT: 4}

#: Lengths of ``D`` OpenCV's pinhole model takes (``cv2.undistortPoints`` and friends):
#: k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tau_x tau_y]]]]. image_geometry hands ``D``
#: to OpenCV as it is, so a plumb_bob or rational_polynomial camera_info of any of
#: these lengths works in ROS.
OPENCV_D_LENGTHS: tuple[int, ...] = (4, 5, 8, 12, 14)

_COEFFICIENT_NAMES = {
    PLUMB_BOB: "k1, k2, p1, p2, k3",
    RATIONAL_POLYNOMIAL: "k1, k2, p1, p2, k3, k4, k5, k6",
    EQUIDISTANT: "k1, k2, k3, k4",
}
_OPENCV_NAMES = {
    4: "k1, k2, p1, p2; k3 = 0",
    5: "k1, k2, p1, p2, k3",
    8: "k1, k2, p1, p2, k3, k4, k5, k6",
    12: "k1..k6 and the thin-prism s1, s2, s3, s4",
    14: "k1..k6, s1..s4 and the tilt tau_x, tau_y",
}
Roi = tuple[int, int, int, int]
"""A region of interest ``(x_offset, y_offset, width, height)`` in pixels."""


@dataclass(frozen=True)
class Calibration:
    """The parts of a CameraInfo that the full-resolution maps depend on (normalized)."""

    width: int
    height: int
    distortion_model: str
    d: tuple[float, ...]
    k: tuple[float, ...]
    r: tuple[float, ...]
    p: tuple[float, ...]
    binning_x: int
    binning_y: int


@dataclass(frozen=True)
class RoiState:
    x: int
    y: int
    width: int
    height: int
    do_rectify: bool


@dataclass(frozen=True)
class ParsedCameraInfo:
    """What :func:`parse_camera_info` found: the calibration, the ROI and what it assumed.

    Attributes:
        calibration: the normalized calibration (the distortion model applied and
            its coefficients, 4 padded to 5).
        roi: the region of interest (all zero read as the full image).
        assumption: None, or a key and a warning text when the distortion model was
            inferred from ``D`` (an empty ``distortion_model``, or a name whose length
            OpenCV reads as the other model): the camera model logs it once.
    """

    calibration: Calibration
    roi: RoiState
    assumption: tuple[str, str] | None = None

    def warn_once(self, seen: set[str], *, camera: str, frame: str) -> None:
        """Log the assumption unless ``seen`` (the model's own set) has it; add it there.

        The logger is ``visnav.perception.camera_model``.
        """
        if self.assumption is None or self.assumption[0] in seen:
            return
        seen.add(self.assumption[0])
        _LOG.warning("%s (frame %r): %s", camera, frame, self.assumption[1])


def _floats(value: Any, field: str, length: int | None) -> tuple[float, ...]:
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        text = f"CameraInfo.{field} is {value!r}: expected a sequence of numbers ({exc})"
        raise CameraModelError(text) from exc
    if length is not None and arr.size != length:
        text = f"CameraInfo.{field} has {arr.size} values: expected {length} (row-major)"
        raise CameraModelError(text)
    if not np.isfinite(arr).all():
        text = f"CameraInfo.{field} is {arr.tolist()}: every value must be finite"
        raise CameraModelError(text)
    return tuple(float(x) for x in arr)


def _format_list(values: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"


def parse_camera_info(info: CameraInfo) -> ParsedCameraInfo:
    """Validate a CameraInfo and return its normalized calibration, ROI and assumption."""
    width, height = int(info.width), int(info.height)
    if width <= 0 or height <= 0:
        text = (
            f"CameraInfo width x height is {width} x {height}: expected the full-resolution "
            "image size in pixels (both > 0)"
        )
        raise CameraModelError(text)
    k = _floats(info.k, "k", 9)
    p = _floats(info.p, "p", 12)
    r = _floats(info.r, "r", 9)
    d = _floats(info.d, "d", None)
    if not any(k):
        text = (
            "CameraInfo.k is all zero: the camera is uncalibrated (image_proc refuses to "
            "rectify it); calibrate it (visnav calibrate) and publish the result, e.g. via "
            "the camera node's camera_info_url"
        )
        raise CameraModelError(text)
    if k[0] == 0.0 or k[4] == 0.0:
        text = f"CameraInfo.k is {_format_list(k)}: fx (k[0]) and fy (k[4]) must be non-zero"
        raise CameraModelError(text)
    if not any(p):
        suggestion = _format_list((*k[0:3], 0.0, *k[3:6], 0.0, *k[6:9], 0.0))
        text = (
            "CameraInfo.p is all zero: fx, fy, cx, cy are read from P (image_geometry does not "
            "fall back to K); for a monocular camera that is not rectified set "
            f"p = {suggestion} (K with a zero fourth column)"
        )
        raise CameraModelError(text)
    if p[0] == 0.0 or p[5] == 0.0:
        text = f"CameraInfo.p is {_format_list(p)}: fx' (p[0]) and fy' (p[5]) must be non-zero"
        raise CameraModelError(text)
    model, d, assumption = _distortion(str(info.distortion_model), d)
    nonzero = any(d)
    if nonzero and not any(r):
        text = (
            "CameraInfo.r is all zero but d is non-zero: rectification needs R; "
            "a monocular camera uses the identity r = [1, 0, 0, 0, 1, 0, 0, 0, 1]"
        )
        raise CameraModelError(text)
    binning_x = int(info.binning_x) or 1
    binning_y = int(info.binning_y) or 1
    roi = info.roi
    rx, ry, rw, rh = int(roi.x_offset), int(roi.y_offset), int(roi.width), int(roi.height)
    if rx == 0 and ry == 0 and rw == 0 and rh == 0:
        rw, rh = width, height
    if rw <= 0 or rh <= 0 or rx + rw > width or ry + rh > height:
        text = (
            f"CameraInfo.roi is x_offset={rx}, y_offset={ry}, width={rw}, height={rh}: expected "
            f"a non-empty region inside the {width} x {height} image (all zero = full image)"
        )
        raise CameraModelError(text)
    if rw // binning_x == 0 or rh // binning_y == 0:
        text = (
            f"CameraInfo binning_x/binning_y is {binning_x}/{binning_y}: larger than the "
            f"{rw} x {rh} region it bins"
        )
        raise CameraModelError(text)
    calib = Calibration(width, height, model, d, k, r, p, binning_x, binning_y)
    return ParsedCameraInfo(calib, RoiState(rx, ry, rw, rh, bool(roi.do_rectify)), assumption)


def _distortion(
    model: str, d: tuple[float, ...]
) -> tuple[str, tuple[float, ...], tuple[str, str] | None]:
    """Return the distortion model applied, its coefficients and what was assumed.

    As image_geometry (which hands ``D`` to OpenCV as it is) and OpenCV: plumb_bob and
    rational_polynomial take any length OpenCV takes, read by length (4 and 5 are
    plumb_bob, 4 padded with k3 = 0; 8, 12 and 14 the rational model, the last two with
    thin-prism and tilt terms); an empty ``distortion_model`` with a non-zero ``D`` is
    read the same way. equidistant takes exactly 4 (``cv2.fisheye``); any other name
    with a non-zero ``D`` is refused.
    """
    if not any(d):
        return model, d, None
    n = len(d)
    if model == EQUIDISTANT:
        if n == DISTORTION_MODELS[EQUIDISTANT]:
            return model, d, None
        text = (
            f"CameraInfo.d has {n} coefficients {_format_list(d)} for distortion_model "
            f"'equidistant': expected 4 ({_COEFFICIENT_NAMES[EQUIDISTANT]}, OpenCV's "
            "fisheye model); fix the calibration file or the distortion_model name"
        )
        raise CameraModelError(text)
    if model and model not in DISTORTION_MODELS:
        close = difflib.get_close_matches(model, list(DISTORTION_MODELS), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        text = (
            f"CameraInfo.distortion_model is {model!r} with non-zero d {_format_list(d)}: "
            f"expected one of {', '.join(DISTORTION_MODELS)} (REP 104){hint}"
        )
        raise CameraModelError(text)
    if n not in OPENCV_D_LENGTHS:
        named = f"distortion_model {model!r}" if model else "an empty distortion_model"
        lengths = ", ".join(f"{k} ({v})" for k, v in _OPENCV_NAMES.items())
        text = (
            f"CameraInfo.d has {n} coefficients {_format_list(d)} for {named}: OpenCV takes "
            f"{lengths}; fix the calibration file"
        )
        raise CameraModelError(text)
    applied = PLUMB_BOB if n <= DISTORTION_MODELS[PLUMB_BOB] else RATIONAL_POLYNOMIAL
    padded = (*d, 0.0) if n == DISTORTION_MODELS[PLUMB_BOB] - 1 else d
    if model == applied:
        return model, padded, None
    if model:
        key = f"{model}->{applied}"
        text = (
            f"CameraInfo.distortion_model is {model!r} but d has {n} coefficients "
            f"{_format_list(d)}: applied as {applied!r} ({_OPENCV_NAMES[n]}), as image_geometry "
            f"and OpenCV read them; set distortion_model: {applied} (REP 104) in the calibration"
        )
    else:
        key = f"''->{applied}"
        text = (
            f"CameraInfo.distortion_model is empty with non-zero d {_format_list(d)}: applied "
            f"as {applied!r} ({_OPENCV_NAMES[n]}), as image_geometry and OpenCV read {n} "
            f"coefficients; set distortion_model: {applied} (REP 104) in the calibration"
        )
    return applied, padded, (key, text)


def binned(
    k: NDArray[np.float64], p: NDArray[np.float64], bx: int, by: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Scale K and P for binning (image_geometry's K_binned / P_binned)."""
    k = k.copy()
    p = p.copy()
    if bx > 1:
        k[0, 0] /= bx
        k[0, 2] /= bx
        p[0, 0] /= bx
        p[0, 2] /= bx
        p[0, 3] /= bx
    if by > 1:
        k[1, 1] /= by
        k[1, 2] /= by
        p[1, 1] /= by
        p[1, 2] /= by
        p[1, 3] /= by
    return k, p


def as_points(values: ArrayLike, dim: int, name: str) -> tuple[NDArray[np.float64], bool]:
    """Return (N, dim) float64 points and whether the input was a single point."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim == 1 and arr.shape[0] == dim:
        return arr.reshape(1, dim), True
    if arr.ndim == 2 and arr.shape[1] == dim:
        return arr, False
    text = f"{name} has shape {arr.shape}: expected ({dim},) or (N, {dim})"
    raise CameraModelError(text)


def shaped(points: NDArray[np.float64], single: bool) -> NDArray[np.float64]:
    """Undo :func:`as_points`: one point back to ``(dim,)``, several as they are."""
    return points[0].copy() if single else points
