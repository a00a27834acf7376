"""One writer for every bag format visnav writes: rosbag2 MCAP, ROS 1, rosbag2 SQLite 3.

Messages go in serialized: CDR for visnav's own types (converted to ROS 1 serialization
for a ROS 1 bag) or, for a topic added with ``serialization="ros1"``, ROS 1 bytes copied
as they are (ROS 1 -> ROS 1 conversion of types visnav does not know).
"""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

from rosbags.interfaces import Connection, Qos, QosDurability
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Rosbag2Writer
from rosbags.serde import SerdeError

from visnav.bag.errors import BagError, BagExistsError, CorruptBagError, UnknownStorageError
from visnav.bag.metadata import MCAP_METADATA_NAME, drops_json, write_ros1_drops
from visnav.bag.rosbag2_mcap import Rosbag2McapWriter
from visnav.bag.storage import check_format
from visnav.bag.typeconv import ros1_definition
from visnav.msgs.serde import get_message_class, message_definition, typestore

__all__ = ["BagWriter", "check_bag_name", "default_bag_path", "format_for_output"]


def default_bag_path(path: str | Path, fmt: str) -> Path:
    """Return the output path for ``fmt``: a ROS 1 bag gets a ``.bag`` suffix (as ``rosbag -O``)."""
    p = Path(path)
    if fmt == "ros1" and p.suffix != ".bag":
        return p.with_name(p.name + ".bag")
    return p


def format_for_output(path: str | Path, fmt: str | None) -> str:
    """The format to write ``path`` in when the user gave ``fmt`` (None: not given).

    A ``.bag`` name means a ROS 1 bag (``rosbag record -O x.bag``); anything else rosbag2
    MCAP (``ros2 bag record``'s default).

    Raises:
        UnknownStorageError: ``fmt`` is a rosbag2 format but the name ends in ``.bag``.
    """
    chosen = fmt or ("ros1" if Path(path).suffix == ".bag" else "mcap")
    check_bag_name(Path(path), chosen.lower())
    return chosen


def check_bag_name(path: Path, fmt: str) -> None:
    """Refuse a ``.bag`` name for a rosbag2 format (readers would take it for a ROS 1 file).

    Raises:
        UnknownStorageError: the name ends in ``.bag`` and ``fmt`` is not ``ros1``.
    """
    if path.suffix == ".bag" and fmt != "ros1":
        msg = (
            f"bag output '{path}': a .bag name means a ROS 1 bag file, but format {fmt!r} "
            f"writes a rosbag2 directory; use --format ros1, or a name without .bag "
            f"(e.g. '{path.with_suffix('')}')"
        )
        raise UnknownStorageError(msg)


@dataclasses.dataclass
class _Topic:
    name: str
    type_name: str
    ros1_bytes: bool
    handle: Any
    count: int = 0


