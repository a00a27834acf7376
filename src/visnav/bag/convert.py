"""``bag convert`` and ``bag reindex``: rewrite a bag in another format, or repair one.

Conversion copies serialized messages: rosbag2 -> rosbag2 and ROS 1 -> ROS 1 keep every
topic with the bag's own definitions; between ROS 1 and ROS 2 the bytes are converted
(``std_msgs/Header.seq`` added or dropped) for the types visnav knows, and topics of other
types are left out with a warning (``ConvertResult.skipped``). Record times and offered QoS
(ROS 1 latching) are kept.

The output is written under a hidden temporary name next to it and renamed into place only
when it is complete, so a failed or killed conversion never leaves a bag that looks whole.
"""

from __future__ import annotations

import dataclasses
import logging
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

from visnav.bag.errors import BagError, BagExistsError
from visnav.bag.info import stored_compression
from visnav.bag.reader import BagReader, TopicMeta
from visnav.bag.storage import COMPRESSIONS, check_format, detect_layout
from visnav.bag.writer import BagWriter, default_bag_path

__all__ = ["ConvertResult", "convert_bag", "reindex_bag"]

_log = logging.getLogger("visnav.bag")


@dataclasses.dataclass(frozen=True)
class ConvertResult:
    """What a conversion wrote.

    Attributes:
        path: the output bag.
        message_count: messages written.
        topics: topics written.
        skipped: topics left out, with the reason.
        recovery: what reading the input by scanning left out (damaged chunks) or why it
            scanned ('' when the input was read through its intact index).
    """

    path: Path
    message_count: int
    topics: tuple[str, ...]
    skipped: dict[str, str]
    recovery: str = ""


def _plan(meta: TopicMeta, out_ros1: bool) -> tuple[str, str | None] | str:
    """Return ``(serialization, definition or None for visnav's)``, or a reason to skip."""
    out_ser = "ros1" if out_ros1 else "cdr"
    if (meta.serialization == "ros1") == out_ros1:  # same family: copy the bytes
        if meta.definition:
            return (out_ser, meta.definition)
        if meta.native:
            return (out_ser, None)
        return f"the bag holds no definition of {meta.type_name}"
    if meta.native:
        return ("cdr", None)  # CDR in; the writer converts to ROS 1 when needed
    return (
        f"type {meta.type_name} is not one of visnav's, so it cannot be converted between "
        "ROS 1 and ROS 2 serialization"
    )


def _digest(reader: BagReader, meta: TopicMeta, out_ros1: bool) -> str:
    if meta.digest:
        return meta.digest
    try:
        if out_ros1:
            return reader.typestore.generate_msgdef(meta.type_name, ros_version=1)[1]
        return reader.typestore.hash_rihs01(meta.type_name)
    except Exception:  # noqa: BLE001 - rosbags raises several errors for odd types
        return ""


def convert_bag(
    src: str | Path,
    dst: str | Path,
    *,
    fmt: str = "mcap",
    compression: str = "none",
    topics: Sequence[str] | None = None,
    scan: bool = False,
) -> ConvertResult:
    """Write the messages of ``src`` into a new bag ``dst``.

    Args:
        src: the input bag (any format visnav reads; unclosed or damaged files are
            recovered with a warning).
        dst: the output (directory for rosbag2, ``.bag`` file for ROS 1). It appears only
            once complete: the bag is written under a hidden temporary name beside it.
        fmt: output format, ``"mcap"``, ``"ros1"`` or ``"sqlite3"``.
        compression: output compression (see :class:`~visnav.bag.writer.BagWriter`).
        topics: only these topics (default all).
        scan: read the input by scanning its storage files (skipping damaged chunks)
            instead of through its index (see :class:`~visnav.bag.reader.BagReader`).

    Returns:
        What was written.

    Raises:
        BagError: unreadable input or message, existing output, unknown format or topic.
    """
    fmt, compression = check_format(fmt, compression)
    final = default_bag_path(dst, fmt)
    if final.exists():
        msg = f"bag output '{final}' exists already: choose another name or remove it"
        raise BagExistsError(msg)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp_dir = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".partial", dir=final.parent))
    try:
        result = _convert(src, tmp_dir / final.name, fmt, compression, topics, scan=scan)
        if final.exists():
            msg = f"bag output '{final}' appeared while converting: choose another name"
            raise BagExistsError(msg)
        result.path.rename(final)
    finally:
        shutil.rmtree(tmp_dir, ignore_errors=True)
    return dataclasses.replace(result, path=final)


