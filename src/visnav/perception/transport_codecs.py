"""Codecs of image_transport's ``compressed`` and ``compressedDepth`` transports (wire compatible).

Plain functions, messages in and out, no graph code (the node level is
:mod:`visnav.perception.image_transport`, the registry :mod:`visnav.perception.transports`):

* :func:`compress` / :func:`decompress`: ``sensor_msgs/CompressedImage`` with JPEG
  or PNG data, as ``compressed_image_transport`` writes and reads it. Colour
  images are compressed as BGR; ``format`` is ``"<encoding>; <jpeg|png>
  compressed <target>"``, e.g. ``"rgb8; jpeg compressed bgr8"``, and for
  non-colour encodings the target is empty (``"mono8; png compressed "``, with
  the trailing space ROS writes).
* :func:`compress_depth` / :func:`decompress_depth`: ``compressedDepth`` as
  ``compressed_depth_image_transport`` writes it: ``data`` is a 12-byte
  little-endian ``ConfigHeader`` (int32 ``format`` = 0 (INV_DEPTH), float32
  ``depthParam[2]``) followed by a 16-bit PNG; ``format`` is
  ``"<encoding>; compressedDepth png"``. ``16UC1`` (mm) is stored as is (values
  above ``depth_max`` become 0); ``32FC1`` (m) is stored as quantised inverse
  depth ``v = A / d + B`` with ``A = q (q + 1)``, ``B = 1 - A / depth_max``
  (``q`` = ``depth_quantization``), 0 for invalid, and decoded as ``A / (v - B)``.

Topic names: the ``compressed`` transport of ``camera/image_raw`` is published on
``camera/image_raw/compressed``; :func:`split_transport_topic` and
:func:`transport_topic` convert between the two forms.

Differences from ROS (deliberate): ``mono16``/``16UC1`` images are refused by
JPEG (ROS saturates them to 8 bits; use PNG); a 32FC1 depth too close to be
represented in 16 bits (below ``A / (65535 - B)``, 0.15 m by default), zero,
negative or infinite is stored as invalid (0, decoded as NaN) where ROS's
float-to-integer conversion is undefined; a PNG without a ``';'`` in its format
that decodes to 16 bits is labelled ``mono16``/``bgr16`` (ROS says ``mono8``/``bgr8``).
The RVL variant of compressedDepth (``"<encoding>; compressedDepth rvl"``, ROS's
``format`` parameter ``rvl``) is read and written too (:mod:`visnav.perception.rvl_codec`).
"""

from __future__ import annotations

import math
import struct
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import (
    encoding_dtype,
    image_to_numpy,
    is_bayer,
    is_color,
    num_channels,
    numpy_to_image,
)
from visnav.msgs.types import CompressedImage, Header, Image, Time
from visnav.perception.errors import PerceptionError
from visnav.perception.rvl_codec import RvlError, compress_rvl, decompress_rvl

__all__ = [
    "COMPRESSED_DEPTH_HEADER",
    "KNOWN_TRANSPORTS",
    "SUPPORTED_TRANSPORTS",
    "ImageTransportError",
    "check_int",
    "check_positive",
    "compress",
    "compress_depth",
    "convert_encoding",
    "decompress",
    "decompress_depth",
    "depth_quantization_params",
    "split_transport_topic",
    "transport_topic",
]

SUPPORTED_TRANSPORTS = ("raw", "compressed", "compressedDepth")
"""The transports visnav can publish and decode."""

KNOWN_TRANSPORTS = (
    *SUPPORTED_TRANSPORTS,
    "theora",
    "zstd",
    "ffmpeg",
    "foxglove",
    "h264",
    "avif",
    "qoi",
)
"""Transport names recognised as a topic suffix (others need a ROS plugin)."""

COMPRESSED_DEPTH_HEADER = struct.Struct("<iff")
"""compressed_depth_image_transport's ConfigHeader: int32 format, float32 depthParam[2]."""

_INV_DEPTH = 0  # ConfigHeader.format value for the (only) inverse-depth PNG coding
_UINT16_MAX = 65535


class ImageTransportError(PerceptionError, ValueError):
    """An image cannot be compressed or a compressed message cannot be decoded."""