class BagWriter:
    """Write a bag.

    Args:
        path: the output: a rosbag2 directory (``mcap``, ``sqlite3``) or a ``.bag`` file
            (``ros1``; the suffix is added when missing). Never overwritten.
        fmt: ``"mcap"`` (default), ``"ros1"`` or ``"sqlite3"``.
        compression: ``"none"``; ``"zstd"`` or ``"lz4"`` chunks for MCAP; ``"lz4"`` or ``"bz2"``
            chunks for ROS 1.
        chunk_size: bytes per chunk before it is closed (MCAP and ROS 1).
        crc: write MCAP chunk and summary CRCs (default), so that readers detect a damaged
            chunk and ``bag reindex`` leaves it out; False stores 0 ("not computed" in MCAP).

    Raises:
        BagExistsError: the output exists.
        UnknownStorageError: unknown format or compression, or a ``.bag`` name for a
            rosbag2 (directory) format: ``.bag`` means a ROS 1 file.

    Example::

        with BagWriter("out", fmt="mcap") as bag:
            t = bag.add_topic("/chatter", "std_msgs/msg/String")
            bag.write(t, time_ns, serialize(String(data="hi")))
    """

    def __init__(
        self,
        path: str | Path,
        *,
        fmt: str = "mcap",
        compression: str = "none",
        chunk_size: int = 1 << 20,
        crc: bool = True,
    ) -> None:
        self.fmt, self.compression = check_format(fmt, compression)
        self.path = default_bag_path(path, self.fmt)
        check_bag_name(self.path, self.fmt)
        if self.path.exists():
            msg = f"bag output '{self.path}' exists already: choose another name or remove it"
            raise BagExistsError(msg)
        if not self.path.parent.exists():
            self.path.parent.mkdir(parents=True)
        self._topics: list[_Topic] = []
        self._mcap: Rosbag2McapWriter | None = None
        self._ros1: Ros1Writer | None = None
        self._sqlite: Rosbag2Writer | None = None
        self._closed = False
        self._drops: dict[str, int] = {}
        self.message_count = 0
        # ROS 1 stores uint32 seconds + nanoseconds; MCAP and SQLite 3 signed/unsigned 64-bit ns
        self._max_time = 2**32 * 1_000_000_000 if self.fmt == "ros1" else 2**63
        if self.fmt == "mcap":
            self._mcap = Rosbag2McapWriter(
                self.path, compression=self.compression, chunk_size=chunk_size, crc=crc
            )
        elif self.fmt == "ros1":
            self._ros1 = Ros1Writer(self.path)
            self._ros1.chunk_threshold = chunk_size
            if self.compression != "none":
                self._ros1.set_compression(Ros1Writer.CompressionFormat[self.compression.upper()])
            self._ros1.open()
            self._ros1.bio.flush()  # type: ignore[union-attr]
        else:
            self._sqlite = Rosbag2Writer(self.path, version=8, storage_plugin=StoragePlugin.SQLITE3)
            self._sqlite.open()

    # ------------------------------------------------------------------ topics
    def add_topic(
        self,
        topic: str,
        type_name: str,
        *,
        qos: Sequence[Qos] = (),
        definition: str | None = None,
        digest: str | None = None,
        serialization: str = "cdr",
    ) -> int:
        """Add a topic (a connection); return the handle to pass to :meth:`write`.

        Args:
            topic: topic name.
            type_name: ROS 2 type name (``pkg/msg/Name``).
            qos: the QoS profiles its publishers offered.
            definition: message definition for a type visnav does not know (``ros2msg`` text
                for rosbag2, ROS 1 ``.msg`` text with ``digest`` = MD5 for ``ros1``).
            digest: the ROS 1 MD5 sum that goes with ``definition``.
            serialization: ``"cdr"`` (default), or ``"ros1"`` to copy ROS 1 bytes into a
                ROS 1 bag.

        Raises:
            BagError: the type is unknown and no definition was given, or ``serialization``
                does not fit the format.
        """
        known = type_name in typestore().types
        if not known and definition is None:
            get_message_class(type_name)  # raises UnknownMessageTypeError with suggestions
        if serialization not in ("cdr", "ros1") or (serialization == "ros1" and not self._ros1):
            msg = (
                f"topic '{topic}': serialization {serialization!r} cannot go into a {self.fmt} "
                "bag: expected 'cdr' (or 'ros1' for a ROS 1 bag)"
            )
            raise BagError(msg)
        if serialization == "cdr" and self._ros1 is not None and not known:
            msg = (
                f"topic '{topic}': type {type_name} is not one of visnav's, so its CDR cannot be "
                "converted to ROS 1; write it to a rosbag2 (mcap) bag instead"
            )
            raise BagError(msg)
        handle: Any
        if self._mcap is not None:
            text = definition if definition is not None else message_definition(type_name)
            handle = self._mcap.add_channel(topic, type_name, text, qos)
        elif self._ros1 is not None:
            if definition is None or digest is None:
                definition, digest = ros1_definition(type_name)
            latching = int(
                bool(qos) and all(q.durability is QosDurability.TRANSIENT_LOCAL for q in qos)
            )
            handle = self._ros1.add_connection(
                topic, type_name, msgdef=definition, md5sum=digest, latching=latching or None
            )
        else:
            assert self._sqlite is not None
            if definition is None:
                handle = self._sqlite.add_connection(
                    topic, type_name, typestore=typestore(), offered_qos_profiles=list(qos)
                )
            else:
                handle = self._sqlite.add_connection(
                    topic,
                    type_name,
                    msgdef=definition,
                    rihs01=digest or "",
                    offered_qos_profiles=list(qos),
                )
        self._topics.append(_Topic(topic, type_name, serialization == "ros1", handle))
        return len(self._topics) - 1

    @property
    def max_time_ns(self) -> int:
        """Record times must be below this (ROS 1 stores uint32 seconds)."""
        return self._max_time

    @property
    def topics(self) -> list[tuple[str, str, int]]:
        """``(topic, type, messages written)`` per added topic."""
        return [(t.name, t.type_name, t.count) for t in self._topics]

    # ------------------------------------------------------------------ messages
    def write(
        self,
        topic: int,
        t_ns: int,
        data: bytes | bytearray | memoryview,
        *,
        publish_ns: int | None = None,
    ) -> None:
        """Append one serialized message (copied before this returns).

        Args:
            topic: the handle from :meth:`add_topic`.
            t_ns: the record time (receive time), ns since the epoch (or sim time).
            data: CDR bytes (ROS 1 bytes for a topic added with ``serialization="ros1"``).
            publish_ns: the publish time (MCAP only; default ``t_ns``).
        """
        t = self._topics[topic]
        if not 0 <= t_ns < self._max_time:
            msg = (
                f"topic '{t.name}': record time {t_ns} ns is outside what a {self.fmt} bag "
                f"stores (0 <= t < {self._max_time})"
            )
            raise BagError(msg)
        if self._mcap is not None:
            self._mcap.write(t.handle, t_ns, data, t_ns if publish_ns is None else publish_ns)
        elif self._ros1 is not None:
            view = memoryview(data)
            raw = view if t.ros1_bytes else self._to_ros1(t, t_ns, view)
            self._ros1.write(t.handle, t_ns, raw)
        else:
            assert self._sqlite is not None
            conn: Connection = t.handle
            self._sqlite.write(conn, t_ns, bytes(data))
        t.count += 1
        self.message_count += 1

    def _to_ros1(self, t: _Topic, t_ns: int, cdr: memoryview) -> memoryview | bytes:
        try:
            return typestore().cdr_to_ros1(cdr, t.type_name)
        except (ValueError, IndexError, KeyError, struct.error, SerdeError, AssertionError) as exc:
            msg = (
                f"topic '{t.name}': message #{t.count} (t={t_ns} ns, {len(cdr)} bytes) is not "
                f"valid CDR of {t.type_name} ({type(exc).__name__}: {exc}), so it cannot be "
                "converted to ROS 1"
            )
            raise CorruptBagError(msg) from exc

    def set_drops(self, drops: dict[str, int]) -> None:
        """Store the messages a recorder lost per topic; written into the bag on :meth:`close`.

        MCAP: a ``visnav_recorder`` Metadata record; ROS 1: a header field (see
        :mod:`visnav.bag.metadata`); SQLite 3: not stored.
        """
        self._drops = {t: n for t, n in drops.items() if n > 0}

    def flush(self) -> None:
        """Put everything written so far into the file (closes the open chunk).

        After this, killing the process loses nothing written before the call (SQLite 3:
        no effect; it commits on :meth:`close`).
        """
        if self._mcap is not None:
            self._mcap.flush()
        elif self._ros1 is not None:
            self._ros1.write_chunk(self._ros1.chunks[-1])
            self._ros1.bio.flush()  # type: ignore[union-attr]

    def close(self) -> None:
        """Finish the bag: indexes, summary, ``metadata.yaml`` (idempotent)."""
        if self._closed:
            return
        self._closed = True
        if self._mcap is not None:
            if self._drops:
                self._mcap.add_metadata(MCAP_METADATA_NAME, {"drops": drops_json(self._drops)})
            self._mcap.close()
        elif self._ros1 is not None:
            try:
                self._ros1.close()
            finally:
                bio = self._ros1.bio
                if bio is not None and not bio.closed:  # close() failed half-way (disk full)
                    bio.close()
            if self._drops:
                write_ros1_drops(self.path, self._drops)
        elif self._sqlite is not None:
            self._sqlite.close()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
