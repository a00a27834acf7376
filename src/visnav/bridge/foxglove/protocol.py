"""The Foxglove WebSocket protocol (``foxglove.websocket.v1``): client frames in, server ones out.

Written from the published specification (github.com/foxglove/ws-protocol, ``docs/spec.md``):
text frames carry JSON objects with an ``op`` field, binary frames start with a one-byte
opcode followed by little-endian fields. Nothing here touches the network or the graph, so
the parser is tested on its own (a fuzz test feeds it arbitrary frames): every malformed
frame raises :class:`FoxgloveProtocolError`, which names the op, the field, the value and
what was expected.
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Any

from visnav.bridge.foxglove.errors import FoxgloveProtocolError

__all__ = [
    "CAPABILITIES",
    "SUBPROTOCOLS",
    "Advertise",
    "CallService",
    "ClientChannel",
    "ClientMessage",
    "FetchAsset",
    "GetParameters",
    "PublishData",
    "SetParameters",
    "Subscribe",
    "SubscribeGraph",
    "SubscribeParameterUpdates",
    "Unadvertise",
    "Unsubscribe",
    "UnsubscribeParameterUpdates",
    "encode_fetch_asset_response",
    "encode_message_data",
    "encode_service_response",
    "encode_time",
    "json_text",
    "parse_client_message",
]

SUBPROTOCOLS = ("foxglove.websocket.v1", "foxglove.sdk.v1")
"""Subprotocols accepted, in order of preference: the spec's (Lichtblick, ``@foxglove/ws-protocol``,
foxglove_bridge) and the Foxglove SDK's newer name (Foxglove app)."""

CAPABILITIES = (
    "clientPublish",
    "parameters",
    "parametersSubscribe",
    "services",
    "connectionGraph",
    "assets",
    "time",
)
"""Capabilities this server can offer (foxglove_bridge's defaults; ``time`` with sim time)."""

MAX_TEXT_CHARS = 16 << 20
"""Largest JSON frame accepted (16 MiB of text)."""

# binary opcodes, server -> client
_OP_MESSAGE_DATA = 0x01
_OP_TIME = 0x02
_OP_SERVICE_RESPONSE = 0x03
_OP_FETCH_ASSET_RESPONSE = 0x04
# binary opcodes, client -> server
_COP_MESSAGE_DATA = 0x01
_COP_SERVICE_REQUEST = 0x02

_MSG_HEADER = struct.Struct("<BIQ")
_TIME = struct.Struct("<BQ")
_SRV_HEADER = struct.Struct("<BIII")
_ASSET_HEADER = struct.Struct("<BIBI")
_U32 = struct.Struct("<I")
_U32_MAX = 0xFFFFFFFF
_U64_MAX = 0xFFFFFFFFFFFFFFFF


@dataclass(frozen=True)
class Subscribe:
    """``subscribe``: pairs of (subscription id, channel id)."""

    subscriptions: tuple[tuple[int, int], ...]


@dataclass(frozen=True)
class Unsubscribe:
    """``unsubscribe``: subscription ids."""

    subscription_ids: tuple[int, ...]


@dataclass(frozen=True)
class ClientChannel:
    """A channel a client advertises to publish on (``clientPublish``)."""

    id: int
    topic: str
    encoding: str
    schema_name: str
    schema: str | None = None
    schema_encoding: str | None = None


@dataclass(frozen=True)
class Advertise:
    """Client ``advertise``."""

    channels: tuple[ClientChannel, ...]


@dataclass(frozen=True)
class Unadvertise:
    """Client ``unadvertise``: client channel ids."""

    channel_ids: tuple[int, ...]


@dataclass(frozen=True)
class PublishData:
    """Binary client message data (opcode 0x01) on a client channel."""

    channel_id: int
    data: bytes


@dataclass(frozen=True)
class CallService:
    """Binary service call request (opcode 0x02)."""

    service_id: int
    call_id: int
    encoding: str
    data: bytes


@dataclass(frozen=True)
class GetParameters:
    """``getParameters``: names (empty: all) and the request id to echo."""

    names: tuple[str, ...]
    request_id: str | None


@dataclass(frozen=True)
class SetParameters:
    """``setParameters``: ``(name, value, type hint)`` triples and the request id to echo."""

    parameters: tuple[tuple[str, Any, str | None], ...]
    request_id: str | None


@dataclass(frozen=True)
class SubscribeParameterUpdates:
    """``subscribeParameterUpdates``."""

    names: tuple[str, ...]


@dataclass(frozen=True)
class UnsubscribeParameterUpdates:
    """``unsubscribeParameterUpdates``."""

    names: tuple[str, ...]


@dataclass(frozen=True)
class SubscribeGraph:
    """``subscribeConnectionGraph`` (True) / ``unsubscribeConnectionGraph`` (False)."""

    subscribe: bool


@dataclass(frozen=True)
class FetchAsset:
    """``fetchAsset``: an asset URI and the uint32 request id to answer with."""

    uri: str
    request_id: int


