"""Service requests and responses as CDR: per-type encoders and decoders, default messages.

A call's hot path looks each type's generated rosbags functions up once (the general
:func:`~visnav.msgs.serde.serialize` / :func:`~visnav.msgs.serde.deserialize` look the
type up on every call); anything unusual goes to the general functions, which word
the errors.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Any

from visnav.msgs.construct import default_message
from visnav.msgs.serde import deserialize, serialize, typestore

__all__ = ["Decoder", "Encoder", "message_factory"]

_CDR_LE = b"\x00\x01"
_COPY_BELOW = 4096


class Decoder:
    """Decode CDR of one message type with its generated function, looked up once.

    A call's hot path: the general :func:`~visnav.msgs.serde.deserialize` looks the
    type up on every call. Anything but well-formed little-endian CDR goes to it, so
    errors (and big-endian data) are handled and worded exactly as there.
    """

    __slots__ = ("_cls", "_func", "_store", "type_name")

    def __init__(self, type_name: str) -> None:
        self.type_name = type_name
        self._store = typestore()
        msgdef = self._store.get_msgdef(type_name)
        self._func = msgdef.deserialize_cdr_le
        self._cls = msgdef.cls

    def __call__(self, data: bytes) -> Any:
        """The message in ``data``; raises MessageError when it does not decode."""
        if data.startswith(_CDR_LE):
            size = len(data)
            # a small message's body is copied (cheaper than a view); a large one is viewed
            body = data[4:] if size <= _COPY_BELOW else memoryview(data)[4:]
            try:
                message, pos = self._func(body, 0, self._cls, self._store)
            except Exception:  # noqa: BLE001, S110 - the general path words the error
                pass
            else:
                if pos + 4 + 3 >= size:
                    return message
        return deserialize(memoryview(data), self.type_name)


class Encoder:
    """Encode messages of one type as little-endian CDR with its generated function.

    The client's hot path (see :class:`Decoder`); a message that does not encode goes
    to :func:`~visnav.msgs.serde.serialize`, which words the error.
    """

    __slots__ = ("_func", "_size", "_store")

    def __init__(self, type_name: str) -> None:
        self._store = typestore()
        msgdef = self._store.get_msgdef(type_name)
        self._size = msgdef.getsize_cdr
        self._func = msgdef.serialize_cdr_le

    def __call__(self, message: Any) -> bytes | bytearray:
        """``message`` as CDR; raises MessageError when it does not encode."""
        try:
            size = self._size(0, message, self._store)
            data = bytearray(4 + size)  # fresh zeros: the generated code skips padding
            data[1] = 1
            if self._func(memoryview(data)[4:], 0, message, self._store) == size:
                return data
        except Exception:  # noqa: BLE001, S110 - the general path words the error
            pass
        return serialize(message)


def message_factory(type_name: str) -> Callable[[], Any]:
    """A maker of fresh default messages of ``type_name`` (``default_message``'s result).

    For types whose fields are all immutable scalars (std_srvs' responses) the
    defaults are computed once; others are built by ``default_message`` each time
    (their arrays and nested messages must not be shared between calls).
    """
    template = default_message(type_name)
    values = {
        f.name: getattr(template, f.name)
        for f in dataclasses.fields(template)
        if f.init and f.name != "__msgtype__"
    }
    if all(type(v) in {bool, int, float, str} for v in values.values()):
        cls: Callable[..., Any] = type(template)
        return functools.partial(cls, **values)
    return functools.partial(default_message, type_name)
