"""CDR (de)serialization and message type lookup through the ``rosbags`` type store.

Type names are ROS 2 style (``sensor_msgs/msg/Image``). :func:`get_message_class`
also accepts the ROS 1 form ``sensor_msgs/Image``.
"""

from __future__ import annotations

import difflib
import functools
from typing import Any

import numpy as np
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from visnav.msgs.action import register_actions
from visnav.msgs.errors import MessageError, UnknownMessageTypeError
from visnav.msgs.gazebo_msgs import register_gazebo_msgs
from visnav.msgs.srv import register_services

__all__ = [
    "CdrSerializer",
    "deserialize",
    "get_message_class",
    "message_definition",
    "msg_type_name",
    "serialize",
    "typestore",
]

STORE = Stores.ROS2_HUMBLE


@functools.cache
def typestore() -> Typestore:
    """Return the ROS 2 Humble type store visnav uses (created once, then shared read-only).

    Returns:
        The ``rosbags`` type store, with the ``gazebo_msgs`` types the simulator
        publishes (:mod:`visnav.msgs.gazebo_msgs`) and the services of
        :mod:`visnav.msgs.srv` added. Do not register other types into it; make your
        own with ``rosbags.typesys.get_typestore`` for that.
    """
    store = get_typestore(STORE)
    register_gazebo_msgs(store)
    register_services(store)
    register_actions(store)
    return store


def msg_type_name(msg_or_cls: Any) -> str:
    """Return the ROS 2 type name of a message instance or class.

    Args:
        msg_or_cls: a message instance or class from :mod:`visnav.msgs`.

    Returns:
        The name, e.g. ``"sensor_msgs/msg/Image"``.

    Raises:
        MessageError: the object is not a ROS message.
    """
    name = getattr(msg_or_cls, "__msgtype__", None)
    if not isinstance(name, str):
        msg = (
            f"{type(msg_or_cls).__name__!s} is not a ROS message (it has no __msgtype__); "
            "expected a class or instance from visnav.msgs"
        )
        raise MessageError(msg)
    return name


def get_message_class(type_name: str) -> type[Any]:
    """Look up a message class by type name.

    Args:
        type_name: ``pkg/msg/Name`` or the ROS 1 spelling ``pkg/Name``.

    Returns:
        The message dataclass.

    Raises:
        UnknownMessageTypeError: no such type; the message suggests close names.
    """
    types = typestore().types
    name = type_name.strip()
    parts = name.split("/")
    if len(parts) == 2:  # ROS 1 form pkg/Name
        name = f"{parts[0]}/msg/{parts[1]}"
    cls = types.get(name)
    if cls is None:
        close = difflib.get_close_matches(name, list(types), n=3, cutoff=0.6)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        msg = (
            f"unknown message type {type_name!r}: "
            f"expected a name like 'sensor_msgs/msg/Image'{hint}"
        )
        raise UnknownMessageTypeError(msg)
    return cls


def serialize(msg: Any) -> bytes:
    """Serialize a message to CDR (little endian), as ROS 2 puts it on the wire.

    Args:
        msg: a message instance.

    Returns:
        The CDR bytes, including the 4-byte encapsulation header.

    Raises:
        MessageError: the message is not a ROS message or a field has the wrong type.
    """
    name = msg_type_name(msg)
    try:
        return bytes(typestore().serialize_cdr(msg, name))
    except (SerdeError, TypeError, ValueError, AttributeError, KeyError, OverflowError) as exc:
        text = f"cannot serialize {name}: {exc}; check the field types against the definition"
        raise MessageError(text) from exc


class CdrSerializer:
    """Serialize messages of one type into a reused buffer (the publisher fast path).

    ``rosbags``' ``serialize_cdr`` allocates and zero-fills a new buffer per call and
    returns a read-only view that must be copied again to hand it to Zenoh; for a
    921,600-byte image those two fresh allocations (page faults included) cost more
    than the transport. This writes with the same generated ``rosbags`` functions
    into a buffer kept between calls while the size stays the same.

    The returned buffer is valid until the next :meth:`serialize` call. It is zeroed
    before each reuse: the generated functions skip string terminators and alignment
    padding (they expect fresh zeros), so stale bytes of the previous message would
    otherwise remain there.
    """

    def __init__(self, type_name: str) -> None:
        get_message_class(type_name)
        self.type_name = type_name
        self._store = typestore()
        self._msgdef = self._store.get_msgdef(type_name)
        self._buf = bytearray()
        self._view = memoryview(self._buf)

    def serialize(self, msg: Any) -> bytearray:
        """Return ``msg`` as CDR (little endian) in the reused buffer.

        Raises:
            MessageError: a field has the wrong type.
        """
        try:
            size = 4 + self._msgdef.getsize_cdr(0, msg, self._store)
            if size != len(self._buf):
                self._view.release()
                self._buf = bytearray(size)
                self._view = memoryview(self._buf)
                self._buf[1] = 1  # CDR_LE encapsulation: 00 01 00 00
            else:
                # rosbags writes neither string terminators nor alignment padding: it relies
                # on a zero-filled buffer, so a reused one must be zeroed again
                np.frombuffer(self._buf, np.uint8, offset=4)[:] = 0
            end = self._msgdef.serialize_cdr_le(self._view[4:], 0, msg, self._store)
        except (SerdeError, TypeError, ValueError, AttributeError, KeyError, OverflowError) as exc:
            text = f"cannot serialize {self.type_name}: {exc}; check the field types"
            raise MessageError(text) from exc
        if end + 4 != size:  # pragma: no cover - rosbags invariant
            text = f"cannot serialize {self.type_name}: size mismatch {end + 4} != {size}"
            raise MessageError(text)
        return self._buf


def deserialize(data: bytes | memoryview, type_name: str) -> Any:
    """Deserialize CDR bytes into a message.

    Args:
        data: CDR bytes with the encapsulation header.
        type_name: ROS 2 type name of the message.

    Returns:
        The message instance (array fields are numpy views on ``data`` where possible).

    Raises:
        MessageError: the bytes do not decode as ``type_name``.
    """
    get_message_class(type_name)
    try:
        return typestore().deserialize_cdr(data, type_name)
    except (SerdeError, ValueError, IndexError, KeyError, TypeError, AssertionError) as exc:
        text = (
            f"cannot deserialize {len(data)} bytes as {type_name}: {exc}; "
            "expected CDR of that type (is the topic's type right?)"
        )
        raise MessageError(text) from exc


def message_definition(type_name: str) -> str:
    """Return the ROS 2 ``.msg`` text of a type with its dependencies (as bags store it).

    Args:
        type_name: ROS 2 type name.

    Returns:
        The concatenated definition (``rosbags``' ``generate_msgdef`` format).
    """
    get_message_class(type_name)
    text, _md5 = typestore().generate_msgdef(type_name, ros_version=2)
    return text
