"""CDR -> ROS 1 for byte-tail types (images, compressed images, grids) without deserializing.

A type whose last field is a ``uint8[]``/``int8[]`` sequence (:attr:`Ros1Type.byte_tail`) has
the same tail bytes on both wires. :func:`split_cdr_to_ros1` walks the CDR bytes of the fields
before the tail once, writing their ROS 1 form (a ``std_msgs/Header`` gains its ``seq``, a
string loses its terminator and its alignment padding goes), and returns the tail as a view on
the CDR bytes: nothing of the tail is copied, no message object is made.

The result equals :func:`visnav.bridge.typemap.cdr_to_ros1` of the same bytes (the full
conversion, tested byte for byte with hypothesis), and bytes that the full path refuses
(a string that is not UTF-8 or lacks its terminator, a length past the end, trailing bytes)
are refused here too, with :class:`~visnav.bridge.errors.TcprosError`. One difference, for
bytes that rosbags never writes: a signalling-NaN ``float32`` before the tail
(``OccupancyGrid.info.resolution``) keeps its bits here, as ros1_bridge's C++ copy keeps them;
the full path, through a Python float, sets its quiet bit.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from rosbags.interfaces import Nodetype

from visnav.bag.typeconv import HEADER
from visnav.bridge.errors import TcprosError
from visnav.bridge.typemap import Ros1Type
from visnav.msgs.serde import typestore

__all__ = ["HeadPlan", "head_plan", "split_cdr_to_ros1"]

_U32 = struct.Struct("<I")
_SIZES = {  # no bool: the full path turns any non-zero byte into 1
    "byte": 1,
    "char": 1,
    "int8": 1,
    "uint8": 1,
    "int16": 2,
    "uint16": 2,
    "int32": 4,
    "uint32": 4,
    "int64": 8,
    "uint64": 8,
    "float32": 4,
    "float64": 8,
}

# One step of the walk over the CDR fields before the tail:
#   ("prim", size)      one fixed-size value, aligned to its size in CDR, copied as it is
#   ("str",)            a string (CDR: aligned length with the terminator; ROS 1: without)
#   ("seqmsg", steps)   a sequence of messages (aligned count, then each message's steps)
#   ("seq0",)           a std_msgs/Header's seq: 4 zero bytes in ROS 1, none in CDR
Step = tuple[object, ...]


@dataclass(frozen=True)
class HeadPlan:
    """How to rewrite the fields before a type's byte tail (made once per type).

    Attributes:
        type_name: the ROS 2 type name.
        steps: the walk (see the module's step kinds).
    """

    type_name: str
    steps: tuple[Step, ...]


@functools.cache
def head_plan(rtype: Ros1Type) -> HeadPlan | None:
    """The walk for ``rtype``'s fields before its byte tail, or None when it has no tail.

    Also None for a head with a field kind the walk does not handle (arrays, sequences of
    values, wstring; none of the byte-tail types has one): such a type keeps the full
    conversion.
    """
    if rtype.byte_tail is None:
        return None
    fields = typestore().fielddefs[rtype.ros2_name][1][:-1]
    steps = _steps(fields)
    return None if steps is None else HeadPlan(rtype.ros2_name, tuple(steps))


def _steps(fields: Sequence[tuple[str, Any]]) -> list[Step] | None:
    steps: list[Step] = []
    for _name, (kind, desc) in fields:
        sub: list[Step] | None
        if kind == Nodetype.NAME:
            sub = _message_steps(str(desc))
        elif kind == Nodetype.BASE:
            name = desc[0]
            sub = (
                [("str",)]
                if name == "string"
                else [("prim", _SIZES[name])]
                if name in _SIZES
                else None
            )
        elif kind == Nodetype.SEQUENCE and desc[0][0] == Nodetype.NAME:
            msg_steps = _message_steps(str(desc[0][1]))
            sub = None if msg_steps is None else [("seqmsg", tuple(msg_steps))]
        else:  # arrays and sequences of values: no byte-tail type has them before its tail
            sub = None
        if sub is None:
            return None
        steps += sub
    return steps


def _message_steps(name: str) -> list[Step] | None:
    sub = _steps(typestore().fielddefs[name][1])
    if sub is None:
        return None
    return [("seq0",), *sub] if name == HEADER else sub


def split_cdr_to_ros1(data: bytes | memoryview, plan: HeadPlan) -> tuple[bytearray, memoryview]:
    """ROS 1 bytes of a byte-tail message as ``(head, tail)``; ``head + tail`` is the message.

    Args:
        data: the CDR bytes (with the 4-byte encapsulation header), little endian.
        plan: :func:`head_plan` of the type.

    Returns:
        The ROS 1 bytes of every field before the tail plus the tail's length (a new
        buffer, ``seq`` 0), and the tail's bytes as a view on ``data`` (not copied).

    Raises:
        TcprosError: the bytes do not decode as the type (names it and the offset).
    """
    view = memoryview(data).cast("B")
    if len(view) < 4 or view[0] != 0 or view[1] != 1:
        msg = (
            f"CDR bytes of {plan.type_name} do not start with the little-endian "
            f"encapsulation 00 01 (got {bytes(view[:4]).hex(' ') or 'nothing'})"
        )
        raise TcprosError(msg)
    raw = view[4:]
    out = bytearray()
    try:
        pos = _walk(raw, 0, plan.steps, out)
        pos = (pos + 3) & -4
        (size,) = _U32.unpack_from(raw, pos)
        pos += 4
        end = pos + size
        if end > len(raw):
            msg = f"byte tail of {size} bytes at offset {pos} runs past the end ({len(raw)})"
            raise TcprosError(msg)
        if end + 3 < len(raw):
            msg = f"{len(raw) - end} bytes after the end of the message"
            raise TcprosError(msg)
    except (struct.error, UnicodeDecodeError, TcprosError) as exc:
        msg = f"CDR bytes do not decode as {plan.type_name}: {exc}"
        raise TcprosError(msg) from exc
    out += _U32.pack(size)
    return out, raw[pos:end]


def _walk(raw: memoryview, pos: int, steps: tuple[Step, ...], out: bytearray) -> int:
    """Write the ROS 1 form of ``steps`` read at ``pos``; return the position after them."""
    for step in steps:
        kind = step[0]
        if kind == "prim":
            size = int(step[1])  # type: ignore[call-overload]
            pos = (pos + size - 1) & -size
            end = pos + size
            if end > len(raw):
                msg = f"{size} bytes at offset {pos} run past the end ({len(raw)})"
                raise TcprosError(msg)
            out += raw[pos:end]
            pos = end
        elif kind == "str":
            pos = _string(raw, pos, out)
        elif kind == "seq0":
            out += b"\0\0\0\0"
        else:  # seqmsg
            pos = (pos + 3) & -4
            (count,) = _U32.unpack_from(raw, pos)
            pos += 4
            if count > len(raw) - pos:  # every element takes at least one byte
                msg = f"sequence of {count} at offset {pos} runs past the end ({len(raw)})"
                raise TcprosError(msg)
            out += _U32.pack(count)
            for _ in range(count):
                pos = _walk(raw, pos, step[1], out)  # type: ignore[arg-type]
    return pos


def _string(raw: memoryview, pos: int, out: bytearray) -> int:
    pos = (pos + 3) & -4
    length: int = _U32.unpack_from(raw, pos)[0]
    end = pos + 4 + length
    if length < 1 or end > len(raw):
        msg = f"invalid string length {length} at offset {pos}"
        raise TcprosError(msg)
    if raw[end - 1] != 0:
        msg = f"missing string terminator at offset {end - 1}"
        raise TcprosError(msg)
    text = raw[pos + 4 : end - 1]
    bytes(text).decode()  # the full path refuses text that is not UTF-8: so does this one
    out += _U32.pack(length - 1)
    out += text
    return end
