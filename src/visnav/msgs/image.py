"""``sensor_msgs/Image`` <-> numpy, with cv_bridge's encodings and array shapes.

Encodings (``Image.encoding``) and the arrays they map to:

============================================  ========  ========
encoding                                      dtype     shape
============================================  ========  ========
``mono8``, ``bayer_*8``, ``8UC1``             uint8     (H, W)
``mono16``, ``bayer_*16``, ``16UC1``          uint16    (H, W)
``32FC1`` (depth in metres, REP 118)          float32   (H, W)
``rgb8``, ``bgr8``, ``8UC3``                  uint8     (H, W, 3)
``rgba8``, ``bgra8``                          uint8     (H, W, 4)
``rgb16``, ``bgr16`` / ``rgba16``, ``bgra16`` uint16    (H, W, 3) / (H, W, 4)
``yuv422_yuy2`` (``yuyv``), ``yuv422``        uint8     (H, W, 2)
``{8U,8S,16U,16S,32S,32F,64F}C<n>``           as named  (H, W) for n = 1, else (H, W, n)
============================================  ========  ========

As in cv_bridge, a bare depth (``"32F"``) means one channel, ``yuv422`` is UYVY
and ``yuv422_yuy2`` is YUYV byte order, both kept as two raw uint8 channels
(:func:`yuv422_yuy2_to_rgb` decodes YUYV with OpenCV).

Row padding (``step`` larger than ``width * bytes_per_pixel``) is dropped on
read; ``is_bigendian`` is honoured (multi-byte data is byte swapped into the
machine's order). Reading returns a zero-copy view on ``msg.data`` when neither
is needed. Writing always copies into a fresh contiguous uint8 ``data`` array
(the message owns its bytes), little endian unless asked otherwise.
"""

from __future__ import annotations

import difflib
import re
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.msgs.errors import MessageError
from visnav.msgs.types import Header, Image, Time

__all__ = [
    "bytes_per_pixel",
    "check_image",
    "encoding_dtype",
    "has_alpha",
    "image_to_numpy",
    "is_bayer",
    "is_color",
    "is_depth",
    "is_mono",
    "num_channels",
    "numpy_to_image",
    "yuv422_yuy2_to_rgb",
]

_MAX_CHANNELS = 512  # OpenCV's CV_CN_MAX; cv_bridge accepts any count up to it
_UINT32_MAX = 2**32 - 1

_COLOR = ("rgb8", "bgr8", "rgba8", "bgra8", "rgb16", "bgr16", "rgba16", "bgra16")
_BAYER_PATTERNS = ("rggb", "bggr", "gbrg", "grbg")

_NAMED: dict[str, tuple[str, int]] = {
    "rgb8": ("u1", 3),
    "bgr8": ("u1", 3),
    "rgba8": ("u1", 4),
    "bgra8": ("u1", 4),
    "rgb16": ("u2", 3),
    "bgr16": ("u2", 3),
    "rgba16": ("u2", 4),
    "bgra16": ("u2", 4),
    "mono8": ("u1", 1),
    "mono16": ("u2", 1),
    "yuv422": ("u1", 2),
    "uyvy": ("u1", 2),
    "yuv422_yuy2": ("u1", 2),
    "yuyv": ("u1", 2),
    **{f"bayer_{p}8": ("u1", 1) for p in _BAYER_PATTERNS},
    **{f"bayer_{p}16": ("u2", 1) for p in _BAYER_PATTERNS},
}

_DEPTHS = {"8U": "u1", "8S": "i1", "16U": "u2", "16S": "i2", "32S": "i4", "32F": "f4", "64F": "f8"}
_GENERIC = re.compile(r"(8U|8S|16U|16S|32S|32F|64F)(?:C([0-9]+))?")

_YUV422 = frozenset({"yuv422", "uyvy", "yuv422_yuy2", "yuyv"})

# Names offered in "did you mean" hints.
_SUGGESTIONS = (
    *_NAMED,
    *(f"{d}C{n}" for d in _DEPTHS for n in range(1, 5)),
)


class _Format(NamedTuple):
    dtype: np.dtype[Any]  # native byte order
    channels: int

    @property
    def bpp(self) -> int:
        return self.dtype.itemsize * self.channels


