"""Where calibration images come from: a directory, a bag, a live topic.

Bag and topic streams hold many near-identical frames; :func:`select_views`
keeps a frame only if the board's position, size or tilt differs from every
view kept so far, as ROS's calibrator does with its sample database.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import image_to_numpy, is_bayer, is_color
from visnav.msgs.types import Image
from visnav.perception._calibration_common import CalibrationError
from visnav.perception.chessboard import board_view_params, find_chessboard, to_gray
from visnav.perception.image_transport import (
    convert_encoding,
    decompress,
    image_transport_subscription,
)

__all__ = [
    "IMAGE_EXTENSIONS",
    "SpinUntil",
    "collect_views_from_topic",
    "images_from_bag",
    "list_image_files",
    "message_pixels",
    "select_views",
]

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")
"""File name suffixes :func:`list_image_files` takes as images (case-insensitive)."""


def list_image_files(directory: str | os.PathLike[str]) -> list[Path]:
    """Return the image files of a directory, sorted by name.

    Raises:
        CalibrationError: not a directory, or no file with an image suffix in it.
    """
    folder = Path(directory)
    if not folder.is_dir():
        text = f"{folder}: not a directory of calibration images"
        raise CalibrationError(text)
    files = sorted(
        p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS
    )
    if not files:
        text = f"{folder}: no image files ({', '.join(IMAGE_EXTENSIONS)})"
        raise CalibrationError(text)
    return files


def message_pixels(msg: Any) -> NDArray[Any]:
    """Return the pixels of an Image or CompressedImage (colour and Bayer as BGR)."""
    if hasattr(msg, "format"):  # CompressedImage
        msg = decompress(msg)
    encoding = msg.encoding
    array = image_to_numpy(msg)
    if is_color(encoding) or is_bayer(encoding):
        array = convert_encoding(array, encoding, "bgr16" if encoding.endswith("16") else "bgr8")
    return array


def images_from_bag(bag: str | os.PathLike[str], topic: str) -> Iterator[tuple[str, NDArray[Any]]]:
    """Yield (name, pixels) for each Image / CompressedImage on ``topic`` in a bag.

    Reads every bag :class:`visnav.bag.BagReader` reads (ROS 1, rosbag2 MCAP / SQLite 3,
    and unclosed or damaged-index bags, recovered with a warning, as ``bag info``/``play``).
    Names are ``"<topic>@<t> s"`` (receive time).

    Raises:
        CalibrationError: the bag cannot be opened or has no such image topic.
        BagError: a message of the bag does not read (names the file and the fix).
    """
    from visnav.bag import BagError, BagReader  # noqa: PLC0415 - only needed for bags

    path = Path(bag)
    try:
        opened = BagReader(path)
    except BagError as exc:
        text = f"{path}: cannot open the bag: {exc}"
        raise CalibrationError(text) from exc
    with opened as reader:
        wanted = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
        meta = reader.topics.get(topic)
        if meta is None or meta.type_name not in wanted:
            topics = sorted(f"{t.name} ({t.type_name})" for t in reader.topics.values())
            text = (
                f"{path}: no Image/CompressedImage topic {topic!r}; "
                f"the bag has: {', '.join(topics)}"
            )
            raise CalibrationError(text)
        for m in reader.messages([topic]):
            yield f"{topic}@{m.t_ns / 1e9:.3f} s", message_pixels(m.msg)


class SpinUntil(Protocol):
    """``spin_until(predicate, timeout_s)``: run callbacks until predicate() or timeout."""

    def __call__(self, predicate: Callable[[], bool], timeout_s: float, /) -> Any:
        """Spin the graph."""


class _ViewSelector:
    """Keeps a frame when its board pose differs from every kept one (ROS's sample database)."""

    def __init__(self, pattern: tuple[int, int], max_views: int, min_view_distance: float) -> None:
        self.pattern = pattern
        self.max_views = max_views
        self.min_view_distance = min_view_distance
        self.kept: list[tuple[str, NDArray[np.uint8]]] = []
        self._params: list[NDArray[np.float64]] = []

    @property
    def full(self) -> bool:
        return len(self.kept) >= self.max_views

    def offer(self, name: str, pixels: NDArray[Any]) -> None:
        if self.full:
            return
        gray = to_gray(pixels, name)
        corners, _ = find_chessboard(gray, self.pattern)
        if corners is None:
            return
        p = board_view_params(corners, self.pattern, (gray.shape[1], gray.shape[0]))
        if all(float(np.abs(p - q).sum()) > self.min_view_distance for q in self._params):
            self.kept.append((name, gray))
            self._params.append(p)


def select_views(
    frames: Iterable[tuple[str, NDArray[Any]]],
    pattern: tuple[int, int],
    *,
    max_views: int = 40,
    min_view_distance: float = 0.2,
) -> list[tuple[str, NDArray[np.uint8]]]:
    """Return up to ``max_views`` frames showing the board in clearly different poses.

    A frame is kept when the board is found and its (x, y, size, skew) differs
    from every kept view by more than ``min_view_distance`` (L1, each in [0, 1]).

    Args:
        frames: (name, pixels) pairs, e.g. from :func:`images_from_bag`.
        pattern: inner corners (columns, rows).
        max_views: stop after this many views.
        min_view_distance: how different a new view must be.

    Returns:
        (name, 8-bit gray pixels) of the kept views, in stream order.
    """
    selector = _ViewSelector(pattern, max_views, min_view_distance)
    for name, pixels in frames:
        selector.offer(name, pixels)
        if selector.full:
            break
    return selector.kept


def collect_views_from_topic(
    node: Any,
    spin_until: SpinUntil,
    topic: str,
    pattern: tuple[int, int],
    *,
    max_views: int = 40,
    min_view_distance: float = 0.2,
    timeout_s: float = 60.0,
) -> list[tuple[str, NDArray[np.uint8]]]:
    """Subscribe to a live image topic and collect distinct chessboard views.

    Args:
        node: the node to subscribe with (``visnav.graph.Node``).
        spin_until: runs the graph's callbacks, e.g. ``context.spin_until``.
        topic: ``image_raw``, ``image_raw/compressed``... (see
            :func:`~visnav.perception.image_transport.image_transport_subscription`).
        pattern: inner corners (columns, rows).
        max_views: stop after this many views.
        min_view_distance: as :func:`select_views`.
        timeout_s: stop listening after this long.

    Returns:
        (name, 8-bit gray pixels) of the kept views; names are ``"<topic>@<stamp>"``.
    """
    selector = _ViewSelector(pattern, max_views, min_view_distance)

    def on_image(msg: Image) -> None:
        stamp = msg.header.stamp
        selector.offer(f"{topic}@{stamp.sec}.{stamp.nanosec:09d}", message_pixels(msg))

    subscription = image_transport_subscription(node, topic, on_image, 5)
    deadline = time.monotonic() + timeout_s
    try:
        spin_until(lambda: selector.full or time.monotonic() >= deadline, timeout_s)
    finally:
        destroy = getattr(node, "destroy_subscription", None)
        if callable(destroy):
            destroy(subscription)
    return selector.kept
