"""Read any bag: rosbag2 (MCAP, SQLite 3), ROS 1, and recordings that were never closed.

Complete bags are read with ``rosbags.highlevel.AnyReader`` (what ROS itself writes: ROS 1
bags, rosbag2 with ``sqlite3`` or ``mcap`` storage, Humble's definition-less SQLite bags via
visnav's type store). A storage file that was not closed (a killed recorder: no MCAP footer,
no ROS 1 index), or whose index or summary does not decode, is read record by record up to
its last complete chunk (:mod:`visnav.bag.recovery`), in file order, skipping chunks whose
bytes are damaged; a warning on the ``visnav.bag`` logger names the file, the reason and the
number of messages recovered (``BagReader.recovery`` holds the reason).

Messages whose type has the same wire format as visnav's come out as visnav message
objects (ROS 1 ones converted, ``Header.seq`` dropped); other types come out as ``rosbags``
objects built from the bag's own definitions (``TopicMeta.native`` is False).

Example::

    for topic, type_name, t_ns, msg in read_bag("run/bag", topics=["/odom"]):
        ...
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import logging
import sqlite3
import struct
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, NamedTuple

import apsw
import zstandard
from backports import zstd as backports_zstd
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import Connection, ConnectionExtRosbag1, ConnectionExtRosbag2, Qos
from rosbags.rosbag1 import ReaderError as Ros1ReaderError
from rosbags.rosbag2 import ReaderError as Ros2ReaderError
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from visnav.bag.errors import BagError, CorruptBagError, TopicNotInBagError
from visnav.bag.qos import latched_qos
from visnav.bag.recovery import (
    RecoveredChannel,
    RecoveredMessage,
    ScanReport,
    scan_mcap,
    scan_ros1,
)
from visnav.bag.storage import BagLayout, detect_layout
from visnav.bag.typeconv import same_wire_format
from visnav.msgs.serde import deserialize, typestore

__all__ = ["BagMessage", "BagReader", "RawMessage", "TopicMeta", "read_bag"]

_log = logging.getLogger("visnav.bag")

_READ_ERRORS = (
    AnyReaderError,
    Ros1ReaderError,
    Ros2ReaderError,
    SerdeError,
    KeyError,
    ValueError,
    IndexError,
    EOFError,
    OSError,
    AssertionError,
    RuntimeError,  # lz4
    OverflowError,  # damaged lengths and offsets
    MemoryError,
    struct.error,
    apsw.Error,  # rosbags' SQLite 3 storage
    sqlite3.Error,
    zstandard.ZstdError,
    backports_zstd.ZstdError,
)


class BagMessage(NamedTuple):
    """One message of a bag: ``(topic, type_name, t_ns, msg)``."""

    topic: str
    type_name: str
    t_ns: int
    msg: Any


class RawMessage(NamedTuple):
    """One serialized message: CDR, or ROS 1 bytes when the bag is a ROS 1 bag."""

    topic: str
    type_name: str
    t_ns: int
    data: bytes | memoryview


@dataclasses.dataclass(frozen=True)
class TopicMeta:
    """A topic as the bag describes it.

    Attributes:
        name: topic name.
        type_name: ROS 2 type name.
        count: number of messages (of the recovered part, for an unclosed file).
        qos: the offered QoS profiles recorded (ROS 1 latched -> transient local).
        definition: the stored message definition ('' when the bag has none).
        digest: the stored type hash (RIHS01 or ROS 1 MD5; may be '').
        serialization: ``"cdr"`` or ``"ros1"``.
        native: True when messages decode to visnav's own message classes.
    """

    name: str
    type_name: str
    count: int
    qos: tuple[Qos, ...]
    definition: str
    digest: str
    serialization: str
    native: bool


def _why(exc: BaseException) -> str:
    """The root cause's text (or its type name when it has none)."""
    while exc.__cause__ is not None:
        exc = exc.__cause__
    text = str(exc)
    if len(exc.args) == 1 and isinstance(exc.args[0], tuple):  # rosbags: ('Could not ...',)
        text = ", ".join(map(str, exc.args[0]))
    return text or type(exc).__name__