def _format(encoding: str, field: str = "encoding") -> _Format:
    """Look up an encoding; raise a MessageError naming ``field`` if it is unknown."""
    named = _NAMED.get(encoding)
    if named is not None:
        return _Format(np.dtype(named[0]), named[1])
    match = _GENERIC.fullmatch(encoding) if isinstance(encoding, str) else None
    if match is not None:
        channels = int(match.group(2)) if match.group(2) is not None else 1
        if 1 <= channels <= _MAX_CHANNELS:
            return _Format(np.dtype(_DEPTHS[match.group(1)]), channels)
    text = f"{field} is {encoding!r}: not a known image encoding"
    if isinstance(encoding, str):
        close = _close_encodings(encoding)
        if close:
            text += f"; did you mean {', '.join(repr(c) for c in close)}?"
    text += (
        "; expected one of rgb8, bgr8, rgba8, bgra8, rgb16, bgr16, rgba16, bgra16, mono8, "
        "mono16, bayer_{rggb,bggr,gbrg,grbg}{8,16}, yuv422, yuv422_yuy2 or "
        "{8U,8S,16U,16S,32S,32F,64F}C<n>"
    )
    raise MessageError(text)


def _close_encodings(encoding: str, n: int = 3) -> list[str]:
    """Return up to ``n`` known encodings most like ``encoding`` (case-insensitive)."""
    matcher = difflib.SequenceMatcher(b=encoding.lower())
    scored = []
    for name in _SUGGESTIONS:
        matcher.set_seq1(name.lower())
        score = matcher.ratio()
        if score >= 0.6:  # difflib's usual cut-off
            scored.append((-score, name))
    return [name for _, name in sorted(scored)[:n]]


def bytes_per_pixel(encoding: str) -> int:
    """Return the bytes one pixel takes in an encoding (``rgb8`` 3, ``32FC1`` 4, ``yuv422`` 2).

    Args:
        encoding: an ``Image.encoding`` string.

    Returns:
        Channels times bytes per channel.

    Raises:
        MessageError: unknown encoding.
    """
    return _format(encoding).bpp


def num_channels(encoding: str) -> int:
    """Return the number of channels of an encoding (``mono16`` 1, ``bgra8`` 4).

    Raises:
        MessageError: unknown encoding.
    """
    return _format(encoding).channels


def encoding_dtype(encoding: str) -> np.dtype[Any]:
    """Return the numpy dtype of one channel of an encoding, in native byte order.

    Raises:
        MessageError: unknown encoding.
    """
    return _format(encoding).dtype


def is_color(encoding: str) -> bool:
    """Return whether an encoding is RGB/BGR(A) colour (as ``sensor_msgs`` ``isColor``)."""
    return encoding in _COLOR


def is_mono(encoding: str) -> bool:
    """Return whether an encoding is ``mono8`` or ``mono16``."""
    return encoding in {"mono8", "mono16"}


def is_bayer(encoding: str) -> bool:
    """Return whether an encoding is a raw Bayer pattern (``bayer_rggb8`` ...)."""
    return encoding.startswith("bayer_") and encoding in _NAMED


def has_alpha(encoding: str) -> bool:
    """Return whether an encoding carries an alpha channel (``rgba8``, ``bgra16`` ...)."""
    return encoding in {"rgba8", "bgra8", "rgba16", "bgra16"}


def is_depth(encoding: str) -> bool:
    """Return whether an encoding is a REP 118 depth image (``32FC1`` metres, ``16UC1`` mm)."""
    return encoding in {"32FC1", "16UC1"}


def _data_bytes(data: Any, field: str) -> NDArray[np.uint8]:
    """Return a message's byte field as a flat uint8 array (no copy when possible)."""
    if isinstance(data, np.ndarray):
        if data.dtype != np.uint8:
            text = f"{field} has dtype {data.dtype}: expected a uint8 array (or bytes)"
            raise MessageError(text)
        return np.ascontiguousarray(data).reshape(-1)
    if isinstance(data, (bytes, bytearray, memoryview)):
        return np.frombuffer(data, dtype=np.uint8)
    try:
        return np.asarray(data, dtype=np.uint8).reshape(-1)
    except (TypeError, ValueError, OverflowError) as exc:
        text = f"{field} is a {type(data).__name__}: expected a uint8 array or bytes ({exc})"
        raise MessageError(text) from exc