# --------------------------------------------------------------------- topics


def split_transport_topic(topic: str) -> tuple[str, str]:
    """Split a transport topic into the base image topic and the transport name.

    Args:
        topic: e.g. ``"camera/image_raw/compressed"`` or ``"camera/image_raw"``.

    Returns:
        ``("camera/image_raw", "compressed")``; ``(topic, "raw")`` when the last
        name is not a known transport.

    Raises:
        ImageTransportError: ``topic`` is empty.
    """
    if not isinstance(topic, str) or not topic.strip("/"):
        text = f"topic is {topic!r}: expected an image topic such as 'image_raw/compressed'"
        raise ImageTransportError(text)
    base, sep, last = topic.rstrip("/").rpartition("/")
    if sep and base and last in KNOWN_TRANSPORTS and last != "raw":
        return base, last
    return topic, "raw"


def transport_topic(base_topic: str, transport: str) -> str:
    """Return the topic a transport of ``base_topic`` uses (``raw`` is the base itself)."""
    return base_topic if transport == "raw" else f"{base_topic.rstrip('/')}/{transport}"


# ----------------------------------------------------------------- conversion

_BAYER_TO_BGR = {
    "rggb": cv2.COLOR_BayerBG2BGR,
    "bggr": cv2.COLOR_BayerRG2BGR,
    "gbrg": cv2.COLOR_BayerGR2BGR,
    "grbg": cv2.COLOR_BayerGB2BGR,
}
_MONO = ("mono8", "mono16")


def _layout(encoding: str) -> str:
    """Channel layout of a colour/mono encoding: 'gray', 'rgb', 'bgr', 'rgba', 'bgra'."""
    if encoding in _MONO:
        return "gray"
    return encoding.rstrip("0123456789")


def _bits(encoding: str) -> int:
    return 8 * encoding_dtype(encoding).itemsize


def _to_layout(array: NDArray[Any], src: str, dst: str) -> NDArray[Any]:
    """Reorder/add/drop channels between gray, rgb, bgr, rgba, bgra (any uint depth)."""
    if src == dst:
        return array
    if src == "gray":
        bgr = cv2.cvtColor(array, cv2.COLOR_GRAY2BGR)
    elif src in ("rgb", "rgba"):
        bgr = np.ascontiguousarray(array[..., 2::-1])
    else:
        bgr = np.ascontiguousarray(array[..., :3])
    if dst == "bgr":
        return np.asarray(bgr)
    if dst == "rgb":
        return np.ascontiguousarray(bgr[..., ::-1])
    if dst == "gray":
        return np.asarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
    alpha_full = np.iinfo(array.dtype).max
    if src in ("rgba", "bgra"):
        alpha = array[..., 3:4]
    else:
        alpha = np.full((*array.shape[:2], 1), alpha_full, dtype=array.dtype)
    color = bgr if dst == "bgra" else bgr[..., ::-1]
    return np.ascontiguousarray(np.concatenate([color, alpha], axis=2))


def _to_bits(array: NDArray[Any], src_bits: int, dst_bits: int) -> NDArray[Any]:
    """Scale between uint8 [0, 255] and uint16 [0, 65535] as cv_bridge does."""
    if src_bits == dst_bits:
        return array
    if src_bits == 8:
        return np.asarray(array.astype(np.uint16) * np.uint16(257), dtype=np.uint16)
    scaled = np.rint(array.astype(np.float64) * (255.0 / 65535.0))
    return scaled.astype(np.uint8)


