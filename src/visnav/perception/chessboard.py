"""Chessboard detection for calibration: pattern parsing, corner finding, view geometry."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import image_to_numpy, is_bayer, is_color
from visnav.perception._calibration_common import CalibrationError
from visnav.perception.image_transport import convert_encoding

__all__ = [
    "MAX_IMAGE_PIXELS",
    "board_view_params",
    "check_image_size",
    "corner_spacing",
    "find_chessboard",
    "image_message_gray",
    "object_points",
    "parse_pattern",
    "perspective_ratio",
    "refine_radius",
    "to_gray",
]

_BORDER_PX = 8  # like ROS: a corner this close to the edge means the board is cut off
_MIN_PX_PER_SQUARE = 3  # smaller boards cannot be found (and break adaptiveThreshold)
_OPENCV_HALF_WINDOW = 11  # cornerSubPix winSize of OpenCV's calibration tutorial
_DETECT_PIXELS = 1280 * 960  # larger images are searched on a copy about this size ...
_DOWNSCALE_ABOVE = 1.5  # ... when they are more than 1.5x larger per side
MAX_IMAGE_PIXELS = 64_000_000
"""Largest image calibrate reads (64 MP): larger ones are refused before decoding."""


def parse_pattern(pattern: str | Sequence[int]) -> tuple[int, int]:
    """Return a chessboard pattern ``"9x6"`` or ``(9, 6)`` as (columns, rows) of inner corners.

    Raises:
        CalibrationError: not two integers >= 2.
    """
    if isinstance(pattern, str):
        match = re.fullmatch(r"\s*(\d+)\s*[xX*,]\s*(\d+)\s*", pattern)
        values: tuple[int, ...] = (int(match[1]), int(match[2])) if match else ()
    else:
        try:
            values = tuple(int(v) for v in pattern if not isinstance(v, bool))
        except (TypeError, ValueError):
            values = ()
    if len(values) != 2 or min(values) < 2:
        text = (
            f"pattern is {pattern!r}: expected inner corners as 'COLSxROWS' such as '9x6' "
            "(a board of 10 x 7 squares), both >= 2"
        )
        raise CalibrationError(text)
    return values[0], values[1]


def to_gray(array: NDArray[Any], name: str) -> NDArray[np.uint8]:
    """Return an 8-bit gray copy of a gray/BGR/BGRA image (16-bit scaled by 255/65535).

    Raises:
        CalibrationError: another dtype or channel count (the text names ``name``).
    """
    arr = np.asarray(array)
    if arr.dtype == np.uint16:
        arr = np.rint(arr.astype(np.float64) * (255.0 / 65535.0)).astype(np.uint8)
    if arr.dtype != np.uint8 or arr.ndim not in (2, 3):
        text = (
            f"{name}: image has dtype {arr.dtype} and shape {arr.shape}: "
            "expected 8/16-bit gray or BGR"
        )
        raise CalibrationError(text)
    if arr.ndim == 3:
        channels = arr.shape[2]
        if channels == 1:
            arr = arr[..., 0]
        elif channels in (3, 4):
            code = cv2.COLOR_BGR2GRAY if channels == 3 else cv2.COLOR_BGRA2GRAY
            arr = cv2.cvtColor(np.ascontiguousarray(arr), code)
        else:
            text = f"{name}: image has {channels} channels: expected 1, 3 or 4"
            raise CalibrationError(text)
    return np.ascontiguousarray(arr, dtype=np.uint8)


def image_message_gray(msg: Any, name: str) -> NDArray[np.uint8]:
    """Return an Image message's pixels as 8-bit gray (colour and Bayer converted).

    Raises:
        CalibrationError: a malformed image or an encoding without a gray form.
    """
    encoding = msg.encoding
    try:
        array = image_to_numpy(msg)
        if is_color(encoding) or is_bayer(encoding) or encoding == "mono16":
            array = convert_encoding(array, encoding, "mono8")
    except ValueError as exc:
        text = f"{name}: cannot read the image: {exc}"
        raise CalibrationError(text) from exc
    return to_gray(array, name)


def check_image_size(width: int, height: int, name: str) -> None:
    """Refuse an image larger than :data:`MAX_IMAGE_PIXELS` (a one-line error naming it).

    Raises:
        CalibrationError: the image is too large to be a camera frame worth calibrating on.
    """
    if width * height > MAX_IMAGE_PIXELS:
        text = (
            f"{name}: image is {width}x{height} px ({width * height / 1e6:.0f} MP): larger than "
            f"the {MAX_IMAGE_PIXELS // 1_000_000} MP visnav calibrate reads. Calibrate on frames "
            "at the camera's working resolution (a calibration is only valid at the size it "
            "was computed for)"
        )
        raise CalibrationError(text)


def refine_radius(spacing: float, scale: float = 1.0) -> int:
    """Half-size of the ``cornerSubPix`` window for a board whose corners are ``spacing`` px apart.

    OpenCV's calibration tutorial uses an 11 px half-size (a 23 x 23 window). On small
    boards that window reaches the neighbouring squares' edges and pulls every corner
    (ROS camera_calibration's half-spacing window does the same: 1.3 px RMS and fx 3 %
    off on OpenCV's own samples), so it is capped at 0.4 x spacing, which keeps the window
    inside the four squares around the corner. ``scale`` > 1 when the corners were found
    on a downscaled copy: the window must then cover their error of up to ``scale`` px.
    """
    cap = max(2, math.ceil(0.4 * spacing))
    return min(max(_OPENCV_HALF_WINDOW, math.ceil(scale)), cap)


def _detect(
    gray: NDArray[np.uint8], pattern: tuple[int, int]
) -> tuple[NDArray[np.float32] | None, float, str]:
    """Find the corners (unrefined, full-resolution pixels); large images on a smaller copy.

    As ROS camera_calibration does, an image much larger than VGA is searched at about
    1280 x 960 and the corners scaled back (``findChessboardCorners`` time grows with
    the pixel count; the refinement then runs on the full image).
    """
    h, w = gray.shape[:2]
    scale = math.sqrt(w * h / _DETECT_PIXELS)
    search: NDArray[Any] = gray
    if scale > _DOWNSCALE_ABOVE:
        size = (max(1, round(w / scale)), max(1, round(h / scale)))
        search = np.asarray(cv2.resize(gray, size, interpolation=cv2.INTER_AREA))
    else:
        scale = 1.0
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    try:
        found, corners = cv2.findChessboardCorners(search, pattern, flags=flags)
    except cv2.error as exc:
        return None, scale, f"OpenCV could not search the {w}x{h} image: {exc.err}"
    if not found or corners is None:
        return None, scale, f"chessboard {pattern[0]}x{pattern[1]} not found"
    pts = np.asarray(corners, dtype=np.float32).reshape(-1, 2)
    if scale != 1.0:
        pts = ((pts + 0.5) * np.float32(scale) - 0.5).astype(np.float32)
    return pts, scale, ""


def find_chessboard(
    gray: NDArray[np.uint8], pattern: tuple[int, int]
) -> tuple[NDArray[np.float32] | None, str]:
    """Find and refine the inner corners of a chessboard.

    Detection is ``cv2.findChessboardCorners`` (adaptive threshold, normalised image),
    refinement ``cv2.cornerSubPix`` with the window of :func:`refine_radius`.

    Args:
        gray: 8-bit gray image.
        pattern: inner corners (columns, rows).

    Returns:
        ``(corners, "")`` with corners of shape (columns * rows, 2) in pixels, row by
        row; or ``(None, reason)`` when the board is not (fully) visible.

    Raises:
        CalibrationError: the image is larger than :data:`MAX_IMAGE_PIXELS`.
    """
    h, w = gray.shape[:2]
    check_image_size(w, h, "image")
    short, long = sorted(pattern)
    if min(h, w) < _MIN_PX_PER_SQUARE * (short + 1) or max(h, w) < _MIN_PX_PER_SQUARE * (long + 1):
        return None, (
            f"the image is {w}x{h} px, too small to show a {pattern[0]}x{pattern[1]} "
            f"chessboard (at least {_MIN_PX_PER_SQUARE} px per square: "
            f"{_MIN_PX_PER_SQUARE * (long + 1)}x{_MIN_PX_PER_SQUARE * (short + 1)} px)"
        )
    pts, scale, reason = _detect(gray, pattern)
    if pts is None:
        return None, reason
    near_edge = (
        (pts[:, 0] < _BORDER_PX)
        | (pts[:, 1] < _BORDER_PX)
        | (pts[:, 0] > w - 1 - _BORDER_PX)
        | (pts[:, 1] > h - 1 - _BORDER_PX)
    )
    if near_edge.any():
        return None, "chessboard touches the image border (partly outside the view)"
    radius = refine_radius(corner_spacing(pts, pattern), scale)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.001)
    refined = cv2.cornerSubPix(
        gray, pts.reshape(-1, 1, 2).copy(), (radius, radius), (-1, -1), criteria
    )
    return np.asarray(refined, dtype=np.float32).reshape(-1, 2), ""


def corner_spacing(corners: NDArray[np.float32], pattern: tuple[int, int]) -> float:
    """The smallest distance in pixels between neighbouring corners (along rows or columns)."""
    cols, rows = pattern
    grid = corners.reshape(rows, cols, 2)
    return min(
        float(np.linalg.norm(np.diff(grid, axis=1), axis=2).min()),
        float(np.linalg.norm(np.diff(grid, axis=0), axis=2).min()),
    )


def object_points(pattern: tuple[int, int], square: float) -> NDArray[np.float32]:
    """Return the board's inner corners in the board frame (z = 0), row by row, in metres."""
    cols, rows = pattern
    grid = np.zeros((rows * cols, 3), np.float32)
    grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
    return grid


# -------------------------------------------------------------- calibration


def board_view_params(
    corners: NDArray[np.float32], pattern: tuple[int, int], size: tuple[int, int]
) -> NDArray[np.float64]:
    """Board position x, y, size and skew in [0, 1], to tell views apart (as ROS does)."""
    cols, _ = pattern
    w, h = size
    ul, ur, dr, dl = corners[0], corners[cols - 1], corners[-1], corners[-cols]
    quad = np.array([ul, ur, dr, dl], dtype=np.float64)
    x, y = quad[:, 0], quad[:, 1]
    area = 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))
    a, b = ul - ur, dr - ur
    cos = float(np.dot(a, b) / max(np.linalg.norm(a) * np.linalg.norm(b), 1e-12))
    skew = min(1.0, 2.0 * abs(math.pi / 2 - math.acos(max(-1.0, min(1.0, cos)))))
    mean = corners.mean(axis=0)
    return np.array([mean[0] / w, mean[1] / h, math.sqrt(area / (w * h)), skew])


def perspective_ratio(
    corners: NDArray[np.float32], pattern: tuple[int, int], square: float = 1.0
) -> float:
    """How much farther the board's farthest corner is than its nearest, from the image alone.

    The board-to-image homography ``H`` has a projective row ``(h31, h32, h33)`` whose
    value at a board point is proportional to that point's depth, whatever the camera
    matrix; the ratio max/min over the corners, minus 1, is 0 for a board parallel to
    the image plane (which carries no information on the focal length) and grows with
    its tilt. Returns 0 when no homography can be fitted.
    """
    board = object_points(pattern, square)[:, :2]
    h_mat, _ = cv2.findHomography(board, corners.reshape(-1, 2).astype(np.float64), 0)
    if h_mat is None:
        return 0.0
    w = board.astype(np.float64) @ h_mat[2, :2] + h_mat[2, 2]
    low, high = float(np.abs(w).min()), float(np.abs(w).max())
    return high / low - 1.0 if low > 0 else 0.0