def _checked(msg: Image) -> tuple[_Format, NDArray[np.uint8]]:
    """Validate an image message; return its format and its data bytes."""
    fmt = _format(msg.encoding, "Image.encoding")
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if height <= 0 or width <= 0:
        text = (
            f"Image.width x Image.height is {width}x{height} (encoding {msg.encoding!r}): "
            "expected at least 1x1 pixels; the publisher sent an empty image"
        )
        raise MessageError(text)
    if msg.encoding in _YUV422 and width % 2:
        text = (
            f"Image.width is {width} for encoding {msg.encoding!r}: expected an even width "
            "(4:2:2 packs two pixels in four bytes)"
        )
        raise MessageError(text)
    row = width * fmt.bpp
    if step < row:
        text = (
            f"Image.step is {step}: expected at least width * bytes_per_pixel = "
            f"{width} * {fmt.bpp} = {row} for encoding {msg.encoding!r}; "
            f"set step = {row} (larger only if rows are padded)"
        )
        raise MessageError(text)
    buf = _data_bytes(msg.data, "Image.data")
    if buf.size != step * height:
        text = (
            f"Image.data has {buf.size} bytes: expected step * height = {step} * {height} = "
            f"{step * height} (encoding {msg.encoding!r}, width {width}); "
            "the message is truncated or its height/step are wrong"
        )
        raise MessageError(text)
    return fmt, buf


def check_image(msg: Image) -> None:
    """Check that an image message can be read (what :func:`image_to_numpy` checks).

    Built-in nodes call this (or :func:`image_to_numpy`) on every image before
    OpenCV sees it, also where they pass an image on unchanged.

    Raises:
        MessageError: unknown encoding, an empty (0-pixel) image, an odd width for
            4:2:2 YUV, ``step`` smaller than one row, or ``data`` not
            ``step * height`` bytes long; the message names the field and the value.
    """
    _checked(msg)


def image_to_numpy(msg: Image) -> NDArray[Any]:
    """Return the pixels of an image message as a numpy array (cv_bridge ``passthrough``).

    Args:
        msg: the ``sensor_msgs/Image``.

    Returns:
        An (H, W) array for one-channel encodings, (H, W, C) otherwise, dtype per
        the encoding in native byte order. When ``step`` has no row padding and
        no byte swap is needed this is a view on ``msg.data`` (read-only if the
        data is); otherwise a fresh contiguous array.

    Raises:
        MessageError: an image :func:`check_image` refuses.
    """
    fmt, buf = _checked(msg)
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    row = width * fmt.bpp
    dtype = fmt.dtype.newbyteorder(">" if msg.is_bigendian else "<")
    if fmt.channels == 1:
        shape: tuple[int, ...] = (height, width)
        strides: tuple[int, ...] = (step, fmt.bpp)
    else:
        shape = (height, width, fmt.channels)
        strides = (step, fmt.bpp, fmt.dtype.itemsize)
    if step == row and dtype.isnative:
        flat: NDArray[Any] = buf.view(dtype)
        return flat.reshape(shape)
    view: NDArray[Any] = np.ndarray(shape, dtype=dtype, buffer=buf, strides=strides)
    return view.astype(fmt.dtype, order="C")


