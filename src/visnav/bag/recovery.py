"""Reading storage files without their index: never closed, or with a damaged index.

An MCAP file without its footer (or with a damaged summary), or a ROS 1 bag whose header has
no index position (or whose index is damaged), still holds every chunk that reached the
disk. These scanners walk the file record by record, stop at the first record that is cut
short, and yield the connections and messages of the complete records: what
``ros2 bag reindex`` / ``rosbag reindex`` would recover.

Given a :class:`ScanReport`, a scan does not raise on damage: a chunk whose bytes do not
decode (MCAP CRC mismatch, bad compression, a record running past its end) is skipped, a
damaged record outside a chunk ends the scan, and both are written into the report.
Without one, damage raises :class:`~visnav.bag.errors.CorruptBagError`.
"""

from __future__ import annotations

import bz2
import dataclasses
import struct
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

import lz4.frame  # type: ignore[import-untyped]
import zstandard
from rosbags.interfaces import Qos
from rosbags.rosbag2.metadata import parse_qos

from visnav.bag.errors import CorruptBagError
from visnav.bag.qos import latched_qos
from visnav.bag.storage import MCAP_MAGIC, ROS1_MAGIC

__all__ = ["RecoveredChannel", "RecoveredMessage", "ScanReport", "scan_mcap", "scan_ros1"]

_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_MSG_HEAD = struct.Struct("<HIQQ")  # channel, sequence, log time, publish time
_CHUNK_HEAD = struct.Struct("<QQQI")  # start, end, uncompressed size, crc
_MAX_CHUNK = 1 << 30  # a larger uncompressed size is damage, not data (writers use ~1 MiB)
# what damaged bytes raise while being parsed
_DAMAGE = (
    KeyError,
    IndexError,
    EOFError,  # bz2: a stream cut short
    struct.error,
    ValueError,
    OSError,
    RuntimeError,
    OverflowError,
    MemoryError,
    zstandard.ZstdError,
)


@dataclasses.dataclass(frozen=True)
class RecoveredChannel:
    """A connection found in an unclosed file.

    Attributes:
        id: the channel (MCAP) or connection (ROS 1) id.
        topic: topic name.
        type_name: message type, ROS 2 spelling (``pkg/msg/Name``).
        definition: the message definition text (``ros2msg`` or ROS 1 ``.msg``).
        digest: the ROS 1 MD5 sum (empty for MCAP).
        qos: offered QoS profiles (ROS 1: latched -> transient local).
        ros1: True when messages are ROS 1 serialized.
    """

    id: int
    topic: str
    type_name: str
    definition: str
    digest: str
    qos: tuple[Qos, ...]
    ros1: bool


@dataclasses.dataclass
class ScanReport:
    """What a tolerant scan left out (filled in while scanning).

    Attributes:
        skipped: one line per damaged chunk that was skipped (file, byte offset, reason).
        stopped: why the scan ended early at a damaged record ('' when it did not).
    """

    skipped: list[str] = dataclasses.field(default_factory=list)
    stopped: str = ""

    def summary(self) -> str:
        """One clause for a warning: what was skipped and where the scan stopped."""
        parts = []
        if self.skipped:
            n = len(self.skipped)
            parts.append(f"skipped {n} damaged chunk{'s' if n > 1 else ''} ({self.skipped[0]})")
        if self.stopped:
            parts.append(f"stopped at {self.stopped}")
        return "; ".join(parts)


@dataclasses.dataclass(frozen=True)
class RecoveredMessage:
    """A message found in an unclosed file."""

    channel: int
    t_ns: int
    data: bytes


class _Buf:
    """A little-endian cursor over bytes."""

    def __init__(self, data: bytes | memoryview) -> None:
        self.data = memoryview(data)
        self.pos = 0

    def u16(self) -> int:
        (v,) = _U16.unpack_from(self.data, self.pos)
        self.pos += 2
        return int(v)

    def u32(self) -> int:
        (v,) = _U32.unpack_from(self.data, self.pos)
        self.pos += 4
        return int(v)

    def u64(self) -> int:
        (v,) = _U64.unpack_from(self.data, self.pos)
        self.pos += 8
        return int(v)

    def take(self, n: int) -> memoryview:
        if self.pos + n > len(self.data):
            msg = "a field runs past the end of its record"
            raise ValueError(msg)
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def string(self) -> str:
        return bytes(self.take(self.u32())).decode("utf-8")


def _ros2_type(name: str) -> str:
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


def _open(path: Path, magic: bytes, what: str) -> tuple[BinaryIO, int]:
    size = path.stat().st_size
    f = path.open("rb")
    if f.read(len(magic)) != magic:
        f.close()
        if size == 0:
            msg = f"bag file '{path}' is empty: nothing was recorded into it"
        else:
            msg = f"'{path}' does not start with the {what} magic bytes: not a {what} file"
        raise CorruptBagError(msg)
    return f, size


def _damaged(path: Path, where: int, exc: BaseException) -> CorruptBagError:
    text = str(exc) or type(exc).__name__
    return CorruptBagError(
        f"'{path}': the record at byte {where} does not decode ({text}): the file is damaged"
    )