def convert_encoding(array: NDArray[Any], src: str, dst: str) -> NDArray[Any]:
    """Convert pixels between ROS colour/mono encodings, as cv_bridge's ``cvtColor``.

    Supports ``mono8``, ``mono16``, ``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``, ``rgb16``,
    ``bgr16``, ``rgba16``, ``bgra16`` in both directions (bit depth scaled by
    65535/255), and ``bayer_*8/16`` to any of them (demosaicked). Identical
    encodings return the array unchanged.

    Args:
        array: pixels as :func:`visnav.msgs.image.image_to_numpy` returns them.
        src: their encoding.
        dst: the wanted encoding.

    Returns:
        The converted array.

    Raises:
        ImageTransportError: a conversion that does not make sense (e.g. to or
            from ``32FC1``), naming both encodings.
    """
    if src == dst:
        return array
    known = (*_MONO, "rgb8", "bgr8", "rgba8", "bgra8", "rgb16", "bgr16", "rgba16", "bgra16")
    if dst not in known or not (src in known or is_bayer(src)):
        text = (
            f"cannot convert encoding {src!r} to {dst!r}: conversions exist between "
            f"{', '.join(known)} (and from bayer_*); use 'passthrough' to keep {src!r}"
        )
        raise ImageTransportError(text)
    if is_bayer(src):
        pattern = src[len("bayer_") : len("bayer_") + 4]
        array = np.asarray(cv2.cvtColor(np.ascontiguousarray(array), _BAYER_TO_BGR[pattern]))
        src = "bgr" + src[len("bayer_") + 4 :]
    out = _to_layout(np.ascontiguousarray(array), _layout(src), _layout(dst))
    return _to_bits(out, _bits(src), _bits(dst))


# ------------------------------------------------------------------ compressed


