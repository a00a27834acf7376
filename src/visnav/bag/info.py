"""``bag info``: what a bag holds (``ros2 bag info`` / ``rosbag info``).

Counts, start/end and per-topic first/last times and sizes come from one pass over the
serialized messages (no deserialization), so the figures hold for bags with no index or
statistics too (including recovered ones: unclosed, a damaged index or summary, or a chunk
that fails its CRC, which is skipped).
"""

from __future__ import annotations

import dataclasses
import datetime
import logging
import struct
from pathlib import Path
from typing import Any

from visnav.bag.errors import CorruptBagError
from visnav.bag.metadata import read_drops
from visnav.bag.reader import BagReader
from visnav.bag.storage import ROS1_MAGIC, BagLayout
from visnav.safe_yaml import YamlError, load_yaml_file

_log = logging.getLogger("visnav.bag")

__all__ = ["BagInfo", "TopicStats", "bag_info", "format_info", "stored_compression"]


@dataclasses.dataclass(frozen=True)
class TopicStats:
    """One topic of a bag.

    Attributes:
        name: topic name.
        type_name: ROS 2 type name.
        count: messages.
        size_bytes: serialized bytes of its messages.
        first_ns: time of its first message (0 if none).
        last_ns: time of its last message.
        frequency_hz: ``(count - 1) / (last - first)``; 0 with fewer than 2 messages.
        serialization: ``"cdr"`` or ``"ros1"``.
        qos: the offered QoS profiles, short form (``reliable/volatile/keep_last(10)``).
    """

    name: str
    type_name: str
    count: int
    size_bytes: int
    first_ns: int
    last_ns: int
    frequency_hz: float
    serialization: str
    qos: tuple[str, ...]


@dataclasses.dataclass(frozen=True)
class BagInfo:
    """A bag's summary (:func:`bag_info`).

    Attributes:
        path: the bag.
        storage: ``"mcap"``, ``"sqlite3"`` or ``"ros1"``.
        files: storage file names.
        size_bytes: bytes on disk (all files, metadata included).
        compression: chunk/file compression (``"none"`` if none).
        start_ns: first message time (0 for an empty bag).
        end_ns: last message time.
        message_count: messages.
        topics: per-topic statistics, sorted by name.
        complete: False when the bag was read by scanning: a storage file was never closed,
            or its index, summary or a chunk is damaged (figures cover what was recovered).
        recovery: why it was read by scanning ('' when complete).
        drops: messages the recorder lost per topic (its queue overflowed), from the bag's
            ``visnav_recorder`` metadata; empty when none were lost or the bag has none.
    """

    path: Path
    storage: str
    files: tuple[str, ...]
    size_bytes: int
    compression: str
    start_ns: int
    end_ns: int
    message_count: int
    topics: tuple[TopicStats, ...]
    complete: bool
    recovery: str = ""
    drops: dict[str, int] = dataclasses.field(default_factory=dict)

    @property
    def duration_ns(self) -> int:
        """``end_ns - start_ns``."""
        return self.end_ns - self.start_ns if self.message_count else 0

    def topic(self, name: str) -> TopicStats:
        """Return one topic's statistics.

        Raises:
            KeyError: no such topic.
        """
        for t in self.topics:
            if t.name == name:
                return t
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (times in ns and s)."""
        return {
            "path": str(self.path),
            "storage": self.storage,
            "files": list(self.files),
            "size_bytes": self.size_bytes,
            "compression": self.compression,
            "complete": self.complete,
            "recovery": self.recovery,
            "drops": dict(self.drops),
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "duration_s": self.duration_ns / 1e9,
            "message_count": self.message_count,
            "topics": {
                t.name: {
                    "type": t.type_name,
                    "count": t.count,
                    "size_bytes": t.size_bytes,
                    "frequency_hz": t.frequency_hz,
                    "first_ns": t.first_ns,
                    "last_ns": t.last_ns,
                    "serialization": t.serialization,
                    "qos": list(t.qos),
                }
                for t in self.topics
            },
        }


def _qos_short(q: Any) -> str:
    hist = "keep_all" if q.history.name == "KEEP_ALL" else f"keep_last({q.depth})"
    return f"{q.reliability.name.lower()}/{q.durability.name.lower()}/{hist}"


def _ros1_compression(path: Path) -> str:
    """The compression of the first chunk of a ROS 1 bag (``"none"`` if it has none)."""
    with path.open("rb") as f:
        f.seek(len(ROS1_MAGIC))
        for _ in range(2):  # the bag header record, then the first chunk
            raw = f.read(4)
            if len(raw) < 4:
                return "none"
            (hlen,) = struct.unpack("<I", raw)
            header = f.read(hlen)
            fields: dict[bytes, bytes] = {}
            pos = 0
            while pos + 4 <= len(header):
                (n,) = struct.unpack_from("<I", header, pos)
                key, _, value = header[pos + 4 : pos + 4 + n].partition(b"=")
                fields[key] = value
                pos += 4 + n
            if fields.get(b"op") == b"\x05":
                return fields.get(b"compression", b"none").decode()
            raw = f.read(4)
            if len(raw) < 4:
                return "none"
            f.seek(struct.unpack("<I", raw)[0], 1)
    return "none"


def _mcap_compression(path: Path) -> str:
    """The chunk compression of an MCAP file (from the first chunk record)."""
    with path.open("rb") as f:
        f.seek(8)
        while True:
            head = f.read(9)
            if len(head) < 9:
                return "none"
            op, length = head[0], struct.unpack("<Q", head[1:])[0]
            if op == 0x06:
                body = f.read(min(length, 64))
                if len(body) < 32:
                    return "none"
                (n,) = struct.unpack_from("<I", body, 28)
                return body[32 : 32 + n].decode() or "none"
            if op in (0x0F, 0x02):
                return "none"
            f.seek(length, 1)


def stored_compression(layout: BagLayout) -> str:
    """The bag's compression as stored (``"unknown"`` when the bytes there are damaged)."""
    try:
        return _stored_compression(layout)
    except (ValueError, OSError, OverflowError, struct.error, YamlError, AttributeError):
        return "unknown"


