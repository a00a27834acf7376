"""Message types between bags and visnav: definitions, wire compatibility, ROS 1 <-> CDR.

visnav's messages are ROS 2 Humble's. A bag carries its own definitions; a topic is
*native* when the bag's definition has the same wire format as visnav's, and then its
messages become visnav message objects (publishable on the graph). ROS 1 bags differ from
ROS 2 in one place that matters: ``std_msgs/Header`` has a ``seq`` field; ``rosbags``'
byte-level converters (``cdr_to_ros1`` / ``ros1_to_cdr``) add and drop it.

ROS 1 definitions written by visnav come from ``rosbags``' Noetic type store when Noetic has
the type with the same wire format (so the MD5 sums match real ROS 1 nodes, e.g.
``sensor_msgs/CameraInfo``'s upper-case ``D, K, R, P``), otherwise from the Humble definition
with ROS 1's Header (``tf2_msgs/TFMessage``, ``visualization_msgs/Marker``).
"""

from __future__ import annotations

import functools
from typing import Any

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from visnav.msgs.serde import typestore

__all__ = [
    "HEADER",
    "native_store",
    "noetic_store",
    "ros1_definition",
    "ros1_header_store",
    "same_wire_format",
]

HEADER = "std_msgs/msg/Header"


def native_store() -> Typestore:
    """visnav's (ROS 2 Humble) type store."""
    return typestore()


@functools.cache
def noetic_store() -> Typestore:
    """``rosbags``' ROS 1 Noetic type store (read-only, shared)."""
    return get_typestore(Stores.ROS1_NOETIC)


@functools.cache
def ros1_header_store() -> Typestore:
    """Humble's definitions with ROS 1's ``std_msgs/Header`` (read-only, shared)."""
    store = get_typestore(Stores.EMPTY)
    store.register({**typestore().fielddefs, HEADER: noetic_store().fielddefs[HEADER]})
    return store


def _same_desc(src: Typestore, dst: Typestore, a: Any, b: Any, ros1_header: bool) -> bool:
    kind_a, args_a = a
    kind_b, args_b = b
    if kind_a != kind_b:
        return False
    if kind_a == Nodetype.BASE:
        return bool(args_a[0] == args_b[0])  # bounds do not change the wire format
    if kind_a == Nodetype.NAME:
        return same_wire_format(src, dst, args_a, args_b, ros1_header=ros1_header)
    sub_a, size_a = args_a
    sub_b, size_b = args_b
    if kind_a == Nodetype.ARRAY and size_a != size_b:
        return False
    return _same_desc(src, dst, sub_a, sub_b, ros1_header)


def same_wire_format(
    src: Typestore,
    dst: Typestore,
    src_type: str,
    dst_type: str | None = None,
    *,
    ros1_header: bool = False,
) -> bool:
    """Whether a type serializes identically in two type stores (field names may differ).

    Args:
        src: the first store (e.g. the bag's).
        dst: the second store (e.g. visnav's).
        src_type: the type name in ``src``.
        dst_type: the type name in ``dst`` (default ``src_type``).
        ros1_header: treat ``std_msgs/msg/Header`` as equal (ROS 1 <-> ROS 2 byte conversion
            handles its ``seq``).

    Returns:
        True when the layouts match field by field.
    """
    dst_type = dst_type or src_type
    if ros1_header and src_type == HEADER and dst_type == HEADER:
        return True
    if src_type not in src.fielddefs or dst_type not in dst.fielddefs:
        return False
    fields_a = src.fielddefs[src_type][1]
    fields_b = dst.fielddefs[dst_type][1]
    if len(fields_a) != len(fields_b):
        return False
    return all(
        _same_desc(src, dst, da, db, ros1_header)
        for (_, da), (_, db) in zip(fields_a, fields_b, strict=True)
    )


@functools.cache
def ros1_definition(type_name: str) -> tuple[str, str]:
    """Return the ROS 1 ``(message_definition, md5sum)`` visnav writes for a Humble type.

    Args:
        type_name: a type of visnav's store, e.g. ``sensor_msgs/msg/Image``.

    Returns:
        Noetic's definition and MD5 when Noetic has the type with the same wire format,
        otherwise Humble's definition with ROS 1's Header.
    """
    noetic = noetic_store()
    if type_name in noetic.fielddefs and same_wire_format(
        typestore(), noetic, type_name, ros1_header=True
    ):
        return noetic.generate_msgdef(type_name, ros_version=1)
    return ros1_header_store().generate_msgdef(type_name, ros_version=1)
