"""RVL, the run-length / variable-length depth codec of ``compressedDepth`` (``format`` ``rvl``).

compressed_depth_image_transport (ROS 1 noetic, ROS 2) writes it when its ``format``
parameter is ``rvl`` instead of ``png``: the message format is ``"<encoding>;
compressedDepth rvl"`` and ``data`` is the 12-byte ConfigHeader, then ``uint32 cols``,
``uint32 rows`` (little endian), then the RVL stream of Wilson (2017, "Fast Lossless
Depth Image Compression", ISS '17) over the 16-bit pixels (the millimetres of ``16UC1``,
the quantised inverse depth of ``32FC1``, as for PNG):

* the pixels are coded as alternating runs: a count of zeros, a count of non-zeros, then
  each non-zero pixel as the zig-zag of its difference to the previous non-zero pixel
  (``(d << 1) ^ (d >> 31)``);
* each number is a variable-length code of 4-bit nibbles, 3 value bits each (least
  significant first), the nibble's high bit set when more follow;
* nibbles are packed eight to a 32-bit word, the first in the word's most significant
  bits, words stored little endian (the C++ ``int`` on x86 and ARM); the last word is
  padded with zero nibbles.

Written from that description and the plugin's behaviour; the decoder checks every count
against the image size and the stream's end (ROS's trusts them).
"""

from __future__ import annotations

import struct

import numba
import numpy as np
from numpy.typing import NDArray

from visnav.perception.errors import PerceptionError

__all__ = ["RVL_SIZE", "RvlError", "compress_rvl", "decompress_rvl"]

RVL_SIZE = struct.Struct("<II")
"""The ``cols``, ``rows`` prefix of an RVL payload."""

_MAX_PIXELS = 1 << 28


class RvlError(PerceptionError, ValueError):
    """RVL data that do not decode to the image they say they hold."""


@numba.njit(cache=True)
def _encode(pixels: NDArray[np.uint16], out: NDArray[np.uint32]) -> int:  # pragma: no cover
    n = pixels.size
    words = 0
    word = np.uint32(0)
    nibbles = 0
    i = 0
    previous = 0
    values = np.empty(3, np.int64)
    while i < n:
        zeros = 0
        while i < n and pixels[i] == 0:
            i += 1
            zeros += 1
        j = i
        while j < n and pixels[j] != 0:
            j += 1
        values[0] = zeros
        values[1] = j - i
        count = 2
        k = -1
        while True:
            if count > 0:
                value = values[2 - count]
                count -= 1
            else:
                k += 1
                if i + k >= j:
                    break
                current = int(pixels[i + k])
                delta = current - previous
                value = (delta << 1) ^ (delta >> 31)
                previous = current
            while True:
                nibble = value & 0x7
                value >>= 3
                if value:
                    nibble |= 0x8
                word = np.uint32((word << np.uint32(4)) | np.uint32(nibble))
                nibbles += 1
                if nibbles == 8:
                    out[words] = word
                    words += 1
                    nibbles = 0
                    word = np.uint32(0)
                if not value:
                    break
        i = j
    if nibbles:
        out[words] = np.uint32(word << np.uint32(4 * (8 - nibbles)))
        words += 1
    return words


@numba.njit(cache=True)
def _decode(words: NDArray[np.uint32], out: NDArray[np.uint16]) -> int:  # pragma: no cover
    """Fill ``out``; 0 on success, -1 if the stream ends early, -2 if a count overflows."""
    n = out.size
    pos = 0
    w = 0
    word = np.uint32(0)
    left = 0
    previous = 0
    state = 0  # 0: zeros count, 1: nonzeros count, 2: a value
    pending = 0
    while pos < n:
        value = 0
        shift = 0
        while True:
            if left == 0:
                if w >= words.size:
                    return -1
                word = words[w]
                w += 1
                left = 8
            nibble = int(word >> np.uint32(28))
            word = np.uint32(word << np.uint32(4))
            left -= 1
            if shift < 32:
                value |= (nibble & 0x7) << shift
            shift += 3
            if not nibble & 0x8:
                break
        if state == 0:
            if value > n - pos:
                return -2
            for _ in range(value):
                out[pos] = 0
                pos += 1
            state = 1
        elif state == 1:
            if value > n - pos:
                return -2
            pending = value
            state = 2 if pending else 0
        else:
            delta = (value >> 1) ^ -(value & 1)
            previous = (previous + delta) & 0xFFFF
            out[pos] = previous
            pos += 1
            pending -= 1
            if pending == 0:
                state = 0
    return 0


def compress_rvl(pixels: NDArray[np.uint16]) -> bytes:
    """RVL payload of a 2-D uint16 image: ``uint32 cols, uint32 rows``, then the words."""
    image = np.ascontiguousarray(pixels, dtype=np.uint16)
    rows, cols = image.shape
    out = np.empty(image.size + 16, np.uint32)  # worst case: 6 value + 2 count nibbles a pixel
    n = int(_encode(image.reshape(-1), out))
    return RVL_SIZE.pack(cols, rows) + out[:n].astype("<u4").tobytes()


def decompress_rvl(payload: bytes | NDArray[np.uint8]) -> NDArray[np.uint16]:
    """The 2-D uint16 image of an RVL payload (as :func:`compress_rvl` and ROS write it).

    Raises:
        RvlError: a zero or implausible size, a truncated stream or counts beyond the image.
    """
    data = bytes(payload)
    if len(data) < RVL_SIZE.size:
        text = f"RVL data has {len(data)} bytes: expected uint32 cols, uint32 rows, then words"
        raise RvlError(text)
    cols, rows = RVL_SIZE.unpack_from(data)
    body = data[RVL_SIZE.size :]
    if rows == 0 or cols == 0 or rows * cols > _MAX_PIXELS:
        text = f"RVL data says {cols}x{rows} pixels: expected 1 to {_MAX_PIXELS} pixels"
        raise RvlError(text)
    usable = len(body) - len(body) % 4
    words = np.frombuffer(body[:usable], dtype="<u4").astype(np.uint32)
    out = np.empty(rows * cols, np.uint16)
    code = int(_decode(words, out))
    if code == -1:
        text = f"RVL stream of {len(body)} bytes ends before its {cols}x{rows} pixels"
        raise RvlError(text)
    if code == -2:
        text = f"RVL stream counts more pixels than its {cols}x{rows} image holds"
        raise RvlError(text)
    return out.reshape(rows, cols)