def _stored_compression(layout: BagLayout) -> str:
    if layout.is_ros1:
        return _ros1_compression(layout.files[0])
    if layout.metadata is not None:
        meta = load_yaml_file(layout.metadata, what="rosbag2 metadata")
        meta = meta.get("rosbag2_bagfile_information", {}) if isinstance(meta, dict) else {}
        fmt, mode = meta.get("compression_format") or "", meta.get("compression_mode") or ""
        if fmt:
            return f"{fmt} ({mode.lower() or 'file'})"
    if layout.storage == "mcap":
        return _mcap_compression(layout.files[0])
    return "none"


def _accumulate(reader: BagReader) -> dict[str, list[int]]:
    """``[count, bytes, first, last]`` per topic, in one pass over the serialized messages."""
    acc: dict[str, list[int]] = {}
    for raw in reader.raw_messages():
        a = acc.setdefault(raw.topic, [0, 0, 0, 0])
        if a[0] == 0:
            a[2] = raw.t_ns
        a[0] += 1
        a[1] += len(raw.data)
        a[2] = min(a[2], raw.t_ns)
        a[3] = max(a[3], raw.t_ns)
    for name in reader.topics:  # after the pass: a fallback to scanning may change the topics
        acc.setdefault(name, [0, 0, 0, 0])
    return acc


