"""Image transports by name (image_transport's plugins: ``raw``, ``compressed``, ...).

:data:`IMAGE_TRANSPORTS` maps a transport name, the topic suffix image_transport
uses, to a ``module:function`` factory returning a :class:`TransportCodec` (message
type, encoder, decoder), imported when the transport is used. Adding a transport:
write its codec module and add one line here (and its name to
:data:`~visnav.perception.transport_codecs.KNOWN_TRANSPORTS` if topics should be
recognised by suffix).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from visnav.msgs.types import CompressedImage, Image
from visnav.perception.transport_codecs import (
    ImageTransportError,
    check_int,
    check_positive,
    compress,
    compress_depth,
    decompress,
    decompress_depth,
)
from visnav.plugin_registry import UnknownPluginError, resolve_factory

__all__ = [
    "IMAGE_TRANSPORTS",
    "TransportCodec",
    "TransportOptions",
    "get_transport",
    "make_compressed",
    "make_compressed_depth",
    "make_raw",
]

IMAGE_TRANSPORTS: Mapping[str, str] = {
    "raw": "visnav.perception.transports:make_raw",
    "compressed": "visnav.perception.transports:make_compressed",
    "compressedDepth": "visnav.perception.transports:make_compressed_depth",
}


@dataclass(frozen=True)
class TransportOptions:
    """Publisher options of the built-in transports (image_transport's parameter names).

    Attributes:
        format: ``compressed`` format, ``"jpeg"`` or ``"png"``.
        jpeg_quality: 1-100.
        png_level: 0-9 (both PNG transports).
        depth_max: compressedDepth maximum depth (m).
        depth_quantization: compressedDepth quantisation depth (m).

    Raises:
        ImageTransportError: a value out of range.
    """

    format: str = "jpeg"
    jpeg_quality: int = 80
    png_level: int = 9
    depth_max: float = 10.0
    depth_quantization: float = 100.0

    def __post_init__(self) -> None:
        if self.format not in ("jpeg", "png"):
            text = f"format is {self.format!r}: expected 'jpeg' or 'png'"
            raise ImageTransportError(text)
        check_int(self.jpeg_quality, "jpeg_quality", 1, 100)
        check_int(self.png_level, "png_level", 0, 9)
        check_positive(self.depth_max, "depth_max")
        check_positive(self.depth_quantization, "depth_quantization")


@dataclass(frozen=True)
class TransportCodec:
    """One transport: its message type and how to encode and decode an Image.

    Attributes:
        name: The transport name (topic suffix; ``raw`` has none).
        msg_type: The message type on the transport topic.
        encode: ``(image, options) -> message``; raises ImageTransportError.
        decode: ``(message, desired_encoding) -> Image``; raises ValueError subclasses.
    """

    name: str
    msg_type: type[Any]
    encode: Callable[[Image, TransportOptions], Any]
    decode: Callable[[Any, str | None], Image]


def _raw_decode(msg: Image, desired_encoding: str | None) -> Image:
    del desired_encoding  # the subscription converts raw images itself
    return msg


def make_raw() -> TransportCodec:
    """``raw``: the Image itself."""
    return TransportCodec("raw", Image, lambda image, _o: image, _raw_decode)


def make_compressed() -> TransportCodec:
    """``compressed``: JPEG or PNG in a CompressedImage (compressed_image_transport)."""

    def encode(image: Image, o: TransportOptions) -> CompressedImage:
        return compress(image, format=o.format, jpeg_quality=o.jpeg_quality, png_level=o.png_level)

    def decode(msg: CompressedImage, desired_encoding: str | None) -> Image:
        return decompress(msg, desired_encoding=desired_encoding)

    return TransportCodec("compressed", CompressedImage, encode, decode)


def make_compressed_depth() -> TransportCodec:
    """``compressedDepth``: 16-bit PNG depth (compressed_depth_image_transport)."""

    def encode(image: Image, o: TransportOptions) -> CompressedImage:
        return compress_depth(
            image,
            depth_max=o.depth_max,
            depth_quantization=o.depth_quantization,
            png_level=o.png_level,
        )

    def decode(msg: CompressedImage, desired_encoding: str | None) -> Image:
        image = decompress_depth(msg)
        if desired_encoding not in (None, "passthrough", image.encoding):
            image = decompress(msg, desired_encoding=desired_encoding)
        return image

    return TransportCodec("compressedDepth", CompressedImage, encode, decode)


def get_transport(name: str) -> TransportCodec:
    """The codec of transport ``name``.

    Raises:
        ImageTransportError: not registered, or its factory does not import.
    """
    if name not in IMAGE_TRANSPORTS:
        text = f"transport {name!r} is not supported: visnav has {', '.join(IMAGE_TRANSPORTS)}"
        raise ImageTransportError(text)
    try:
        factory = resolve_factory(name, IMAGE_TRANSPORTS, what="image transport")
    except UnknownPluginError as exc:
        raise ImageTransportError(str(exc)) from exc
    codec = factory()
    if not isinstance(codec, TransportCodec):
        text = f"image transport {name!r}: its factory returned {type(codec).__name__}"
        raise ImageTransportError(text)
    return codec