def check_int(value: int, name: str, lo: int, hi: int) -> int:
    """Return ``value`` if it is an int in ``[lo, hi]``.

    Raises:
        ImageTransportError: otherwise (the message names ``name``).
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        text = f"{name} is {value!r}: expected an int in [{lo}, {hi}]"
        raise ImageTransportError(text)
    return int(value)


def _encode(ext: str, array: NDArray[Any], params: list[int], what: str) -> NDArray[np.uint8]:
    try:
        ok, buf = cv2.imencode(ext, np.ascontiguousarray(array), params)
    except cv2.error as exc:
        text = f"cv2.imencode({ext!r}) failed on {what}: {exc}"
        raise ImageTransportError(text) from exc
    if not ok:
        text = f"cv2.imencode({ext!r}) failed on {what}"
        raise ImageTransportError(text)
    return np.asarray(buf, dtype=np.uint8).reshape(-1)


def _copy_header(header: Header) -> Header:
    stamp = Time(sec=int(header.stamp.sec), nanosec=int(header.stamp.nanosec))
    return Header(stamp=stamp, frame_id=header.frame_id)


def compress(
    image: Image, *, format: str = "jpeg", jpeg_quality: int = 80, png_level: int = 9
) -> CompressedImage:
    """Compress an image for the ``compressed`` transport (compressed_image_transport).

    Colour encodings (rgb/bgr/rgba/bgra, 8 or 16 bit) are converted to BGR first
    (``bgr8`` for JPEG, ``bgr8``/``bgr16`` for PNG; alpha is dropped as in ROS);
    other 8/16-bit encodings with 1, 3 or 4 channels (mono, bayer, ``8UC3``...)
    are compressed as they are.

    Args:
        image: the ``sensor_msgs/Image``.
        format: ``"jpeg"`` or ``"png"``.
        jpeg_quality: 1-100 (ROS parameter ``jpeg_quality``).
        png_level: zlib level 0-9 (ROS parameter ``png_level``).

    Returns:
        The ``sensor_msgs/CompressedImage`` with the image's header and the ROS
        format string.

    Raises:
        ImageTransportError: unknown format, a parameter out of range, an encoding
            that cannot be compressed (float or signed, 16-bit mono in JPEG), or a
            malformed image.
    """
    if format not in ("jpeg", "png"):
        text = f"format is {format!r}: expected 'jpeg' or 'png'"
        raise ImageTransportError(text)
    encoding = image.encoding
    array = _image_array(image)
    dtype = array.dtype
    channels = 1 if array.ndim == 2 else int(array.shape[2])
    if dtype not in (np.uint8, np.uint16) or channels not in (1, 3, 4):
        text = (
            f"Image.encoding is {encoding!r}: the compressed transport needs an 8/16-bit "
            "unsigned image with 1, 3 or 4 channels"
        )
        if encoding in ("32FC1", "16UC1"):
            text += "; for depth images use the compressedDepth transport (compress_depth)"
        raise ImageTransportError(text)
    bits = 8 * dtype.itemsize
    if format == "jpeg":
        quality = check_int(jpeg_quality, "jpeg_quality", 1, 100)
        params = [cv2.IMWRITE_JPEG_QUALITY, quality]
        target = "bgr8" if is_color(encoding) else ""
        if not target and bits == 16:
            text = (
                f"Image.encoding is {encoding!r}: JPEG holds 8 bits per channel and would "
                "saturate this 16-bit image; use format='png'"
            )
            raise ImageTransportError(text)
        ext = ".jpg"
    else:
        level = check_int(png_level, "png_level", 0, 9)
        params = [cv2.IMWRITE_PNG_COMPRESSION, level]
        target = f"bgr{bits}" if is_color(encoding) else ""
        ext = ".png"
    if target:
        array = convert_encoding(array, encoding, target)
    data = _encode(ext, array, params, f"a {encoding} image")
    return CompressedImage(
        header=_copy_header(image.header),
        format=f"{encoding}; {format} compressed {target}",
        data=data,
    )


def _image_array(image: Image) -> NDArray[Any]:
    try:
        return image_to_numpy(image)
    except ValueError as exc:
        raise ImageTransportError(str(exc)) from exc


def _data_bytes(msg: CompressedImage) -> NDArray[np.uint8]:
    data = msg.data
    if isinstance(data, (bytes, bytearray, memoryview)):
        return np.frombuffer(data, dtype=np.uint8)
    return np.ascontiguousarray(np.asarray(data, dtype=np.uint8)).reshape(-1)


def _decode(buf: NDArray[np.uint8], what: str) -> NDArray[Any]:
    if buf.size == 0:
        text = f"CompressedImage.data is empty ({what})"
        raise ImageTransportError(text)
    try:
        decoded = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:
        decoded = None
        reason = f": {exc}"
    else:
        reason = ""
    if decoded is None:
        head = bytes(buf[:8]).hex(" ")
        text = (
            f"CompressedImage.data ({buf.size} bytes, starting {head}) is not a decodable "
            f"JPEG/PNG stream ({what}){reason}"
        )
        raise ImageTransportError(text)
    return np.asarray(decoded)


def decompress(msg: CompressedImage, *, desired_encoding: str | None = None) -> Image:
    """Decode a ``compressed`` (or ``compressedDepth``) message into an Image.

    Reads the format string as compressed_image_transport does: the encoding
    before ``';'`` (older messages without one decode as ``mono8``/``bgr8`` by
    channel count), colour converted back from BGR (``"compressed bgr"``) or
    RGB, and 16-bit encodings sent as JPEG scaled back by 256. A format naming
    ``compressedDepth`` is passed to :func:`decompress_depth`.

    Args:
        msg: the ``sensor_msgs/CompressedImage``.
        desired_encoding: convert to this encoding (see :func:`convert_encoding`);
            None or ``"passthrough"`` keeps the transmitted one.

    Returns:
        The ``sensor_msgs/Image`` with the message's header.

    Raises:
        ImageTransportError: undecodable data, or decoded pixels that do not fit the
            encoding the format string names.
    """
    fmt = msg.format
    if "compressedDepth" in fmt:
        image = decompress_depth(msg)
    else:
        decoded = _decode(_data_bytes(msg), f"format {fmt!r}")
        channels = 1 if decoded.ndim == 2 else int(decoded.shape[2])
        encoding, sep, rest = fmt.partition(";")
        encoding = encoding.strip()
        if not sep:
            # Older compressed_image_transport: no encoding in the format string.
            if channels not in (1, 3):
                text = f"CompressedImage.format {fmt!r}: cannot label {channels} decoded channels"
                raise ImageTransportError(text)
            bits = 8 * decoded.dtype.itemsize
            encoding = f"mono{bits}" if channels == 1 else f"bgr{bits}"
        elif is_color(encoding) and channels == 3:
            source = "bgr" if "compressed bgr" in rest else "rgb"
            decoded = _to_layout(decoded, source, _layout(encoding))
        if sep and "jpeg" in rest and _bits_or_none(encoding) == 16 and decoded.dtype == np.uint8:
            decoded = decoded.astype(np.uint16) * np.uint16(256)
        _check_decoded(decoded, encoding, fmt)
        image = numpy_to_image(decoded, encoding, header=_copy_header(msg.header))
    if desired_encoding is None or desired_encoding in ("passthrough", image.encoding):
        return image
    array = convert_encoding(image_to_numpy(image), image.encoding, desired_encoding)
    return numpy_to_image(array, desired_encoding, header=image.header)


def _bits_or_none(encoding: str) -> int | None:
    try:
        return _bits(encoding)
    except ValueError:
        return None


def _check_decoded(decoded: NDArray[Any], encoding: str, fmt: str) -> None:
    channels = 1 if decoded.ndim == 2 else int(decoded.shape[2])
    try:
        want_dtype, want_channels = encoding_dtype(encoding), num_channels(encoding)
    except ValueError as exc:
        text = f"CompressedImage.format {fmt!r} names an unknown encoding: {exc}"
        raise ImageTransportError(text) from exc
    if decoded.dtype != want_dtype or channels != want_channels:
        text = (
            f"CompressedImage.format {fmt!r} says {encoding!r} ({want_channels} x "
            f"{want_dtype}), but the data decodes to {channels} x {decoded.dtype}"
        )
        raise ImageTransportError(text)


# ------------------------------------------------------------- compressedDepth


def check_positive(value: float, name: str) -> float:
    """Return ``value`` as float if finite and > 0.

    Raises:
        ImageTransportError: otherwise (the message names ``name``).
    """
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or value <= 0:
        text = f"{name} is {value!r}: expected a finite number > 0"
        raise ImageTransportError(text)
    return float(value)


def depth_quantization_params(depth_max: float, depth_quantization: float) -> tuple[float, float]:
    """Return compressedDepth's float32 (A, B): ``A = q (q + 1)``, ``B = 1 - A / depth_max``."""
    z0 = np.float32(depth_quantization)
    a = np.float32(z0 * (z0 + np.float32(1.0)))
    b = np.float32(np.float32(1.0) - a / np.float32(depth_max))
    return float(a), float(b)