ClientMessage = (
    Subscribe
    | Unsubscribe
    | Advertise
    | Unadvertise
    | PublishData
    | CallService
    | GetParameters
    | SetParameters
    | SubscribeParameterUpdates
    | UnsubscribeParameterUpdates
    | SubscribeGraph
    | FetchAsset
)


def _fail(op: str, what: str) -> FoxgloveProtocolError:
    return FoxgloveProtocolError(f"client message {op!r}: {what}")


def _field(obj: dict[str, Any], op: str, key: str, kind: type | tuple[type, ...]) -> Any:
    if key not in obj:
        raise _fail(op, f"field {key!r} is missing (see the ws-protocol spec)")
    value = obj[key]
    if isinstance(value, bool) and kind is not bool and bool not in _kinds(kind):
        raise _fail(op, f"field {key!r} is {value!r}: expected {_kind_name(kind)}")
    if not isinstance(value, kind):
        raise _fail(op, f"field {key!r} is {_short(value)}: expected {_kind_name(kind)}")
    return value


def _kinds(kind: type | tuple[type, ...]) -> tuple[type, ...]:
    return kind if isinstance(kind, tuple) else (kind,)


def _kind_name(kind: type | tuple[type, ...]) -> str:
    names = {int: "an integer", str: "a string", list: "an array", dict: "an object"}
    return " or ".join(names.get(k, k.__name__) for k in _kinds(kind))


def _short(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, (bytes, bytearray)) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _uint(obj: dict[str, Any], op: str, key: str, limit: int = _U32_MAX) -> int:
    value = _field(obj, op, key, int)
    if not 0 <= value <= limit:
        raise _fail(op, f"field {key!r} is {value}: expected an integer in [0, {limit}]")
    return int(value)


def _list(obj: dict[str, Any], op: str, key: str) -> list[Any]:
    return list(_field(obj, op, key, list))


def _objects(obj: dict[str, Any], op: str, key: str) -> list[dict[str, Any]]:
    items = _list(obj, op, key)
    for i, item in enumerate(items):
        if not isinstance(item, dict):
            raise _fail(op, f"{key}[{i}] is {_short(item)}: expected an object")
    return items


def _strings(obj: dict[str, Any], op: str, key: str) -> tuple[str, ...]:
    items = _list(obj, op, key)
    for i, item in enumerate(items):
        if not isinstance(item, str):
            raise _fail(op, f"{key}[{i}] is {_short(item)}: expected a string")
    return tuple(items)


def _uints(obj: dict[str, Any], op: str, key: str) -> tuple[int, ...]:
    items = _list(obj, op, key)
    for i, item in enumerate(items):
        if isinstance(item, bool) or not isinstance(item, int) or not 0 <= item <= _U32_MAX:
            raise _fail(op, f"{key}[{i}] is {_short(item)}: expected an integer in [0, 2^32)")
    return tuple(items)


def _request_id(obj: dict[str, Any], op: str) -> str | None:
    rid = obj.get("id")
    if rid is None:
        return None
    if not isinstance(rid, str):
        raise _fail(op, f"field 'id' is {_short(rid)}: expected a string")
    return rid


def _optional_str(obj: dict[str, Any], op: str, key: str) -> str | None:
    value = obj.get(key)
    if value is not None and not isinstance(value, str):
        raise _fail(op, f"field {key!r} is {_short(value)}: expected a string")
    return value


def _parse_channel(item: dict[str, Any]) -> ClientChannel:
    op = "advertise"
    return ClientChannel(
        id=_uint(item, op, "id"),
        topic=_field(item, op, "topic", str),
        encoding=_field(item, op, "encoding", str),
        schema_name=_field(item, op, "schemaName", str),
        schema=_optional_str(item, op, "schema"),
        schema_encoding=_optional_str(item, op, "schemaEncoding"),
    )


def _parse_parameter(item: dict[str, Any]) -> tuple[str, Any, str | None]:
    op = "setParameters"
    name = _field(item, op, "name", str)
    hint = _optional_str(item, op, "type")
    if hint not in (None, "byte_array", "float64", "float64_array"):
        raise _fail(
            op, f"parameter {name!r}: type {hint!r} is not byte_array|float64|float64_array"
        )
    return name, item.get("value"), hint