def _suggest(name: str, names: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(names), n=3, cutoff=0.4)
    return f"; did you mean {', '.join(close)}?" if close else ""


def _types_of(definition: str, type_name: str, fmt: str) -> dict[str, Any]:
    if not definition:
        return {}
    if fmt == "ros2idl" or definition.startswith("=" * 80 + "\nIDL: "):
        out: dict[str, Any] = {}
        for part in definition.split("=" * 80 + "\n")[1:]:
            out.update(get_types_from_idl(part.split("\n", 1)[1]))
        return out
    return dict(get_types_from_msg(definition, type_name))


class _Topic:
    """Per-topic decoding state."""

    def __init__(self, meta: TopicMeta, bag_store: Typestore) -> None:
        self.meta = meta
        name = meta.type_name
        ros1 = meta.serialization == "ros1"
        native_store = typestore()
        self.decode: Callable[[bytes | memoryview], Any]
        self.to_cdr: Callable[[bytes | memoryview], bytes | memoryview] | None
        if meta.native:
            if ros1:
                self.decode = lambda raw: deserialize(native_store.ros1_to_cdr(raw, name), name)
                self.to_cdr = lambda raw: native_store.ros1_to_cdr(raw, name)
            else:
                self.decode = lambda raw: deserialize(raw, name)
                self.to_cdr = lambda raw: raw
        elif ros1:
            self.decode = lambda raw: bag_store.deserialize_ros1(raw, name)
            self.to_cdr = None
        else:
            self.decode = lambda raw: bag_store.deserialize_cdr(raw, name)
            self.to_cdr = lambda raw: raw