def compress_depth(
    image: Image,
    *,
    depth_max: float = 10.0,
    depth_quantization: float = 100.0,
    png_level: int = 9,
    compression_format: str = "png",
) -> CompressedImage:
    """Compress a depth image for the ``compressedDepth`` transport.

    Args:
        image: a ``16UC1``/``mono16`` (millimetres) or ``32FC1`` (metres) image.
        depth_max: metres; deeper pixels are stored as invalid (0). ROS default 10.
        depth_quantization: the depth (m) at which the 32FC1 quantisation step is
            1 m; larger keeps more precision. ROS default 100.
        png_level: zlib level 0-9.
        compression_format: ``"png"`` (ROS default) or ``"rvl"`` (ROS's ``format``
            parameter; larger than PNG on noisy depth, faster to decode).

    Returns:
        A ``CompressedImage`` with format ``"<encoding>; compressedDepth png"`` and
        ``data`` = 12-byte ConfigHeader + 16-bit PNG (``rvl``: ``uint32 cols, rows`` and
        the RVL stream), decodable by ROS subscribers.

    Raises:
        ImageTransportError: any other encoding (e.g. a colour image), a parameter
            out of range or a malformed image.
    """
    encoding = image.encoding
    if encoding not in ("16UC1", "mono16", "32FC1"):
        text = (
            f"Image.encoding is {encoding!r}: compressedDepth needs a depth image, 16UC1 "
            "(millimetres) or 32FC1 (metres); use the compressed transport for other images"
        )
        raise ImageTransportError(text)
    if compression_format not in ("png", "rvl"):
        text = f"compression_format is {compression_format!r}: expected 'png' or 'rvl'"
        raise ImageTransportError(text)
    depth_max = check_positive(depth_max, "depth_max")
    depth_quantization = check_positive(depth_quantization, "depth_quantization")
    params = [cv2.IMWRITE_PNG_COMPRESSION, check_int(png_level, "png_level", 0, 9)]
    depth = _image_array(image)
    if encoding == "32FC1":
        a, b = depth_quantization_params(depth_max, depth_quantization)
        inv = _quantise_inverse_depth(depth, a, b, depth_max)
        header = COMPRESSED_DEPTH_HEADER.pack(_INV_DEPTH, a, b)
        pixels, what = inv, "the quantised inverse depth"
    else:
        limit = int(np.float32(depth_max) * np.float32(1000.0))  # ROS: unsigned short cast
        pixels = np.where(depth > limit, np.uint16(0), depth).astype(np.uint16)
        header = COMPRESSED_DEPTH_HEADER.pack(_INV_DEPTH, 0.0, 0.0)
        what = f"a {encoding} depth image"
    if compression_format == "png":
        body = _encode(".png", pixels, params, what)
    else:
        body = np.frombuffer(compress_rvl(pixels), dtype=np.uint8)
    data = np.concatenate([np.frombuffer(header, dtype=np.uint8), body])
    return CompressedImage(
        header=_copy_header(image.header),
        format=f"{encoding}; compressedDepth {compression_format}",
        data=data,
    )


