"""ROS 2 (visnav) <-> ROS 1 message types: names, definitions, MD5 sums and byte conversion.

visnav's messages are ROS 2 Humble's. A type crosses to ROS 1 when ROS 1 Noetic has a type of
the same name and the same wire format (the only allowed difference is ``std_msgs/Header``'s
``seq``, which the byte converters add and drop), or when it is one of the few types Noetic has
outside ``rosbags``' Noetic store with the same definition (``tf2_msgs/TFMessage``). Its ROS 1
definition and MD5 sum come from :func:`visnav.bag.typeconv.ros1_definition`, the ones visnav's
ROS 1 bags carry; they equal real ROS 1's (tested against ``genpy``).
"""

from __future__ import annotations

import functools
import struct
from dataclasses import dataclass
from typing import Any

from rosbags.interfaces import Nodetype
from rosbags.serde import SerdeError

from visnav.bag.typeconv import HEADER, noetic_store, ros1_definition, same_wire_format
from visnav.bridge.errors import TcprosError, UnconvertibleTypeError
from visnav.msgs.gazebo_msgs import GAZEBO_MSGS
from visnav.msgs.serde import typestore

__all__ = [
    "Ros1Type",
    "cdr_to_ros1",
    "ros1_name",
    "ros1_to_cdr",
    "ros1_type",
    "ros2_name",
    "rosout_type",
]

# Types ROS 1 Noetic has (same definition as Humble's with ROS 1's Header) that rosbags'
# Noetic store leaves out: tf2_msgs, and the gazebo_msgs visnav knows (their .msg files are
# the same in ROS 1 and ROS 2: visnav.msgs.gazebo_msgs).
_NOETIC_OUTSIDE_STORE = frozenset({"tf2_msgs/msg/TFMessage", "tf2_msgs/msg/TF2Error", *GAZEBO_MSGS})

_DECODE_ERRORS = (SerdeError, struct.error, IndexError, ValueError, KeyError, TypeError)


@dataclass(frozen=True)
class Ros1Type:
    """A message type as both graphs name it.

    Attributes:
        ros2_name: visnav's name, e.g. ``sensor_msgs/msg/Image``.
        ros1_name: ROS 1's name, e.g. ``sensor_msgs/Image``.
        md5sum: ROS 1's MD5 sum of the definition (TCPROS ``md5sum``).
        definition: ROS 1's full message definition (TCPROS ``message_definition``).
        header_first: the first field is a ``std_msgs/Header``, so the ROS 1 bytes start with
            its ``seq`` (which publishers number, as rospy does).
        byte_tail: the name of the last field when it is a ``uint8[]``/``int8[]`` sequence
            (``Image.data``, ``CompressedImage.data``, ``OccupancyGrid.data``): its bytes are
            the same on both wires, so the bridge sends them from the message as they are
            and converts only the fields before them.
    """

    ros2_name: str
    ros1_name: str
    md5sum: str
    definition: str
    header_first: bool = False
    byte_tail: str | None = None


@functools.cache
def rosout_type() -> Ros1Type:
    """``rosgraph_msgs/Log`` of ``/rosout`` (ROS 1 only: visnav has no such type to convert)."""
    definition, md5 = noetic_store().generate_msgdef("rosgraph_msgs/msg/Log", ros_version=1)
    return Ros1Type("rosgraph_msgs/msg/Log", "rosgraph_msgs/Log", md5, definition)


def ros1_name(name: str) -> str:
    """Return the ROS 1 spelling ``pkg/Name`` of ``pkg/msg/Name`` (unchanged if already ROS 1)."""
    parts = name.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        return f"{parts[0]}/{parts[2]}"
    return name


def ros2_name(name: str) -> str:
    """Return the ROS 2 spelling ``pkg/msg/Name`` of ``pkg/Name`` (unchanged if already ROS 2)."""
    parts = name.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return name


@functools.cache
def ros1_type(name: str) -> Ros1Type:
    """Return the ROS 1 form of a visnav message type.

    Args:
        name: ``pkg/msg/Name`` or ``pkg/Name``.

    Returns:
        Names, MD5 sum and definition.

    Raises:
        UnconvertibleTypeError: visnav has no such type, or ROS 1 has none with the same wire
            format (the message says which).
    """
    r2 = ros2_name(name)
    native = typestore()
    if r2 not in native.fielddefs:
        msg = (
            f"message type {ros1_name(r2)} is not one visnav knows (no {r2} in its ROS 2 Humble "
            "type store); it cannot be bridged: exclude its topic with --exclude"
        )
        raise UnconvertibleTypeError(msg)
    noetic = noetic_store()
    if r2 in noetic.fielddefs:
        if not same_wire_format(native, noetic, r2, ros1_header=True):
            msg = (
                f"message type {ros1_name(r2)} has different fields in ROS 1 Noetic and ROS 2 "
                "Humble, so its messages cannot be converted byte for byte; exclude its topic "
                "with --exclude"
            )
            raise UnconvertibleTypeError(msg)
    elif r2 not in _NOETIC_OUTSIDE_STORE:
        msg = (
            f"message type {r2} exists only in ROS 2 (ROS 1 Noetic has no {ros1_name(r2)}); "
            "it cannot be bridged: exclude its topic with --exclude"
        )
        raise UnconvertibleTypeError(msg)
    definition, md5 = ros1_definition(r2)
    fields = native.fielddefs[r2][1]
    header_first = bool(fields) and fields[0][1][0] == Nodetype.NAME and fields[0][1][1] == HEADER
    return Ros1Type(r2, ros1_name(r2), md5, definition, header_first, _byte_tail(fields))


def _byte_tail(fields: list[tuple[str, tuple[Any, ...]]]) -> str | None:
    """The last field's name if it is a sequence of bytes (same bytes in CDR and ROS 1)."""
    if not fields:
        return None
    name, (kind, sub) = fields[-1][0], fields[-1][1]
    if kind != Nodetype.SEQUENCE:
        return None
    (elem_kind, elem), bound = sub
    if elem_kind != Nodetype.BASE or bound != 0 or elem[0] not in ("uint8", "int8"):
        return None
    return str(name)


def cdr_to_ros1(data: bytes | memoryview, rtype: Ros1Type) -> memoryview:
    """Convert a CDR message (visnav's wire bytes) into ROS 1 bytes (``seq`` set to 0).

    Returns:
        A view on a new buffer that only the caller holds (not copied again: a ``bytes``
        copy of a 1 MB image costs more than the conversion).

    Raises:
        TcprosError: the bytes do not decode as ``rtype`` (names the type).
    """
    try:
        return typestore().cdr_to_ros1(data, rtype.ros2_name)
    except _DECODE_ERRORS as exc:
        msg = f"CDR bytes do not decode as {rtype.ros2_name}: {exc}"
        raise TcprosError(msg) from exc


def ros1_to_cdr(data: bytes | memoryview, rtype: Ros1Type) -> memoryview:
    """Convert ROS 1 bytes into CDR (``seq`` dropped).

    Returns:
        A view on a new buffer that only the caller holds.

    Raises:
        TcprosError: the bytes do not decode as ``rtype`` (names the type and length).
    """
    try:
        return typestore().ros1_to_cdr(data, rtype.ros2_name)
    except _DECODE_ERRORS as exc:
        msg = f"{len(data)} bytes do not decode as ROS 1 {rtype.ros1_name}: {exc}"
        raise TcprosError(msg) from exc