class BagReader:
    """Open a bag for reading (a context manager).

    Args:
        path: a rosbag2 directory, an ``.mcap``/``.db3`` file or a ROS 1 ``.bag`` file.
        recover: read files that were never closed, or whose index or summary does not
            decode, by scanning them up to their last complete chunk (default, with a
            warning); False raises :class:`CorruptBagError` for them instead.
        scan: read MCAP and ROS 1 files by scanning even when their index is intact (what
            ``bag reindex`` does: chunks that fail their CRC are skipped, not fatal).

    Attributes:
        recovery: why the bag was read by scanning ('' when it was read through its index).
        report: what the scan skipped (damaged chunks) or where it stopped.

    Raises:
        BagNotFoundError: nothing at ``path``.
        UnknownStorageError: not a bag visnav reads.
        CorruptBagError: the bag does not decode.
    """

    def __init__(self, path: str | Path, *, recover: bool = True, scan: bool = False) -> None:
        self.layout: BagLayout = detect_layout(path)
        self.path = self.layout.path
        self._any: AnyReader | None = None
        self._conns: dict[str, list[Connection]] = {}
        self._recovered: list[RecoveredChannel] = []
        self._store = get_typestore(Stores.EMPTY)
        self.start_ns = 0
        self.end_ns = 0
        self.message_count = 0
        self.recovery = ""
        self.report = ScanReport()
        self._recover = recover and self.layout.storage in ("mcap", "ros1")
        if not self.layout.complete and not recover:
            msg = (
                f"bag '{self.path}' was not closed (recording killed?): "
                f"{', '.join(map(str, self.layout.incomplete))}; run 'visnav bag reindex'"
            )
            raise CorruptBagError(msg)
        if not self.layout.complete:
            names = ", ".join(str(f) for f in self.layout.incomplete)
            metas = self._recover_from(f"not closed (recording killed?): {names}")
        elif scan and self._recover:
            metas = self._recover_from("read by scanning (as asked)", warn=False)
        else:
            try:
                metas = self._open_any()
            except CorruptBagError as exc:
                if not self._recover:
                    raise
                metas = self._recover_from(f"its index does not decode ({_why(exc)})")
        self._topics = {m.name: _Topic(m, self._store) for m in metas}

    def _recover_from(self, reason: str, *, warn: bool = True) -> list[TopicMeta]:
        """Open by scanning; warn with the file, the reason and the count recovered."""
        self._close_any()
        self._conns = {}
        self._store = get_typestore(Stores.EMPTY)
        self.recovery = reason
        try:
            metas = self._open_recovered()
        except BagError:
            raise
        except _READ_ERRORS as exc:
            raise self._fail(exc) from exc
        extra = self.report.summary()
        if extra:
            self.recovery = f"{reason}; {extra}"
        if warn:
            _log.warning(
                "bag '%s': %s; recovered %d messages on %d topics by scanning the file; "
                "'visnav bag reindex %s' rewrites it",
                self.path,
                self.recovery,
                self.message_count,
                len(metas),
                self.path,
            )
        return metas

    # ------------------------------------------------------------------ opening
    def _fail(self, exc: BaseException) -> CorruptBagError:
        return CorruptBagError(f"cannot read bag '{self.path}': {_why(exc)}")

    def _open_any(self) -> list[TopicMeta]:
        lay = self.layout
        # rosbags takes any path ending in '.bag' for a ROS 1 file: give it the storage files of
        # a rosbag2 directory named like that (a recording made with '-o X.bag')
        named_bag = lay.path.is_dir() and lay.path.suffix == ".bag"
        by_dir = lay.metadata is not None and not named_bag
        paths = [lay.path] if by_dir or not lay.path.is_dir() else list(lay.files)
        try:
            reader = AnyReader(paths, default_typestore=typestore())
            reader.open()
        except _READ_ERRORS as exc:
            raise self._fail(exc) from exc
        self._any = reader
        self._store = reader.typestore
        if reader.message_count:
            self.start_ns, self.end_ns = reader.start_time, reader.end_time - 1
        self.message_count = reader.message_count
        metas: list[TopicMeta] = []
        by_topic: dict[str, list[Connection]] = {}
        for c in reader.connections:
            by_topic.setdefault(c.topic, []).append(c)
        for topic, conns in by_topic.items():
            first = conns[0]
            ros1 = isinstance(first.ext, ConnectionExtRosbag1)
            qos: list[Qos] = []
            for c in conns:
                if isinstance(c.ext, ConnectionExtRosbag2):
                    qos.extend(c.ext.offered_qos_profiles)
                elif c.ext.latching:
                    qos.append(latched_qos())
            metas.append(
                self._meta(
                    topic,
                    first.msgtype,
                    sum(c.msgcount for c in conns),
                    tuple(qos),
                    first.msgdef.data,
                    first.digest,
                    ros1,
                )
            )
            self._conns[topic] = conns
        return metas

    def _meta(
        self,
        topic: str,
        type_name: str,
        count: int,
        qos: tuple[Qos, ...],
        definition: str,
        digest: str,
        ros1: bool,
    ) -> TopicMeta:
        native = type_name in typestore().fielddefs and (
            type_name not in self._store.fielddefs
            or same_wire_format(self._store, typestore(), type_name, ros1_header=ros1)
        )
        return TopicMeta(
            topic, type_name, count, qos, definition, digest, "ros1" if ros1 else "cdr", native
        )

    def _scan(
        self, report: ScanReport
    ) -> Iterator[tuple[Path, RecoveredChannel | RecoveredMessage]]:
        scan = scan_ros1 if self.layout.is_ros1 else scan_mcap
        if self.layout.storage == "sqlite3":  # pragma: no cover - detect_layout never flags it
            msg = f"bag '{self.path}' is incomplete SQLite storage; it cannot be recovered"
            raise CorruptBagError(msg)
        for f in self.layout.files:
            for item in scan(f, report):
                yield f, item

    def _open_recovered(self) -> list[TopicMeta]:
        channels: dict[tuple[Path, int], RecoveredChannel] = {}
        counts: dict[str, int] = {}
        start, end, total = 2**63 - 1, 0, 0
        self.report = ScanReport()
        for f, item in self._scan(self.report):
            if isinstance(item, RecoveredChannel):
                channels[(f, item.id)] = item
                counts.setdefault(item.topic, 0)
            else:
                ch = channels.get((f, item.channel))
                if ch is None:
                    continue
                counts[ch.topic] += 1
                start, end, total = min(start, item.t_ns), max(end, item.t_ns), total + 1
        self._recovered = list(channels.values())
        types: dict[str, Any] = {}
        for ch in self._recovered:
            try:
                types.update(_types_of(ch.definition, ch.type_name, "msg"))
            except Exception as exc:
                msg = f"bag '{self.path}': the definition of {ch.type_name} does not parse: {exc}"
                raise CorruptBagError(msg) from exc
        if types:
            self._store.register(types)
        if total:
            self.start_ns, self.end_ns = start, end
        self.message_count = total
        metas: dict[str, TopicMeta] = {}
        for ch in self._recovered:
            if ch.topic not in metas:
                metas[ch.topic] = self._meta(
                    ch.topic,
                    ch.type_name,
                    counts[ch.topic],
                    ch.qos,
                    ch.definition,
                    ch.digest,
                    ch.ros1,
                )
        return list(metas.values())

    # ------------------------------------------------------------------ queries
    @property
    def complete(self) -> bool:
        """False when the bag was read by scanning (unclosed, or its index does not decode)."""
        return self.layout.complete and not self.recovery

    @property
    def topics(self) -> dict[str, TopicMeta]:
        """The bag's topics by name."""
        return {name: t.meta for name, t in self._topics.items()}

    @property
    def is_ros1(self) -> bool:
        """True for a ROS 1 bag."""
        return self.layout.is_ros1

    @property
    def typestore(self) -> Typestore:
        """The type store built from the bag's definitions."""
        return self._store

    def check_topics(self, topics: Iterable[str] | None) -> list[str]:
        """Return the topics asked for, or all topics for None.

        Raises:
            TopicNotInBagError: a topic is not in the bag (closest names suggested).
        """
        if topics is None:
            return list(self._topics)
        wanted = list(topics)
        for name in wanted:
            if name not in self._topics:
                msg = (
                    f"topic '{name}' is not in bag '{self.path}'"
                    f"{_suggest(name, self._topics)} (the bag has: "
                    f"{', '.join(sorted(self._topics)) or 'no topics'})"
                )
                raise TopicNotInBagError(msg)
        return wanted

    # ------------------------------------------------------------------ messages
    def raw_messages(
        self,
        topics: Iterable[str] | None = None,
        *,
        start_ns: int | None = None,
        stop_ns: int | None = None,
    ) -> Iterator[RawMessage]:
        """Yield serialized messages in time order (file order for a recovered file).

        Args:
            topics: topic names (default all); unknown names raise.
            start_ns: only messages at or after this time.
            stop_ns: only messages before this time.

        Raises:
            TopicNotInBagError: a topic is not in the bag.
            CorruptBagError: the bag's bytes do not decode.
        """
        wanted = set(self.check_topics(topics))
        if not wanted:
            return
        yielded = False
        try:
            if self._any is not None:
                conns = [c for t in wanted for c in self._conns[t]]
                for conn, t, raw in self._any.messages(conns, start=start_ns, stop=stop_ns):
                    yielded = True
                    yield RawMessage(conn.topic, conn.msgtype, t, raw)
                return
            yield from self._raw_recovered(wanted, start_ns, stop_ns)
            return
        except BagError:
            raise
        except _READ_ERRORS as exc:
            if yielded or not self._recover or self._any is None:
                hint = "; 'visnav bag reindex' rewrites it without the damaged chunks"
                failure = self._fail(exc)
                raise CorruptBagError(f"{failure}{hint if self._recover else ''}") from exc
            why = _why(exc)
        # the index opened but the first chunk it points at does not decode: scan instead
        metas = self._recover_from(f"its index points at data that does not decode ({why})")
        self._topics = {m.name: _Topic(m, self._store) for m in metas}
        yield from self._raw_recovered(wanted & set(self._topics), start_ns, stop_ns)

    def _raw_recovered(
        self, wanted: set[str], start_ns: int | None, stop_ns: int | None
    ) -> Iterator[RawMessage]:
        channels: dict[tuple[Path, int], RecoveredChannel] = {}
        lo = -(2**63) if start_ns is None else start_ns
        hi = 2**64 if stop_ns is None else stop_ns
        for f, item in self._scan(ScanReport()):
            if isinstance(item, RecoveredChannel):
                channels[(f, item.id)] = item
                continue
            ch = channels.get((f, item.channel))
            if ch is not None and ch.topic in wanted and lo <= item.t_ns < hi:
                yield RawMessage(ch.topic, ch.type_name, item.t_ns, item.data)

    def messages(
        self,
        topics: Iterable[str] | None = None,
        *,
        start_ns: int | None = None,
        stop_ns: int | None = None,
    ) -> Iterator[BagMessage]:
        """Yield deserialized messages in time order; arguments as :meth:`raw_messages`."""
        for raw in self.raw_messages(topics, start_ns=start_ns, stop_ns=stop_ns):
            yield BagMessage(raw.topic, raw.type_name, raw.t_ns, self.decode(raw))

    def decode(self, raw: RawMessage) -> Any:
        """Deserialize one raw message (visnav class when the topic is native).

        Raises:
            CorruptBagError: the bytes do not decode as the topic's type.
        """
        try:
            return self._topics[raw.topic].decode(raw.data)
        except (ValueError, SerdeError, IndexError, KeyError, TypeError, AssertionError) as exc:
            msg = (
                f"bag '{self.path}': a message on '{raw.topic}' at t={raw.t_ns} does not decode "
                f"as {raw.type_name}: {exc}"
            )
            raise CorruptBagError(msg) from exc

    def to_cdr(self, raw: RawMessage) -> bytes | memoryview | None:
        """Return the CDR of a raw message, or None for a ROS 1 type visnav does not know.

        Raises:
            CorruptBagError: ROS 1 bytes that do not decode as the topic's type.
        """
        conv = self._topics[raw.topic].to_cdr
        if conv is None:
            return None
        try:
            return conv(raw.data)
        except (ValueError, SerdeError, IndexError, KeyError, TypeError, struct.error) as exc:
            msg = (
                f"bag '{self.path}': a message on '{raw.topic}' at t={raw.t_ns} ns "
                f"({len(raw.data)} bytes) is not valid ROS 1 {raw.type_name} "
                f"({type(exc).__name__}: {exc}), so it cannot be converted to CDR; leave the "
                "topic out (--topics) or keep the ROS 1 format"
            )
            raise CorruptBagError(msg) from exc

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        """Close the files (idempotent)."""
        self._close_any()

    def _close_any(self) -> None:
        if self._any is not None:
            reader, self._any = self._any, None
            with contextlib.suppress(*_READ_ERRORS):  # a reader that failed half-way
                reader.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def read_bag(
    path: str | Path,
    topics: Sequence[str] | None = None,
    *,
    start_ns: int | None = None,
    stop_ns: int | None = None,
) -> Iterator[BagMessage]:
    """Yield ``(topic, type_name, t_ns, msg)`` of a bag in time order.

    Args:
        path: the bag (any format visnav reads).
        topics: topic names (default all).
        start_ns: only messages at or after this time.
        stop_ns: only messages before this time.

    Raises:
        BagNotFoundError, UnknownStorageError, CorruptBagError, TopicNotInBagError.
    """
    with BagReader(path) as reader:
        yield from reader.messages(topics, start_ns=start_ns, stop_ns=stop_ns)