def _tolerate(
    report: ScanReport | None, path: Path, where: int, exc: BaseException, *, chunk: bool
) -> None:
    """Raise for a strict scan; note the damage in ``report`` for a tolerant one."""
    if report is None:
        raise _damaged(path, where, exc) from exc
    text = str(exc) or type(exc).__name__
    if chunk:
        report.skipped.append(f"'{path}' chunk at byte {where}: {text}")
    else:
        report.stopped = f"'{path}' byte {where}: {text}"


# ---------------------------------------------------------------------------- MCAP
def _mcap_record(
    op: int, body: memoryview, schemas: dict[int, tuple[str, str, str]]
) -> Iterator[RecoveredChannel | RecoveredMessage]:
    if op == 0x05:
        channel, _seq, log_time, _pub = _MSG_HEAD.unpack_from(body, 0)
        yield RecoveredMessage(channel, log_time, bytes(body[_MSG_HEAD.size :]))
    elif op == 0x03:
        b = _Buf(body)
        sid = b.u16()
        name, encoding = b.string(), b.string()
        data = bytes(b.take(b.u32())).decode("utf-8")
        schemas[sid] = (name, encoding, data)
    elif op == 0x04:
        b = _Buf(body)
        cid, sid = b.u16(), b.u16()
        topic, encoding = b.string(), b.string()
        meta = _Buf(b.take(b.u32()))
        qos_text = ""
        while meta.pos < len(meta.data):
            key, value = meta.string(), meta.string()
            if key == "offered_qos_profiles":
                qos_text = value
        name, _enc, definition = schemas.get(sid, ("", "", ""))
        yield RecoveredChannel(
            cid,
            topic,
            name,
            definition,
            "",
            tuple(parse_qos(qos_text)) if qos_text else (),
            ros1=encoding == "ros1",
        )


def _mcap_chunk(
    body: bytes, schemas: dict[int, tuple[str, str, str]]
) -> list[RecoveredChannel | RecoveredMessage]:
    _start, _end, usize, crc = _CHUNK_HEAD.unpack_from(body, 0)
    b = _Buf(body)
    b.pos = _CHUNK_HEAD.size
    kind = b.string()
    records = b.take(b.u64())
    if usize > _MAX_CHUNK:
        msg = f"the chunk says it holds {usize} bytes uncompressed (more than 1 GiB)"
        raise ValueError(msg)
    if kind == "":
        raw = bytes(records)
    elif kind == "zstd":
        raw = zstandard.ZstdDecompressor().decompress(records, max_output_size=usize)
    elif kind == "lz4":
        raw = bytes(lz4.frame.decompress(records))
    else:
        msg = f"unknown chunk compression {kind!r}"
        raise ValueError(msg)
    if len(raw) != usize or (crc and zlib.crc32(raw) != crc):
        msg = "the chunk fails its size/CRC check"
        raise ValueError(msg)
    out: list[RecoveredChannel | RecoveredMessage] = []
    view = memoryview(raw)
    pos = 0
    while pos + 9 <= len(view):
        op = view[pos]
        (length,) = _U64.unpack_from(view, pos + 1)
        if pos + 9 + length > len(view):
            msg = "a record runs past the end of its chunk"
            raise ValueError(msg)
        out.extend(_mcap_record(op, view[pos + 9 : pos + 9 + length], schemas))
        pos += 9 + length
    return out


def scan_mcap(
    path: Path, report: ScanReport | None = None
) -> Iterator[RecoveredChannel | RecoveredMessage]:
    """Yield the channels and messages of an MCAP file, stopping at a cut-short record.

    Args:
        path: the ``.mcap`` file (closed or not).
        report: collect damage here instead of raising (damaged chunks are skipped).

    Yields:
        :class:`RecoveredChannel` before the messages that use it, then messages in file
        order (time order inside each chunk).

    Raises:
        CorruptBagError: not an MCAP file, or (without ``report``) a complete record that
            does not decode.
    """
    f, size = _open(path, MCAP_MAGIC, "MCAP")
    with f:
        schemas: dict[int, tuple[str, str, str]] = {}
        pos = len(MCAP_MAGIC)
        while pos + 9 <= size:
            head = f.read(9)
            op = head[0]
            (length,) = _U64.unpack_from(head, 1)
            if pos + 9 + length > size or op == 0x0F:
                return  # cut short (the recorder died while writing it), or the data end
            where = pos
            pos += 9 + length
            if op not in (0x03, 0x04, 0x05, 0x06):
                f.seek(pos)
                continue
            try:
                body = f.read(length)
                if op == 0x06:
                    items = _mcap_chunk(body, schemas)
                else:
                    items = list(_mcap_record(op, memoryview(body), schemas))
            except _DAMAGE as exc:
                _tolerate(report, path, where, exc, chunk=op == 0x06)
                if op != 0x06:
                    return
                f.seek(pos)
                continue
            yield from items