def bag_info(path: str | Path) -> BagInfo:
    """Summarise a bag.

    Args:
        path: the bag (any format visnav reads; unclosed or damaged files are recovered
            with a warning, see :class:`~visnav.bag.reader.BagReader`).

    Returns:
        The summary.

    Raises:
        BagNotFoundError, UnknownStorageError, CorruptBagError.
    """
    with BagReader(path) as reader:
        try:
            acc = _accumulate(reader)
        except CorruptBagError as exc:
            if reader.recovery or reader.layout.storage not in ("mcap", "ros1"):
                raise
            # a damaged chunk behind an intact index: summarise what a scan recovers
            reader.close()
            cause = str(exc.__cause__ or exc)
            with BagReader(path, scan=True) as scanned:
                acc = _accumulate(scanned)
                skipped = scanned.report.summary()
                _log.warning(
                    "bag '%s': its data does not decode (%s); recovered %d messages by scanning "
                    "the file%s; 'visnav bag reindex %s' rewrites it",
                    scanned.path,
                    cause,
                    sum(a[0] for a in acc.values()),
                    f" ({skipped})" if skipped else "",
                    scanned.path,
                )
                return _summarise(scanned, acc, f"damaged data ({skipped or cause})")
        return _summarise(reader, acc, reader.recovery)


def _summarise(reader: BagReader, acc: dict[str, list[int]], recovery: str) -> BagInfo:
    layout = reader.layout
    stats = []
    for name in sorted(acc):
        count, size, first, last = acc[name]
        meta = reader.topics[name]
        freq = (count - 1) / ((last - first) / 1e9) if count > 1 and last > first else 0.0
        stats.append(
            TopicStats(
                name,
                meta.type_name,
                count,
                size,
                first,
                last,
                freq,
                meta.serialization,
                tuple(_qos_short(q) for q in meta.qos),
            )
        )
    total = sum(s.count for s in stats)
    start = min((s.first_ns for s in stats if s.count), default=0)
    end = max((s.last_ns for s in stats if s.count), default=0)
    on_disk = [layout.path] if layout.path.is_file() else list(layout.path.iterdir())
    return BagInfo(
        path=layout.path,
        storage=layout.storage,
        files=tuple(f.name for f in layout.files),
        size_bytes=sum(p.stat().st_size for p in on_disk if p.is_file()),
        compression=stored_compression(layout),
        start_ns=start,
        end_ns=end,
        message_count=total,
        topics=tuple(stats),
        complete=not recovery,
        recovery=recovery,
        drops=read_drops(layout),
    )


def _size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"  # pragma: no cover


def _stamp(ns: int) -> str:
    dt = datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.timezone.utc)
    return f"{dt:%b %d %Y %H:%M:%S}.{ns % 1_000_000_000 // 1_000_000:03d} UTC ({ns / 1e9:.3f})"


def format_info(info: BagInfo) -> str:
    """Format a summary like ``ros2 bag info`` (with rate and size per topic).

    Returns:
        The text, without a trailing newline.
    """
    lines = [
        f"Files:             {', '.join(info.files)}",
        f"Bag size:          {_size(info.size_bytes)}",
        f"Storage id:        {info.storage}",
        f"Compression:       {info.compression}",
        f"Duration:          {info.duration_ns / 1e9:.3f}s",
    ]
    if info.message_count:
        lines += [
            f"Start:             {_stamp(info.start_ns)}",
            f"End:               {_stamp(info.end_ns)}",
        ]
    lines.append(f"Messages:          {info.message_count}")
    if not info.complete:
        lines.append(
            f"Note:              {info.recovery or 'not closed'}: figures cover what a scan "
            "recovered; 'visnav bag reindex' rewrites it"
        )
    if info.drops:
        dropped = ", ".join(f"{t}: {n}" for t, n in sorted(info.drops.items()))
        lines.append(f"Recorder drops:    {sum(info.drops.values())} ({dropped})")
    if not info.topics:
        lines.append("Topic information: (none)")
        return "\n".join(lines)
    wn = max(len(t.name) for t in info.topics)
    wt = max(len(t.type_name) for t in info.topics)
    wc = max(len(str(t.count)) for t in info.topics)
    for i, t in enumerate(info.topics):
        head = "Topic information: " if i == 0 else " " * 19
        lines.append(
            f"{head}Topic: {t.name:<{wn}} | Type: {t.type_name:<{wt}} | Count: {t.count:>{wc}} | "
            f"Frequency: {t.frequency_hz:8.2f} Hz | Size: {_size(t.size_bytes):>10} | "
            f"Serialization Format: {t.serialization}"
        )
    return "\n".join(lines)
