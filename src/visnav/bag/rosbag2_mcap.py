"""A rosbag2 directory with MCAP storage, written with the ``mcap`` package.

What ``ros2 bag record`` (Humble, ``-s mcap``) writes: ``<name>/<name>_0.mcap`` with profile
``ros2``, one ``ros2msg`` schema per type (the ``.msg`` text with its dependencies), one ``cdr``
channel per topic whose metadata holds ``offered_qos_profiles``, and ``<name>/metadata.yaml``
(version 5). Foxglove, Rerun, the ``mcap`` CLI/readers, ``rosbags`` and ROS 2 read it.

Why not ``rosbags.rosbag2.Writer``: its MCAP storage (0.11) compresses chunks with zstd only,
closes a chunk only when it reaches 1 MiB and keeps the file buffered until ``close()``; a
recorder needs lz4 too and a flush on a timer, so that a killed recording keeps every chunk
written before the last flush. ``metadata.yaml`` is written when the bag opens and rewritten
(atomically) at a flush that follows a new topic or comes 5 s after the last rewrite (a YAML
dump of every topic costs ~10 ms: rewriting it on every 0.5 s flush took ~2 % of a core), so
even a killed recording has one, with counts at most 5 s old (``visnav bag reindex`` recounts).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.interfaces import Qos

from visnav import __version__
from visnav.bag.qos import qos_to_yaml

__all__ = ["METADATA_VERSION", "Rosbag2McapWriter", "write_metadata"]

_METADATA_PERIOD_S = 5.0  # metadata.yaml is rewritten at most this often on flushes

METADATA_VERSION = 5  # Humble's; newer ROS 2 and rosbags read it too
_COMPRESSION = {
    "none": CompressionType.NONE,
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
}


@dataclasses.dataclass
class _Topic:
    name: str
    type_name: str
    qos_yaml: str
    serialization: str = "cdr"
    count: int = 0


def write_metadata(
    directory: Path,
    *,
    storage: str,
    files: Sequence[str],
    topics: Sequence[tuple[str, str, str, str, int]],
    start_ns: int,
    end_ns: int,
    compression_format: str = "",
    compression_mode: str = "",
) -> None:
    """Write ``metadata.yaml`` (rosbag2 version 5) atomically.

    Args:
        directory: the bag directory.
        storage: ``"mcap"`` or ``"sqlite3"``.
        files: storage file names relative to ``directory``.
        topics: ``(name, type, serialization_format, offered_qos_yaml, message_count)``.
        start_ns: first message time (0 for an empty bag).
        end_ns: last message time.
        compression_format: rosbag2 file/message compression (``""`` for none).
        compression_mode: ``""``, ``"file"`` or ``"message"``.
    """
    count = sum(t[4] for t in topics)
    duration = max(0, end_ns - start_ns) if count else 0
    start = start_ns if count else 0
    info: dict[str, Any] = {
        "version": METADATA_VERSION,
        "storage_identifier": storage,
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": count,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": name,
                    "type": type_name,
                    "serialization_format": fmt,
                    "offered_qos_profiles": qos,
                },
                "message_count": n,
            }
            for name, type_name, fmt, qos, n in topics
        ],
        "compression_format": compression_format,
        "compression_mode": compression_mode,
        "relative_file_paths": list(files),
        "files": [
            {
                "path": f,
                "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration},
                "message_count": count,
            }
            for f in files
        ],
    }
    text = yaml.safe_dump(
        {"rosbag2_bagfile_information": info}, sort_keys=False, default_flow_style=False
    )
    tmp = directory / "metadata.yaml.tmp"
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(directory / "metadata.yaml")


class Rosbag2McapWriter:
    """Write a rosbag2 MCAP directory (the caller checks that ``directory`` does not exist).

    Args:
        directory: the bag directory to create.
        compression: chunk compression, ``"none"``, ``"zstd"`` or ``"lz4"``.
        chunk_size: close a chunk once it holds this many bytes.
        crc: write chunk and summary CRCs (readers then detect damaged chunks).
    """

    def __init__(
        self,
        directory: Path,
        *,
        compression: str = "none",
        chunk_size: int = 1 << 20,
        crc: bool = True,
    ) -> None:
        directory.mkdir(parents=True)
        self.directory = directory
        self.path = directory / f"{directory.name}_0.mcap"
        self._stream = self.path.open("xb")
        self._mcap: Any = McapWriter(
            self._stream,
            chunk_size=chunk_size,
            compression=_COMPRESSION[compression],
            enable_crcs=crc,
        )
        self._mcap.start(profile="ros2", library=f"visnav-{__version__}")
        self._schemas: dict[str, int] = {}
        self._topics: dict[int, _Topic] = {}
        self._start = 2**63 - 1
        self._end = 0
        self._closed = False
        self._metadata_at = (-1, 0.0)  # (topics, monotonic time) of the last metadata.yaml
        self._write_metadata()

    def add_channel(
        self,
        topic: str,
        type_name: str,
        definition: str,
        qos: Sequence[Qos] = (),
    ) -> int:
        """Register a topic; return its channel id.

        Args:
            topic: topic name.
            type_name: ROS 2 type name.
            definition: the message definition (``.msg`` text with dependencies).
            qos: the offered QoS profiles.
        """
        sid = self._schemas.get(type_name)
        if sid is None:
            idl = definition.startswith("=" * 80 + "\nIDL: ")
            encoding = "ros2idl" if idl else "ros2msg"
            sid = self._mcap.register_schema(type_name, encoding, definition.encode())
            self._schemas[type_name] = sid
        qos_yaml = qos_to_yaml(qos)
        cid: int = self._mcap.register_channel(
            topic, "cdr", sid, {"offered_qos_profiles": qos_yaml}
        )
        self._topics[cid] = _Topic(topic, type_name, qos_yaml)
        return cid

    def write(
        self, channel: int, t_ns: int, data: bytes | bytearray | memoryview, publish_ns: int
    ) -> None:
        """Append a CDR message (the data is copied before this returns)."""
        self._mcap.add_message(channel, t_ns, data, publish_ns)
        self._topics[channel].count += 1
        self._start = min(self._start, t_ns)
        self._end = max(self._end, t_ns)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """Write an MCAP Metadata record (key-value strings) into the data section."""
        self._mcap.add_metadata(name, data)

    def flush(self) -> None:
        """Close the current chunk, hand the file its bytes and rewrite ``metadata.yaml``."""
        self._mcap.flush()
        topics, written = self._metadata_at
        if topics != len(self._topics) or time.monotonic() - written >= _METADATA_PERIOD_S:
            self._write_metadata()

    def close(self) -> None:
        """Write the MCAP summary and footer and the final ``metadata.yaml`` (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._mcap.finish()
        finally:
            self._stream.close()
        self._write_metadata()

    def _write_metadata(self) -> None:
        self._metadata_at = (len(self._topics), time.monotonic())
        write_metadata(
            self.directory,
            storage="mcap",
            files=[self.path.name],
            topics=[
                (t.name, t.type_name, t.serialization, t.qos_yaml, t.count)
                for t in self._topics.values()
            ],
            start_ns=self._start,
            end_ns=self._end,
        )