def _convert(
    src: str | Path,
    dst: Path,
    fmt: str,
    compression: str,
    topics: Sequence[str] | None,
    *,
    scan: bool,
) -> ConvertResult:
    out_ros1 = fmt == "ros1"
    with BagReader(src, scan=scan) as reader:
        names = reader.check_topics(topics)
        skipped: dict[str, str] = {}
        plans: dict[str, tuple[str, str | None]] = {}
        for name in names:
            plan = _plan(reader.topics[name], out_ros1)
            if isinstance(plan, str):
                skipped[name] = plan
                _log.warning("not converting '%s': %s", name, plan)
            else:
                plans[name] = plan
        with BagWriter(dst, fmt=fmt, compression=compression) as writer:
            handles: dict[str, int] = {}
            for name, (ser, definition) in plans.items():
                meta = reader.topics[name]
                digest = None if definition is None else _digest(reader, meta, out_ros1)
                handles[name] = writer.add_topic(
                    name,
                    meta.type_name,
                    qos=meta.qos,
                    definition=definition,
                    digest=digest,
                    serialization=ser,
                )
            count = 0
            for raw in reader.raw_messages(list(plans)):
                ser = plans[raw.topic][0]
                data = raw.data if (ser == "ros1") == reader.is_ros1 else reader.to_cdr(raw)
                if data is None:  # pragma: no cover - excluded by _plan
                    continue
                try:
                    writer.write(handles[raw.topic], raw.t_ns, data)
                except BagError as exc:
                    msg = f"converting '{reader.path}': {exc}"
                    raise type(exc)(msg) from exc
                count += 1
            path = writer.path
        recovery = reader.report.summary() if scan else reader.recovery
    return ConvertResult(path, count, tuple(plans), skipped, recovery)


def _backup_name(path: Path) -> Path:
    if path.is_dir():
        return path.with_name(path.name + ".orig")
    return path.with_name(f"{path.stem}.orig{path.suffix}")


def _remove(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()


def reindex_bag(path: str | Path) -> ConvertResult:
    """Repair a bag whose recording was killed: rewrite it complete, in place.

    Like ``ros2 bag reindex`` / ``rosbag reindex``, but the storage file itself is rewritten
    (same format and compression) from what its complete chunks hold, so every reader opens
    it afterwards. MCAP and ROS 1 files are read by scanning, not through their index, so a
    damaged index or summary is rebuilt and chunks that fail their CRC (or do not decode) are
    left out (``ConvertResult.recovery`` says which). The original is renamed
    ``<name>.orig`` during the rewrite and removed after it succeeded (restored if it
    failed). A rosbag2 directory gets a correct ``metadata.yaml``.

    Args:
        path: the bag.

    Returns:
        What was written.

    Raises:
        BagError: the bag does not read, or the backup name exists.
    """
    layout = detect_layout(path)
    src = layout.path
    fmt = layout.storage
    compression = stored_compression(layout).split(" ")[0]
    if compression not in ("none", "zstd", "lz4", "bz2") or compression not in COMPRESSIONS[fmt]:
        compression = "none"
    backup = _backup_name(src)
    if backup.exists():
        msg = f"cannot reindex '{src}': '{backup}' exists; move it away first"
        raise BagExistsError(msg)
    bare_mcap = src.is_file() and fmt == "mcap"
    out = src.with_name(src.name + ".reindex") if bare_mcap else src
    src.rename(backup)
    try:
        result = convert_bag(backup, out, fmt=fmt, compression=compression, scan=fmt != "sqlite3")
        if bare_mcap:
            (out / f"{out.name}_0.mcap").rename(src)
            shutil.rmtree(out)
            result = dataclasses.replace(result, path=src)
    except BaseException:
        _remove(out)
        _remove(src)
        backup.rename(src)
        raise
    _remove(backup)
    return dataclasses.replace(result, recovery=result.recovery.replace(str(backup), str(src)))
