"""Images in bags through image_transport's compressed transports (record side and read side).

Recording (:class:`ImageCompression`, used by :class:`~visnav.bag.BagRecorder` with
``image_transport=``): a ``sensor_msgs/Image`` topic is stored as the topic an image_transport
publisher would have sent it on, ``<image topic>/compressed`` or
``<image topic>/compressedDepth``, of type ``sensor_msgs/CompressedImage``, exactly as the
``compressed_image_transport`` and ``compressed_depth_image_transport`` plugins write it
(codecs: :mod:`visnav.perception.transport_codecs`):

* colour and mono 8-bit images: JPEG, format ``"rgb8; jpeg compressed bgr8"`` (quality 80,
  the plugin's default ``jpeg_quality``); 16-bit colour/mono images: PNG (``png_level`` 9,
  the plugin's default), where ROS's JPEG default would saturate them to 8 bits;
* depth, ``32FC1`` (m) and ``16UC1`` (mm): ``compressedDepth``, the 12-byte ConfigHeader
  and a 16-bit PNG (32FC1 as quantised inverse depth; ``depth_max`` 10 m,
  ``depth_quantization`` 100 and ``png_level`` 1, the plugin's defaults: deeper pixels
  become invalid, NaN when read back); with ``format`` ``rvl`` (the plugin's other
  lossless format, same quantisation) the RVL stream instead of the PNG;
* any other encoding (float colour, signed, 64-bit): stored raw on its own topic, with one
  log line.

The transport is chosen per topic from its first message. Encoding runs on the recorder's
writer thread, not the executor's.

Reading (:func:`transport_base`, :func:`decode_image`, :func:`image_topics`): the readers
(``visnav view``, ``doctor --bag``, ``slam --bag``, ``bag play --decompress``) find an
image topic's compressed form in a bag and decode it to an ``Image`` as an image_transport
subscriber does.

The defaults are ROS 1 (noetic) image_transport_plugins': ``jpeg_quality`` 80, ``png_level``
9 and compressedDepth's ``png_level`` 1 (ROS 2 Humble's plugins default to 95, 3 and 9, later
ROS 2 releases' compressedDepth to 3; any subscriber decodes either).
:meth:`ImageCompression.from_params` takes the plugins' parameter names
(``compressed.jpeg_quality``, ``compressedDepth.format``, ...), as ``visnav run
--image-transport`` and ``visnav bag record --image-transport`` do. compressedDepth ``rvl``
is decoded by ROS 1 noetic's plugin and ROS 2's from Jazzy on, not by Humble's.

Where visnav differs from image_transport: 16-bit colour/mono images go to PNG, not JPEG
(above); ROS publishes every transport of every image (a depth image also gets a
``/compressed`` topic, whose JPEG encoder refuses 32FC1 with an error per frame), the
recorder stores one transport per image topic, the one a ROS user records. The PNG bytes
may differ from libpng's in ROS (another zlib); the format is the same.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from typing import Any

from visnav.msgs.serde import deserialize, serialize
from visnav.msgs.types import CompressedImage, Image
from visnav.perception.transport_codecs import (
    ImageTransportError,
    check_int,
    check_positive,
    compress,
    compress_depth,
    decompress,
    split_transport_topic,
    transport_topic,
)

__all__ = [
    "COMPRESSED_IMAGE",
    "DEPTH_ENCODINGS",
    "IMAGE",
    "IMAGE_TRANSPORT_PARAMS",
    "ImageCompression",
    "decode_image",
    "image_topics",
    "image_transport_from_args",
    "transport_base",
]

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
DEPTH_ENCODINGS = frozenset({"32FC1", "16UC1"})
"""Encodings stored through ``compressedDepth`` (what the plugin takes as depth)."""

_COMPRESSIBLE = frozenset(
    {
        "mono8",
        "mono16",
        "rgb8",
        "bgr8",
        "rgba8",
        "bgra8",
        "rgb16",
        "bgr16",
        "rgba16",
        "bgra16",
        "8UC1",
        "8UC3",
        "8UC4",
        "16UC3",
        "16UC4",
    }
)
_DECODABLE_TRANSPORTS = ("compressed", "compressedDepth")
IMAGE_TRANSPORT_PARAMS = {
    "compressed.jpeg_quality": "jpeg_quality",
    "compressed.png_level": "png_level",
    "compressedDepth.format": "depth_format",
    "compressedDepth.png_level": "depth_png_level",
    "compressedDepth.depth_max": "depth_max",
    "compressedDepth.depth_quantization": "depth_quantization",
}
"""image_transport plugin parameter (``<transport>.<name>``) -> :class:`ImageCompression` field."""


@dataclasses.dataclass(frozen=True)
class ImageCompression:
    """How a recorder stores Image topics: image_transport's plugin parameters.

    Attributes:
        jpeg_quality: JPEG quality 1-100 (compressed_image_transport ``jpeg_quality``, 80).
        png_level: zlib level 0-9 of compressed's PNG (compressed_image_transport
            ``png_level``, 9).
        depth_png_level: zlib level 0-9 of compressedDepth's PNG
            (compressed_depth_image_transport ``png_level``, 1: level 9 costs ~0.7 s per
            640x480 noisy depth frame here for a PNG ~25 % smaller).
        depth_max: compressedDepth ``depth_max`` in metres (10).
        depth_quantization: compressedDepth ``depth_quantization`` in metres (100).
        depth_format: compressedDepth ``format``, ``"png"`` (default) or ``"rvl"`` (the
            same quantised values, run-length/variable-length coded: ~3x cheaper to encode
            than PNG and, inside the bag's zstd chunks, ~20 % smaller for noisy depth).

    Raises:
        ImageTransportError: a value out of range (the message names it).
    """

    jpeg_quality: int = 80
    png_level: int = 9
    depth_png_level: int = 1
    depth_max: float = 10.0
    depth_quantization: float = 100.0
    depth_format: str = "png"

    def __post_init__(self) -> None:
        check_int(self.jpeg_quality, "jpeg_quality", 1, 100)
        check_int(self.png_level, "png_level", 0, 9)
        check_int(self.depth_png_level, "depth_png_level", 0, 9)
        check_positive(self.depth_max, "depth_max")
        check_positive(self.depth_quantization, "depth_quantization")
        if self.depth_format not in ("png", "rvl"):
            text = (
                f"compressedDepth.format is {self.depth_format!r}: expected 'png' or 'rvl' "
                "(compressed_depth_image_transport's formats)"
            )
            raise ImageTransportError(text)

    @classmethod
    def from_params(cls, params: Mapping[str, str | int | float]) -> ImageCompression:
        """The policy of image_transport plugin parameters, the rest at their defaults.

        Args:
            params: ``{name: value}`` with names as the plugins declare them,
                ``compressed.jpeg_quality``, ``compressed.png_level``,
                ``compressedDepth.format``, ``compressedDepth.png_level``,
                ``compressedDepth.depth_max``, ``compressedDepth.depth_quantization``
                (``/`` also separates, as in ROS 1's ``.../compressed/jpeg_quality``); a
                value may be text (from a command line).

        Raises:
            ImageTransportError: an unknown name or a value of the wrong type or range.
        """
        fields: dict[str, Any] = {}
        for name, value in params.items():
            key = IMAGE_TRANSPORT_PARAMS.get(name.strip("/").replace("/", "."))
            if key is None:
                text = (
                    f"image_transport parameter {name!r} is not known: expected one of "
                    f"{', '.join(IMAGE_TRANSPORT_PARAMS)}"
                )
                raise ImageTransportError(text)
            fields[key] = _param_value(name, key, value)
        return cls(**fields)

    @staticmethod
    def transport_for(encoding: str) -> str:
        """``compressedDepth``, ``compressed`` or ``raw`` (not compressible) for an encoding."""
        if encoding in DEPTH_ENCODINGS:
            return "compressedDepth"
        if encoding in _COMPRESSIBLE or encoding.startswith("bayer_"):
            return "compressed"
        return "raw"

    def encode(self, image: Image, transport: str) -> CompressedImage:
        """Compress ``image`` for ``transport`` (``compressed`` or ``compressedDepth``).

        Raises:
            ImageTransportError: the image does not fit the transport (its encoding changed
                since the transport was chosen) or is malformed.
        """
        if transport == "compressedDepth":
            return compress_depth(
                image,
                depth_max=self.depth_max,
                depth_quantization=self.depth_quantization,
                png_level=self.depth_png_level,
                compression_format=self.depth_format,
            )
        if transport != "compressed":
            text = f"transport is {transport!r}: expected 'compressed' or 'compressedDepth'"
            raise ImageTransportError(text)
        sixteen = image.encoding.endswith("16") or image.encoding.startswith("16U")
        return compress(
            image,
            format="png" if sixteen else "jpeg",
            jpeg_quality=self.jpeg_quality,
            png_level=self.png_level,
        )

    def encode_cdr(self, data: bytes | memoryview, transport: str) -> bytes:
        """CDR bytes of an Image -> CDR bytes of its CompressedImage (the writer thread's job).

        Raises:
            ImageTransportError: as :meth:`encode`; MessageError: bytes that do not decode.
        """
        return serialize(self.encode(deserialize(data, IMAGE), transport))

    @staticmethod
    def topic(base_topic: str, transport: str) -> str:
        """The topic the transport of ``base_topic`` is stored on (``raw``: the topic itself)."""
        return transport_topic(base_topic, transport)


def image_transport_from_args(items: Iterable[str] | None) -> ImageCompression:
    """The policy of a command line's ``NAME=VALUE`` (or ``NAME:=VALUE``) image_transport items.

    Raises:
        ImageTransportError: an item without ``=``, an unknown name or a bad value.
    """
    params: dict[str, str] = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name.rstrip(":"):
            text = (
                f"--image-transport item {item!r}: expected NAME=VALUE, e.g. "
                "compressed.jpeg_quality=50 or compressedDepth.format=rvl"
            )
            raise ImageTransportError(text)
        params[name.rstrip(":")] = value
    return ImageCompression.from_params(params)


def _param_value(name: str, key: str, value: str | int | float) -> str | int | float:
    """``value`` as the type of field ``key`` (text from a command line converted)."""
    if key == "depth_format":
        return str(value)
    kind: type[int] | type[float] = float if key in ("depth_max", "depth_quantization") else int
    if isinstance(value, str):
        try:
            return kind(value)
        except ValueError:
            text = f"image_transport parameter {name} is {value!r}: expected a {kind.__name__}"
            raise ImageTransportError(text) from None
    return value


def transport_base(topic: str, type_name: str) -> tuple[str, str] | None:
    """``(base image topic, transport)`` of a compressed image topic, else None.

    ``/camera/image_raw/compressed`` (``sensor_msgs/msg/CompressedImage``) gives
    ``("/camera/image_raw", "compressed")``; a CompressedImage topic without a transport
    suffix counts as ``compressed`` of itself, as image_transport cannot name it otherwise.
    """
    if type_name != COMPRESSED_IMAGE:
        return None
    base, transport = split_transport_topic(topic)
    if transport == "raw":
        return topic, "compressed"
    if transport not in _DECODABLE_TRANSPORTS:
        return None
    return base, transport


def decode_image(msg: Any) -> Image:
    """An Image from an Image (returned as is) or a CompressedImage (decoded).

    Raises:
        ImageTransportError: compressed data that do not decode (a ``ValueError``).
    """
    if isinstance(msg, CompressedImage):
        return decompress(msg)
    if isinstance(msg, Image):
        return msg
    text = f"message is a {type(msg).__name__}: expected sensor_msgs/Image or CompressedImage"
    raise ImageTransportError(text)


def image_topics(topics: Mapping[str, str] | Iterable[tuple[str, str]]) -> dict[str, str]:
    """Image topics of a bag as a subscriber would name them: ``{base topic: stored topic}``.

    A raw ``Image`` topic maps to itself; a ``CompressedImage`` transport topic
    (``.../compressed``, ``.../compressedDepth``) maps from its base topic, unless the
    base topic itself is in the bag (raw wins, as it is exact).

    Args:
        topics: ``{topic: type name}`` or ``(topic, type name)`` pairs.
    """
    items = list(topics.items() if isinstance(topics, Mapping) else topics)
    out: dict[str, str] = {t: t for t, type_name in items if type_name == IMAGE}
    for topic, type_name in items:
        found = transport_base(topic, type_name)
        if found is not None and found[0] not in out:
            out[found[0]] = topic
    return out
