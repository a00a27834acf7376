"""Bags: record topics, read, summarise, play back and convert (``ros2 bag`` / ``rosbag``).

Formats: rosbag2 with MCAP storage (default), rosbag2 with SQLite 3 storage (read, convert),
and ROS 1 ``.bag`` files. Everything ROS itself writes in those formats reads; what visnav
writes opens in ROS tools, ``rosbags``, the ``mcap`` readers, Rerun and Foxglove.

Library entry points (the ``visnav bag`` verbs wrap them):

* :class:`BagRecorder` (``record``), :class:`BagPlayer` (``play``),
* :func:`read_bag` / :class:`BagReader`, :func:`bag_info` (``info``),
* :func:`convert_bag` (``convert``), :func:`reindex_bag` (``reindex``),
* damaged or unclosed bags are read by scanning (:mod:`visnav.bag.recovery`), with a warning,
* :class:`BagWriter` for writing serialized messages directly,
* :class:`ImageCompression`: images recorded as image_transport's ``compressed`` /
  ``compressedDepth`` topics (:mod:`visnav.bag.image_compression`).
"""

from __future__ import annotations

from visnav.bag.convert import ConvertResult, convert_bag, reindex_bag
from visnav.bag.errors import (
    BagError,
    BagExistsError,
    BagNotFoundError,
    CorruptBagError,
    RecordError,
    TopicNotInBagError,
    UnknownStorageError,
)
from visnav.bag.image_compression import ImageCompression
from visnav.bag.info import BagInfo, TopicStats, bag_info, format_info
from visnav.bag.player import BagPlayer, PlayStats
from visnav.bag.reader import BagMessage, BagReader, RawMessage, TopicMeta, read_bag
from visnav.bag.recorder import BagRecorder, RecordedTopic
from visnav.bag.storage import COMPRESSIONS, FORMATS, BagLayout, detect_layout
from visnav.bag.writer import BagWriter

__all__ = [
    "COMPRESSIONS",
    "FORMATS",
    "BagError",
    "BagExistsError",
    "BagInfo",
    "BagLayout",
    "BagMessage",
    "BagNotFoundError",
    "BagPlayer",
    "BagReader",
    "BagRecorder",
    "BagWriter",
    "ConvertResult",
    "CorruptBagError",
    "ImageCompression",
    "PlayStats",
    "RawMessage",
    "RecordError",
    "RecordedTopic",
    "TopicMeta",
    "TopicNotInBagError",
    "TopicStats",
    "UnknownStorageError",
    "bag_info",
    "convert_bag",
    "detect_layout",
    "format_info",
    "read_bag",
    "reindex_bag",
]
