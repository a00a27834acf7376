"""Per-message metadata: who published it, when, and its sequence number.

Subscription callbacks that take two arguments receive it (rclpy's
``callback(msg, msg_info)`` form). Between processes it travels as a small
Zenoh attachment (``<q sequence><q source timestamp ns><I entity id><zid ascii>``).
"""

from __future__ import annotations

import dataclasses
import struct

__all__ = ["MessageInfo", "decode_attachment", "encode_attachment"]

_HEAD = struct.Struct("<qqI")


@dataclasses.dataclass(frozen=True)
class MessageInfo:
    """Where and when a message came from.

    Attributes:
        source_timestamp_ns: wall-clock time of publication (ns since the epoch).
        received_timestamp_ns: wall-clock time of arrival in this process.
        publication_sequence_number: the publisher's running count, from 1.
        publisher_zid: Zenoh id of the publishing context (``"0"`` for local-only).
        publisher_entity_id: the publisher's entity id in its context.
        from_this_process: True for in-process delivery.
    """

    source_timestamp_ns: int
    received_timestamp_ns: int
    publication_sequence_number: int
    publisher_zid: str
    publisher_entity_id: int
    from_this_process: bool


def encode_attachment(seq: int, source_ns: int, entity_id: int, zid: str) -> bytes:
    """Pack the metadata that travels with a remote sample."""
    return _HEAD.pack(seq, source_ns, entity_id) + zid.encode("ascii")


def decode_attachment(data: bytes | None, received_ns: int) -> MessageInfo | None:
    """Unpack :func:`encode_attachment`'s bytes (None if absent or foreign)."""
    if data is None or len(data) < _HEAD.size:
        return None
    seq, source_ns, entity_id = _HEAD.unpack_from(data)
    zid = data[_HEAD.size :].decode("ascii", errors="replace")
    return MessageInfo(source_ns, received_ns, seq, zid, entity_id, from_this_process=False)
