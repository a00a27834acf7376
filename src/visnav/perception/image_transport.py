"""image_transport on the graph: publish an Image with its compressed forms, subscribe decoded.

:class:`ImageTransportPublisher` publishes an ``Image`` on the raw topic and its
compressed forms on the transport topics; :func:`image_transport_subscription`
subscribes to ``image_raw/compressed`` (or any transport topic) and hands the
callback a decoded ``Image``. Transports come from the registry
(:data:`~visnav.perception.transports.IMAGE_TRANSPORTS`); the codecs are plain
functions in :mod:`visnav.perception.transport_codecs`, re-exported here.

Differences from ROS: see :mod:`visnav.perception.transport_codecs`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.msgs.types import CompressedImage, Image
from visnav.perception.transport_codecs import (
    COMPRESSED_DEPTH_HEADER,
    KNOWN_TRANSPORTS,
    SUPPORTED_TRANSPORTS,
    ImageTransportError,
    compress,
    compress_depth,
    convert_encoding,
    decompress,
    decompress_depth,
    depth_quantization_params,
    split_transport_topic,
    transport_topic,
)
from visnav.perception.transports import (
    IMAGE_TRANSPORTS,
    TransportCodec,
    TransportOptions,
    get_transport,
)

__all__ = [
    "COMPRESSED_DEPTH_HEADER",
    "IMAGE_TRANSPORTS",
    "KNOWN_TRANSPORTS",
    "SUPPORTED_TRANSPORTS",
    "ImageTransportError",
    "ImageTransportPublisher",
    "compress",
    "compress_depth",
    "convert_encoding",
    "decompress",
    "decompress_depth",
    "depth_quantization_params",
    "image_transport_subscription",
    "split_transport_topic",
    "transport_topic",
]


class _Publisher(Protocol):
    def publish(self, msg: Any, /) -> None: ...


class _Node(Protocol):
    def create_publisher(self, msg_type: Any, topic: str, qos: Any, /) -> Any: ...

    def create_subscription(
        self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: Any, /
    ) -> Any: ...


def _log(node: Any, level: str, text: str) -> None:
    get_logger = getattr(node, "get_logger", None)
    logger = get_logger() if callable(get_logger) else None
    method = getattr(logger, level, None) or getattr(logger, "warning", None)
    if callable(method):
        method(text)


class ImageTransportPublisher:
    """Publish an Image on ``base_topic`` and its compressed forms, as image_transport does.

    Each transport gets its own publisher: ``raw`` on ``base_topic``,
    ``compressed`` on ``base_topic/compressed``, ``compressedDepth`` on
    ``base_topic/compressedDepth``. A compressed form is only computed when its
    topic has subscriptions (if the publisher can tell). A frame a transport
    cannot encode (a colour image on ``compressedDepth``) is skipped on that
    transport with an error logged through the node's logger (once, then at
    debug level); the other transports still publish it.

    Args:
        node: the node (``visnav.graph.Node``).
        base_topic: the raw image topic, e.g. ``"camera/image_raw"``.
        qos: queue depth or QoS profile, used for every transport topic.
        transports: which of ``raw``, ``compressed``, ``compressedDepth`` to publish.
        format: ``compressed`` format, ``"jpeg"`` or ``"png"``.
        jpeg_quality: 1-100.
        png_level: 0-9 (both PNG transports).
        depth_max: compressedDepth maximum depth in metres.
        depth_quantization: compressedDepth quantisation depth in metres.

    Raises:
        ImageTransportError: an unknown transport or a parameter out of range.
    """

    def __init__(
        self,
        node: _Node,
        base_topic: str,
        qos: Any = 10,
        transports: Sequence[str] = ("raw", "compressed"),
        *,
        format: str = "jpeg",
        jpeg_quality: int = 80,
        png_level: int = 9,
        depth_max: float = 10.0,
        depth_quantization: float = 100.0,
    ) -> None:
        transports = tuple(transports)
        unknown = [t for t in transports if t not in IMAGE_TRANSPORTS]
        if unknown or not transports:
            text = (
                f"transports is {transports!r}: expected a non-empty selection of "
                f"{', '.join(IMAGE_TRANSPORTS)}"
            )
            raise ImageTransportError(text)
        self._options = TransportOptions(
            format=format,
            jpeg_quality=jpeg_quality,
            png_level=png_level,
            depth_max=depth_max,
            depth_quantization=depth_quantization,
        )
        self._codecs: dict[str, TransportCodec] = {t: get_transport(t) for t in transports}
        self.node = node
        self.base_topic = base_topic
        self.transports = transports
        self.publishers: dict[str, Any] = {}
        for transport, codec in self._codecs.items():
            topic = transport_topic(base_topic, transport)
            self.publishers[transport] = node.create_publisher(codec.msg_type, topic, qos)
        self._failed: set[str] = set()

    @property
    def topics(self) -> dict[str, str]:
        """The topic of each transport."""
        return {t: transport_topic(self.base_topic, t) for t in self.transports}

    def publish(self, image: Image) -> None:
        """Publish ``image`` on every transport (compressing only where someone listens)."""
        for transport, pub in self.publishers.items():
            if transport == "raw":
                pub.publish(image)
                continue
            count = getattr(pub, "get_subscription_count", None)
            if callable(count) and count() == 0:
                continue
            try:
                msg = self._codecs[transport].encode(image, self._options)
            except ImageTransportError as exc:
                topic = transport_topic(self.base_topic, transport)
                text = f"image_transport: not publishing on {topic}: {exc}"
                _log(self.node, "debug" if transport in self._failed else "error", text)
                self._failed.add(transport)
                continue
            pub.publish(msg)


def image_transport_subscription(
    node: _Node,
    topic: str,
    callback: Callable[[Image], None],
    qos: Any = 10,
    *,
    transport: str | None = None,
    desired_encoding: str | None = None,
) -> Any:
    """Subscribe to an image through a transport and receive decoded Images.

    The transport is taken from the topic name (``"camera/image_raw/compressed"``)
    or given explicitly (``topic="camera/image_raw", transport="compressed"``, like
    ROS's ``image_transport`` parameter). Messages that cannot be decoded are
    logged through the node's logger and skipped.

    Args:
        node: the node (``visnav.graph.Node``).
        topic: the transport topic or, with ``transport``, the base image topic.
        callback: called with each decoded ``sensor_msgs/Image``.
        qos: queue depth or QoS profile.
        transport: ``raw``, ``compressed`` or ``compressedDepth``; default from ``topic``.
        desired_encoding: convert every image to this encoding (see
            :func:`convert_encoding`); default: as transmitted.

    Returns:
        The subscription object ``node.create_subscription`` returned.

    Raises:
        ImageTransportError: an unsupported transport.
    """
    if transport is None:
        base, transport = split_transport_topic(topic)
    else:
        base = topic
    if transport not in IMAGE_TRANSPORTS:
        text = (
            f"transport {transport!r} (topic {topic!r}) is not supported: visnav decodes "
            f"{', '.join(IMAGE_TRANSPORTS)}"
        )
        raise ImageTransportError(text)
    codec = get_transport(transport)
    full_topic = transport_topic(base, transport)

    def on_image(msg: Image) -> None:
        if desired_encoding is not None and desired_encoding not in ("passthrough", msg.encoding):
            try:
                array = convert_encoding(image_to_numpy(msg), msg.encoding, desired_encoding)
            except ValueError as exc:
                _log(node, "error", f"image_transport: dropped an image on {full_topic}: {exc}")
                return
            msg = numpy_to_image(array, desired_encoding, header=msg.header)
        callback(msg)

    def on_compressed(msg: CompressedImage) -> None:
        try:
            image = codec.decode(msg, desired_encoding)
        except ValueError as exc:
            _log(node, "error", f"image_transport: dropped a message on {full_topic}: {exc}")
            return
        callback(image)

    if transport == "raw":
        return node.create_subscription(Image, full_topic, on_image, qos)
    return node.create_subscription(codec.msg_type, full_topic, on_compressed, qos)
