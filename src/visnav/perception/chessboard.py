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
    "board_view_params",
    "find_chessboard",
    "image_message_gray",
    "object_points",
    "parse_pattern",
    "to_gray",
]

_BORDER_PX = 8  # like ROS: a corner this close to the edge means the board is cut off


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


def find_chessboard(
    gray: NDArray[np.uint8], pattern: tuple[int, int]
) -> tuple[NDArray[np.float32] | None, str]:
    """Find and refine the inner corners of a chessboard.

    Args:
        gray: 8-bit gray image.
        pattern: inner corners (columns, rows).

    Returns:
        ``(corners, "")`` with corners of shape (columns * rows, 2) in pixels, row by
        row; or ``(None, reason)`` when the board is not (fully) visible.
    """
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(gray, pattern, flags=flags)
    if not found or corners is None:
        return None, f"chessboard {pattern[0]}x{pattern[1]} not found"
    pts = np.asarray(corners, dtype=np.float32).reshape(-1, 2)
    h, w = gray.shape[:2]
    near_edge = (
        (pts[:, 0] < _BORDER_PX)
        | (pts[:, 1] < _BORDER_PX)
        | (pts[:, 0] > w - 1 - _BORDER_PX)
        | (pts[:, 1] > h - 1 - _BORDER_PX)
    )
    if near_edge.any():
        return None, "chessboard touches the image border (partly outside the view)"
    cols, rows = pattern
    grid = pts.reshape(rows, cols, 2)
    spacing = min(
        float(np.linalg.norm(np.diff(grid, axis=1), axis=2).min()),
        float(np.linalg.norm(np.diff(grid, axis=0), axis=2).min()),
    )
    radius = max(2, math.ceil(spacing * 0.5))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.01)
    refined = cv2.cornerSubPix(
        gray, pts.reshape(-1, 1, 2).copy(), (radius, radius), (-1, -1), criteria
    )
    return np.asarray(refined, dtype=np.float32).reshape(-1, 2), ""


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