# ---------------------------------------------------------------------------- ROS 1
def _fields(header: bytes | memoryview) -> dict[str, bytes]:
    out: dict[str, bytes] = {}
    pos = 0
    while pos + 4 <= len(header):
        (n,) = _U32.unpack_from(header, pos)
        if pos + 4 + n > len(header):
            msg = "a header field runs past its header"
            raise ValueError(msg)
        field = bytes(header[pos + 4 : pos + 4 + n])
        pos += 4 + n
        key, _, value = field.partition(b"=")
        out[key.decode("ascii")] = value
    return out


def _ros1_item(
    fields: dict[str, bytes], data: bytes | memoryview, seen: set[int]
) -> RecoveredChannel | RecoveredMessage | None:
    op = fields.get("op", b"\x00")[0]
    if op == 0x07:
        conn = _fields(data)
        cid = _U32.unpack(fields["conn"])[0]
        if cid in seen:
            return None
        seen.add(cid)
        latching = conn.get("latching", b"0") not in (b"", b"0")
        return RecoveredChannel(
            cid,
            fields.get("topic", conn.get("topic", b"")).decode(),
            _ros2_type(conn["type"].decode()),
            conn.get("message_definition", b"").decode(),
            conn.get("md5sum", b"").decode(),
            (latched_qos(),) if latching else (),
            ros1=True,
        )
    if op == 0x02:
        (cid,) = _U32.unpack(fields["conn"])
        sec, nsec = struct.unpack("<II", fields["time"])
        return RecoveredMessage(cid, sec * 1_000_000_000 + nsec, bytes(data))
    return None


def _ros1_chunk(
    fields: dict[str, bytes], data: bytes, seen: set[int]
) -> list[RecoveredChannel | RecoveredMessage]:
    kind = fields.get("compression", b"none").decode()
    (usize,) = _U32.unpack(fields["size"])
    if usize > _MAX_CHUNK:
        msg = f"the chunk says it holds {usize} bytes uncompressed (more than 1 GiB)"
        raise ValueError(msg)
    if kind == "none":
        raw = data
    elif kind == "lz4":
        raw = bytes(lz4.frame.decompress(data))
    elif kind == "bz2":
        raw = bz2.decompress(data)
    else:
        msg = f"unknown chunk compression {kind!r}"
        raise ValueError(msg)
    if len(raw) != usize:
        msg = f"the chunk holds {len(raw)} bytes, its header says {usize}"
        raise ValueError(msg)
    out: list[RecoveredChannel | RecoveredMessage] = []
    view = memoryview(raw)
    pos = 0
    while pos + 4 <= len(view):
        (hlen,) = _U32.unpack_from(view, pos)
        if pos + 8 + hlen > len(view):
            msg = "a record runs past the end of its chunk"
            raise ValueError(msg)
        (dlen,) = _U32.unpack_from(view, pos + 4 + hlen)
        start = pos + 8 + hlen
        if start + dlen > len(view):
            msg = "a record runs past the end of its chunk"
            raise ValueError(msg)
        item = _ros1_item(_fields(view[pos + 4 : pos + 4 + hlen]), view[start : start + dlen], seen)
        if item is not None:
            out.append(item)
        pos = start + dlen
    return out


def scan_ros1(
    path: Path, report: ScanReport | None = None
) -> Iterator[RecoveredChannel | RecoveredMessage]:
    """Yield the connections and messages of a ROS 1 bag, stopping at a cut-short record.

    Args:
        path: the ``.bag`` file (indexed or not).
        report: collect damage here instead of raising (damaged chunks are skipped).

    Yields:
        :class:`RecoveredChannel` before its messages, then messages in file order.

    Raises:
        CorruptBagError: not a ROS 1 bag, or (without ``report``) a complete record that
            does not decode.
    """
    f, size = _open(path, ROS1_MAGIC, "ROS 1 bag")
    with f:
        seen: set[int] = set()
        pos = len(ROS1_MAGIC)
        while pos + 4 <= size:
            (hlen,) = _U32.unpack(f.read(4))
            if pos + 8 + hlen > size:
                return  # cut short
            header = f.read(hlen)
            (dlen,) = _U32.unpack(f.read(4))
            if pos + 8 + hlen + dlen > size:
                return  # cut short
            where = pos
            pos += 8 + hlen + dlen
            op = -1
            try:
                fields = _fields(header)
                op = fields.get("op", b"\x00")[0]
                if op not in (0x02, 0x05, 0x07):  # bag header, index data, chunk info
                    f.seek(pos)
                    continue
                data = f.read(dlen)
                if op == 0x05:  # a damaged chunk must not mark its connections as seen
                    fresh = set(seen)
                    items = _ros1_chunk(fields, data, fresh)
                    seen |= fresh
                else:  # an unchunked bag, or the connections of the index
                    item = _ros1_item(fields, data, seen)
                    items = [] if item is None else [item]
            except _DAMAGE as exc:
                _tolerate(report, path, where, exc, chunk=op == 0x05)
                if op != 0x05:
                    return
                f.seek(pos)
                continue
            yield from items