def numpy_to_image(
    array: ArrayLike,
    encoding: str,
    *,
    header: Header | None = None,
    step: int | None = None,
    is_bigendian: bool = False,
) -> Image:
    """Return an image message holding a copy of ``array`` (cv_bridge ``cv2_to_imgmsg``).

    Args:
        array: (H, W) or (H, W, 1) for one-channel encodings, (H, W, C) otherwise,
            with exactly the encoding's dtype (any byte order).
        encoding: the ``Image.encoding`` to write, e.g. ``"rgb8"`` or ``"32FC1"``.
        header: the message header (default: zero stamp, empty frame_id).
        step: bytes per row; default ``width * bytes_per_pixel``, larger values
            pad each row with zero bytes.
        is_bigendian: write multi-byte data big endian (default little endian).

    Returns:
        The ``sensor_msgs/Image``; ``data`` is a new contiguous uint8 array.

    Raises:
        MessageError: unknown encoding, dtype or shape not matching the encoding,
            or ``step`` smaller than one row.
    """
    fmt = _format(encoding)
    arr = np.asarray(array)
    if arr.dtype.kind != fmt.dtype.kind or arr.dtype.itemsize != fmt.dtype.itemsize:
        text = (
            f"array has dtype {arr.dtype}: encoding {encoding!r} needs {fmt.dtype}; "
            f"convert first, e.g. array.astype(np.{fmt.dtype.name})"
        )
        raise MessageError(text)
    channels = fmt.channels
    ok_shape = arr.ndim == 3 and arr.shape[2] == channels
    if channels == 1:
        ok_shape = ok_shape or arr.ndim == 2
    if not ok_shape:
        want = "(H, W) or (H, W, 1)" if channels == 1 else f"(H, W, {channels})"
        text = f"array has shape {arr.shape}: encoding {encoding!r} needs {want}"
        if channels > 1 and arr.ndim == 2:
            text += "; a 2-D array is one channel (use mono8/mono16/32FC1 or stack channels)"
        raise MessageError(text)
    height, width = int(arr.shape[0]), int(arr.shape[1])
    row = width * fmt.bpp
    if step is None:
        step = row
    elif not isinstance(step, (int, np.integer)) or not row <= step <= _UINT32_MAX:
        text = (
            f"step is {step!r}: expected an int >= width * bytes_per_pixel = "
            f"{width} * {fmt.bpp} = {row} (and < 2**32)"
        )
        raise MessageError(text)
    step = int(step)
    if height > _UINT32_MAX or width > _UINT32_MAX:  # pragma: no cover - cannot allocate
        text = f"array has shape {arr.shape}: height and width must fit uint32"
        raise MessageError(text)
    dtype = fmt.dtype.newbyteorder(">" if is_bigendian else "<")
    buf = (np.zeros if step > row else np.empty)(height * step, dtype=np.uint8)
    if channels == 1:
        shape: tuple[int, ...] = (height, width)
        strides: tuple[int, ...] = (step, fmt.bpp)
        arr = arr.reshape(shape)
    else:
        shape = (height, width, channels)
        strides = (step, fmt.bpp, fmt.dtype.itemsize)
    dst: NDArray[Any] = np.ndarray(shape, dtype=dtype, buffer=buf, strides=strides)
    dst[...] = arr
    return Image(
        header=header if header is not None else Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
        height=height,
        width=width,
        encoding=encoding,
        is_bigendian=int(bool(is_bigendian)),
        step=step,
        data=buf,
    )


def yuv422_yuy2_to_rgb(array: ArrayLike) -> NDArray[np.uint8]:
    """Decode a ``yuv422_yuy2`` (YUYV) image into RGB with OpenCV.

    Args:
        array: the (H, W, 2) uint8 array :func:`image_to_numpy` returns for a
            ``yuv422_yuy2`` message; W must be even (two pixels share U and V).

    Returns:
        An (H, W, 3) uint8 RGB array.

    Raises:
        MessageError: wrong dtype, shape or odd width.
    """
    arr = np.asarray(array)
    if arr.dtype != np.uint8 or arr.ndim != 3 or arr.shape[2] != 2 or arr.shape[1] % 2:
        text = (
            f"array has dtype {arr.dtype} and shape {arr.shape}: expected uint8 (H, W, 2) "
            "with an even W, as image_to_numpy returns for 'yuv422_yuy2'"
        )
        raise MessageError(text)
    if arr.size == 0:
        return np.zeros((*arr.shape[:2], 3), dtype=np.uint8)
    import cv2  # noqa: PLC0415 - OpenCV is heavy; load it only when decoding

    rgb = cv2.cvtColor(np.ascontiguousarray(arr), cv2.COLOR_YUV2RGB_YUY2)
    return np.asarray(rgb, dtype=np.uint8)
