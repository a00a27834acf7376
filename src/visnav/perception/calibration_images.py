"""Reading calibration image files safely: the size from the header before decoding.

A 20000 x 20000 PNG decodes to 1.2 GB of BGR pixels and takes a minute to search
for a chessboard; :func:`read_gray_image` reads the width and height from the
file header (PNG, JPEG, BMP, PNM, TIFF via OpenCV otherwise) and refuses the
file with a one-line error before decoding when it is larger than
:data:`~visnav.perception.chessboard.MAX_IMAGE_PIXELS`.
"""

from __future__ import annotations

import struct
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.perception._calibration_common import CalibrationError
from visnav.perception.chessboard import check_image_size, to_gray

__all__ = ["header_size", "read_gray_image"]

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers (SOF0-SOF15 without DHT C4, JPG C8 and DAC CC).
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
_JPEG_SCAN_LIMIT = 4 * 1024 * 1024  # SOF sits after EXIF/ICC blocks; give up after 4 MB


def _png_size(head: bytes) -> tuple[int, int] | None:
    if len(head) >= 24 and head.startswith(_PNG_MAGIC) and head[12:16] == b"IHDR":
        width, height = struct.unpack(">II", head[16:24])
        return int(width), int(height)
    return None


def _bmp_size(head: bytes) -> tuple[int, int] | None:
    if len(head) >= 26 and head[:2] == b"BM":
        width, height = struct.unpack("<ii", head[18:26])
        return abs(int(width)), abs(int(height))
    return None


def _pnm_size(head: bytes) -> tuple[int, int] | None:
    if len(head) < 3 or head[:1] != b"P" or head[1:2] not in b"123456":
        return None
    numbers: list[int] = []
    for line in head[2:].split(b"\n"):
        for token in line.split(b"#", 1)[0].split():
            if not token.isdigit():
                return None
            numbers.append(int(token))
            if len(numbers) == 2:
                return numbers[0], numbers[1]
    return None


def _jpeg_size(path: Path) -> tuple[int, int] | None:
    with path.open("rb") as f:
        if f.read(2) != b"\xff\xd8":
            return None
        while f.tell() < _JPEG_SCAN_LIMIT:
            byte = f.read(1)
            if not byte:
                return None
            if byte != b"\xff":
                continue
            marker = f.read(1)
            while marker == b"\xff":  # fill bytes
                marker = f.read(1)
            if not marker:
                return None
            code = marker[0]
            if code in (0xD8, 0x01) or 0xD0 <= code <= 0xD7:
                continue  # markers without a length
            length_bytes = f.read(2)
            if len(length_bytes) < 2:
                return None
            (length,) = struct.unpack(">H", length_bytes)
            if code in _JPEG_SOF:
                frame = f.read(5)
                if len(frame) < 5:
                    return None
                height, width = struct.unpack(">HH", frame[1:5])
                return int(width), int(height)
            f.seek(length - 2, 1)
    return None


def header_size(path: Path) -> tuple[int, int] | None:
    """Return (width, height) from an image file's header, or None for other formats."""
    with path.open("rb") as f:
        head = f.read(64)
    for parse in (_png_size, _bmp_size, _pnm_size):
        size = parse(head)
        if size is not None:
            return size
    if head[:2] == b"\xff\xd8":
        return _jpeg_size(path)
    return None


def read_gray_image(path: Path) -> NDArray[np.uint8]:
    """Read an image file as 8-bit gray, refusing oversized files before decoding them.

    Raises:
        CalibrationError: no such file, an unreadable file, an empty (0-pixel) image or
            one larger than ``MAX_IMAGE_PIXELS`` (each a one-line message naming the file).
    """
    if not path.is_file():
        text = f"{path}: no such image file"
        raise CalibrationError(text)
    size = header_size(path)
    if size is not None:
        check_image_size(size[0], size[1], str(path))
    pixels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if pixels is None or pixels.size == 0:
        text = f"{path}: cannot read it as an image (unsupported format or corrupt file)"
        raise CalibrationError(text)
    check_image_size(int(pixels.shape[1]), int(pixels.shape[0]), str(path))
    return to_gray(pixels, path.name)