def _quantise_inverse_depth(
    depth: NDArray[Any], a: float, b: float, depth_max: float
) -> NDArray[np.uint16]:
    d = depth.astype(np.float32, copy=False)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        value = np.float32(a) / d + np.float32(b)
        valid = (d < np.float32(depth_max)) & (d > 0) & (value >= 0) & (value < _UINT16_MAX + 1)
        inv = np.where(valid, value, np.float32(0))
    return np.asarray(inv.astype(np.uint16), dtype=np.uint16)  # truncation, as C++ does


def decompress_depth(msg: CompressedImage) -> Image:
    """Decode a ``compressedDepth`` message (from visnav or from ROS) into an Image.

    Accepts the format strings ROS has written over the years
    (``"32FC1; compressedDepth png"``, ``"16UC1; compressedDepth"``, a bare ``"32FC1"``)
    and the RVL variant (``"32FC1; compressedDepth rvl"``). ``32FC1`` is decoded from
    the quantised inverse depth with the header's (A, B), invalid pixels becoming NaN;
    ``16UC1``/``mono16`` are the stored pixels unchanged.

    Raises:
        ImageTransportError: an unknown variant, data no longer than the 12-byte header,
            undecodable PNG/RVL data or PNG pixels that are not one 16-bit channel.
    """
    fmt = msg.format
    encoding, sep, rest = fmt.partition(";")
    encoding = encoding.strip()
    rvl = bool(sep) and "compressedDepth rvl" in rest and "compressedDepth png" not in rest
    other = "compressedDepth" not in rest or "compressedDepth " in rest
    if sep and "compressedDepth png" not in rest and not rvl and other:
        text = f"CompressedImage.format {fmt!r} is not a compressedDepth PNG or RVL format"
        raise ImageTransportError(text)
    if encoding not in ("16UC1", "mono16", "32FC1"):
        text = (
            f"CompressedImage.format {fmt!r}: compressedDepth carries 16UC1, mono16 or 32FC1, "
            f"not {encoding!r}"
        )
        raise ImageTransportError(text)
    buf = _data_bytes(msg)
    size = COMPRESSED_DEPTH_HEADER.size
    if buf.size <= size:
        text = (
            f"CompressedImage.data has {buf.size} bytes: a compressedDepth message holds a "
            f"{size}-byte ConfigHeader followed by PNG data"
        )
        raise ImageTransportError(text)
    _, a, b = COMPRESSED_DEPTH_HEADER.unpack(buf[:size].tobytes())
    if rvl:
        try:
            pixels = decompress_rvl(buf[size:])
        except RvlError as exc:
            text = f"CompressedImage.format {fmt!r}: {exc}"
            raise ImageTransportError(text) from exc
    else:
        pixels = _decode(buf[size:], f"format {fmt!r}")
    if pixels.dtype != np.uint16 or pixels.ndim != 2:
        text = (
            f"compressedDepth PNG decodes to {pixels.dtype} with shape {pixels.shape}: "
            "expected one uint16 channel"
        )
        raise ImageTransportError(text)
    header = _copy_header(msg.header)
    if encoding != "32FC1":
        return numpy_to_image(pixels, encoding, header=header)
    inv = pixels.astype(np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.float32(a) / (inv - np.float32(b))
    depth = np.where(pixels != 0, depth, np.float32(np.nan)).astype(np.float32)
    return numpy_to_image(depth, "32FC1", header=header)
