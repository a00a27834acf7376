"""visnav's own bag metadata: the recorder's per-topic drop counts.

``bag record`` stores how many messages each topic lost (its subscription queue overflowed)
so that ``bag info`` can show them long after the recording:

* MCAP: a Metadata record named ``visnav_recorder`` (``{"drops": "<json object>"}``), which
  every MCAP reader lists and ignores otherwise;
* ROS 1: a ``visnav_drops=<json object>`` field in the bag header record. The header is
  padded to a fixed size (4 KiB in what ``rosbag`` and ``rosbags`` write), so the field
  replaces padding and no offset in the file changes; ``rosbag`` reads the header fields it
  knows by name and ignores this one.

Reading is tolerant: a damaged or missing record gives no drops (an empty dict).
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

from visnav.bag.storage import MCAP_MAGIC, ROS1_MAGIC, BagLayout

__all__ = [
    "MCAP_METADATA_NAME",
    "ROS1_DROPS_FIELD",
    "drops_json",
    "read_drops",
    "write_ros1_drops",
]

MCAP_METADATA_NAME = "visnav_recorder"
ROS1_DROPS_FIELD = b"visnav_drops"
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")


def drops_json(drops: dict[str, int]) -> str:
    """The compact JSON text stored for ``drops`` (topics sorted)."""
    return json.dumps({t: int(n) for t, n in sorted(drops.items())}, separators=(",", ":"))


def _parse(text: bytes | str) -> dict[str, int]:
    try:
        value = json.loads(text)
    except (ValueError, UnicodeDecodeError):
        return {}
    if not isinstance(value, dict):
        return {}
    return {str(k): v for k, v in value.items() if isinstance(v, int) and v > 0}


def _ros1_header(path: Path) -> tuple[int, bytes, int] | None:
    """``(record length, header bytes, data length)`` of a ROS 1 bag's header record."""
    with path.open("rb") as f:
        f.seek(len(ROS1_MAGIC))
        raw = f.read(4)
        if len(raw) < 4:
            return None
        (hlen,) = _U32.unpack(raw)
        header = f.read(hlen)
        raw = f.read(4)
        if len(header) < hlen or len(raw) < 4 or hlen > 1 << 16:
            return None
        (dlen,) = _U32.unpack(raw)
    return 8 + hlen + dlen, header, dlen


def _fields(header: bytes) -> list[tuple[bytes, bytes]]:
    out: list[tuple[bytes, bytes]] = []
    pos = 0
    while pos + 4 <= len(header):
        (n,) = _U32.unpack_from(header, pos)
        field = header[pos + 4 : pos + 4 + n]
        pos += 4 + n
        key, _, value = field.partition(b"=")
        out.append((key, value))
    return out


def write_ros1_drops(path: Path, drops: dict[str, int]) -> bool:
    """Put the drop counts into a closed ROS 1 bag's header record (in place, same size).

    Args:
        path: the ``.bag`` file (closed).
        drops: messages lost per topic.

    Returns:
        False when the field does not fit into the header's padding (the bag is unchanged).
    """
    found = _ros1_header(path)
    if found is None:
        return False
    total, header, _ = found
    fields = [(k, v) for k, v in _fields(header) if k != ROS1_DROPS_FIELD]
    fields.append((ROS1_DROPS_FIELD, drops_json(drops).encode()))
    new = b"".join(_U32.pack(len(k) + 1 + len(v)) + k + b"=" + v for k, v in fields)
    pad = total - 8 - len(new)
    if pad < 0:
        return False
    with path.open("r+b") as f:
        f.seek(len(ROS1_MAGIC))
        f.write(_U32.pack(len(new)) + new + _U32.pack(pad) + b" " * pad)
    return True


def _ros1_drops(path: Path) -> dict[str, int]:
    found = _ros1_header(path)
    if found is None:
        return {}
    for key, value in _fields(found[1]):
        if key == ROS1_DROPS_FIELD:
            return _parse(value)
    return {}


def _string(body: bytes, pos: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(body, pos)
    end = pos + 4 + n
    if end > len(body):
        msg = "a string runs past its record"
        raise ValueError(msg)
    return body[pos + 4 : end].decode("utf-8"), end


def _mcap_drops(path: Path) -> dict[str, int]:
    """Walk the top-level records of the data section for the recorder's Metadata record."""
    size = path.stat().st_size
    with path.open("rb") as f:
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            return {}
        pos = len(MCAP_MAGIC)
        while pos + 9 <= size:
            head = f.read(9)
            op, (length,) = head[0], _U64.unpack_from(head, 1)
            if op == 0x0F or pos + 9 + length > size:
                return {}
            pos += 9 + length
            if op != 0x0C or length > 1 << 20:
                f.seek(pos)
                continue
            body = f.read(length)
            name, at = _string(body, 0)
            if name != MCAP_METADATA_NAME:
                continue
            at += 4  # byte length of the map
            while at < len(body):
                key, at = _string(body, at)
                value, at = _string(body, at)
                if key == "drops":
                    return _parse(value)
    return {}


def read_drops(layout: BagLayout) -> dict[str, int]:
    """The recorder's drop counts stored in a bag (empty when it has none or they are damaged).

    Args:
        layout: the bag (see :func:`~visnav.bag.storage.detect_layout`).

    Returns:
        Messages lost per topic (only topics that lost some).
    """
    out: dict[str, int] = {}
    for f in layout.files:
        try:
            if layout.storage == "ros1":
                found = _ros1_drops(f)
            elif layout.storage == "mcap":
                found = _mcap_drops(f)
            else:
                found = {}
        except (OSError, ValueError, struct.error, IndexError):
            found = {}
        for topic, n in found.items():
            out[topic] = out.get(topic, 0) + n
    return out