def _parse_json(text: str) -> ClientMessage:
    if len(text) > MAX_TEXT_CHARS:
        raise _fail("?", f"a text frame of {len(text)} characters (at most {MAX_TEXT_CHARS})")
    try:
        obj = json.loads(text, parse_constant=_no_constant)
    except (ValueError, RecursionError) as exc:
        raise _fail("?", f"the text frame is not JSON ({exc})") from exc
    if not isinstance(obj, dict):
        raise _fail("?", f"the text frame is {_short(obj)}: expected a JSON object with 'op'")
    op = obj.get("op")
    if not isinstance(op, str):
        raise _fail("?", f"field 'op' is {_short(op)}: expected the operation's name")
    if op == "subscribe":
        subs = _objects(obj, op, "subscriptions")
        return Subscribe(tuple((_uint(s, op, "id"), _uint(s, op, "channelId")) for s in subs))
    if op == "unsubscribe":
        return Unsubscribe(_uints(obj, op, "subscriptionIds"))
    if op == "advertise":
        return Advertise(tuple(_parse_channel(c) for c in _objects(obj, op, "channels")))
    if op == "unadvertise":
        return Unadvertise(_uints(obj, op, "channelIds"))
    if op == "getParameters":
        return GetParameters(_strings(obj, op, "parameterNames"), _request_id(obj, op))
    if op == "setParameters":
        params = tuple(_parse_parameter(p) for p in _objects(obj, op, "parameters"))
        return SetParameters(params, _request_id(obj, op))
    if op == "subscribeParameterUpdates":
        return SubscribeParameterUpdates(_strings(obj, op, "parameterNames"))
    if op == "unsubscribeParameterUpdates":
        return UnsubscribeParameterUpdates(_strings(obj, op, "parameterNames"))
    if op in ("subscribeConnectionGraph", "unsubscribeConnectionGraph"):
        return SubscribeGraph(op == "subscribeConnectionGraph")
    if op == "fetchAsset":
        return FetchAsset(_field(obj, op, "uri", str), _uint(obj, op, "requestId"))
    known = (
        "subscribe, unsubscribe, advertise, unadvertise, getParameters, setParameters, "
        "subscribeParameterUpdates, unsubscribeParameterUpdates, subscribeConnectionGraph, "
        "unsubscribeConnectionGraph, fetchAsset"
    )
    raise _fail(op, f"unknown operation (expected one of {known})")


def _no_constant(name: str) -> Any:
    msg = f"{name} is not JSON"
    raise ValueError(msg)


def _parse_binary(data: bytes) -> ClientMessage:
    if not data:
        raise _fail("binary", "an empty binary frame: expected an opcode byte (1 or 2)")
    opcode = data[0]
    if opcode == _COP_MESSAGE_DATA:
        if len(data) < 5:
            raise _fail("messageData", f"{len(data)} bytes: expected opcode + uint32 channel id")
        (channel,) = _U32.unpack_from(data, 1)
        return PublishData(channel, bytes(data[5:]))
    if opcode == _COP_SERVICE_REQUEST:
        if len(data) < 13:
            raise _fail(
                "serviceCallRequest",
                f"{len(data)} bytes: expected opcode + service id, call id, encoding length",
            )
        _op, service_id, call_id, n = _SRV_HEADER.unpack_from(data, 0)
        if 13 + n > len(data):
            raise _fail("serviceCallRequest", f"encoding length {n} exceeds the frame")
        try:
            encoding = bytes(data[13 : 13 + n]).decode()
        except UnicodeDecodeError as exc:
            raise _fail("serviceCallRequest", f"the encoding is not UTF-8 ({exc})") from exc
        return CallService(service_id, call_id, encoding, bytes(data[13 + n :]))
    raise _fail(
        "binary", f"opcode {opcode:#04x}: expected 0x01 (message data) or 0x02 (service call)"
    )


def parse_client_message(frame: str | bytes | bytearray | memoryview) -> ClientMessage:
    """Parse one WebSocket frame from a client.

    Args:
        frame: a text frame (``str``) or a binary frame.

    Returns:
        The parsed operation.

    Raises:
        FoxgloveProtocolError: the frame is not a valid client message of the spec.
    """
    if isinstance(frame, str):
        return _parse_json(frame)
    return _parse_binary(bytes(frame))


def json_text(obj: dict[str, Any]) -> str:
    """A server JSON message as text (NaN and infinities become null, as JSON has none)."""
    return json.dumps(_finite(obj), separators=(",", ":"), allow_nan=False)


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def encode_message_data(subscription_id: int, timestamp_ns: int, payload: bytes) -> bytes:
    """Binary message data (opcode 0x01): subscription id, receive time (ns), payload."""
    return _MSG_HEADER.pack(_OP_MESSAGE_DATA, subscription_id, timestamp_ns & _U64_MAX) + payload


def encode_time(timestamp_ns: int) -> bytes:
    """Binary time (opcode 0x02), for the ``time`` capability."""
    return _TIME.pack(_OP_TIME, timestamp_ns & _U64_MAX)


def encode_service_response(service_id: int, call_id: int, encoding: str, payload: bytes) -> bytes:
    """Binary service call response (opcode 0x03)."""
    enc = encoding.encode()
    return _SRV_HEADER.pack(_OP_SERVICE_RESPONSE, service_id, call_id, len(enc)) + enc + payload


def encode_fetch_asset_response(
    request_id: int, *, data: bytes = b"", error: str | None = None
) -> bytes:
    """Binary fetch asset response (opcode 0x04): the asset's bytes, or (``error``) status 1.

    Args:
        request_id: the ``requestId`` of the client's ``fetchAsset``.
        data: the file's contents (status 0).
        error: why the asset cannot be served (status 1, no data).
    """
    if error is None:
        return _ASSET_HEADER.pack(_OP_FETCH_ASSET_RESPONSE, request_id, 0, 0) + data
    text = error.encode()
    return _ASSET_HEADER.pack(_OP_FETCH_ASSET_RESPONSE, request_id, 1, len(text)) + text
