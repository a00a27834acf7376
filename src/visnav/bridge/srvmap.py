"""ROS 2 (visnav) <-> ROS 1 service types: names, MD5 sums and the request / response bytes.

A visnav service type ``pkg/srv/Name`` crosses to ROS 1 as ``pkg/Name`` when its package is
one ROS 1 has (not a ROS 2-only one such as ``rcl_interfaces``) and every message its request
and response hold crosses as a topic type does (:func:`visnav.bridge.typemap.ros1_type`). Its
MD5 sum is ROS 1's: the MD5 of the request's MD5 text followed by the response's (genmsg's
rule), checked against Debian's ``std_srvs`` and ``nav_msgs`` in the tests. ROS 2's
``structure_needs_at_least_one_member`` (an empty request or response) is no byte in ROS 1.
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from typing import Any

from rosbags.interfaces import Nodetype

from visnav.bag.typeconv import ros1_definition
from visnav.bridge.errors import TcprosError, UnconvertibleTypeError
from visnav.bridge.typemap import Ros1Type, cdr_to_ros1, ros1_name, ros1_to_cdr, ros1_type
from visnav.msgs.construct import default_message
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import deserialize, serialize, typestore

__all__ = [
    "ROS2_ONLY_PACKAGES",
    "Ros1ServiceType",
    "decode_part",
    "encode_part",
    "md5_text",
    "ros1_service_type",
]

ROS2_ONLY_PACKAGES = frozenset(
    {
        "action_msgs",
        "composition_interfaces",
        "lifecycle_msgs",
        "nav2_msgs",
        "rcl_interfaces",
        "rosbag2_interfaces",
        "type_description_interfaces",
    }
)
"""Packages of service types ROS 1 has no counterpart of (not bridged, logged at debug)."""

_PLACEHOLDER = "structure_needs_at_least_one_member"
_TIME = {"builtin_interfaces/msg/Time": "time", "builtin_interfaces/msg/Duration": "duration"}


@dataclass(frozen=True)
class Ros1ServiceType:
    """A service type as both graphs name it.

    Attributes:
        ros2_name: visnav's name, e.g. ``std_srvs/srv/SetBool``.
        ros1_name: ROS 1's, e.g. ``std_srvs/SetBool``.
        md5sum: ROS 1's MD5 sum of the service (TCPROS ``md5sum``).
        request: the request message (``std_srvs/srv/SetBool_Request`` /
            ``std_srvs/SetBoolRequest``).
        response: the response message.
    """

    ros2_name: str
    ros1_name: str
    md5sum: str
    request: Ros1Type
    response: Ros1Type


def _hash_type(desc: tuple[Any, Any]) -> str:
    kind, args = desc
    if kind == Nodetype.BASE:
        return str(args[0])
    if kind == Nodetype.NAME:
        return _TIME.get(args) or ros1_definition(args)[1]
    (sub_kind, sub), count = args
    if sub_kind == Nodetype.BASE:
        size = str(count) if kind == Nodetype.ARRAY and count else ""
        return f"{sub[0]}[{size}]"
    if sub in _TIME:
        size = str(count) if kind == Nodetype.ARRAY and count else ""
        return f"{_TIME[sub]}[{size}]"
    return ros1_definition(sub)[1]  # arrays of messages hash as the message (genmsg)


def md5_text(type_name: str) -> str:
    """genmsg's MD5 text of a message of visnav's store (constants, then fields)."""
    consts, fields = typestore().fielddefs[type_name]
    lines = [f"{typ} {name}={value}" for name, typ, value in consts]
    lines += [f"{_hash_type(desc)} {name}" for name, desc in fields if name != _PLACEHOLDER]
    return "\n".join(lines)


def _is_empty(type_name: str) -> bool:
    fields = typestore().fielddefs[type_name][1]
    return all(name == _PLACEHOLDER for name, _ in fields)


def _check_fields(service: str, type_name: str) -> None:
    for name, (kind, args) in typestore().fielddefs[type_name][1]:
        sub = args if kind == Nodetype.NAME else (args[0][1] if kind != Nodetype.BASE else None)
        if not isinstance(sub, str) or sub in _TIME:
            continue
        try:
            ros1_type(sub)
        except UnconvertibleTypeError as exc:
            msg = f"service type {service}: field {name!r} cannot cross to ROS 1: {exc}"
            raise UnconvertibleTypeError(msg) from exc


def _part(type_name: str, ros1: str) -> Ros1Type:
    text = md5_text(type_name)
    md5 = hashlib.md5(text.encode()).hexdigest()  # noqa: S324 - ROS 1's checksum, not security
    return Ros1Type(type_name, ros1, md5, "")


@functools.cache
def ros1_service_type(name: str) -> Ros1ServiceType:
    """Return the ROS 1 form of a visnav service type.

    Args:
        name: ``pkg/srv/Name`` (or ``pkg/Name``).

    Raises:
        UnconvertibleTypeError: visnav does not know it, it is ROS 2-only (an action's
            services, ``rcl_interfaces``, ...), or a field has no ROS 1 counterpart.
    """
    parts = name.split("/")
    r2 = f"{parts[0]}/srv/{parts[1]}" if len(parts) == 2 else name
    pkg, kind, short = ([*r2.split("/"), "", ""])[:3]
    store = typestore().fielddefs
    if kind != "srv" or f"{r2}_Request" not in store or f"{r2}_Response" not in store:
        msg = (
            f"{name} is not a service type visnav knows as pkg/srv/Name (an action's "
            "services cross to ROS 1 as actionlib topics, not as services)"
        )
        raise UnconvertibleTypeError(msg)
    if pkg in ROS2_ONLY_PACKAGES:
        msg = f"service type {r2} exists only in ROS 2 (ROS 1 has no {pkg})"
        raise UnconvertibleTypeError(msg)
    _check_fields(r2, f"{r2}_Request")
    _check_fields(r2, f"{r2}_Response")
    ros1 = ros1_name(f"{pkg}/msg/{short}")
    request = _part(f"{r2}_Request", f"{ros1}Request")
    response = _part(f"{r2}_Response", f"{ros1}Response")
    text = md5_text(request.ros2_name) + md5_text(response.ros2_name)
    md5 = hashlib.md5(text.encode()).hexdigest()  # noqa: S324 - ROS 1's checksum
    return Ros1ServiceType(r2, ros1, md5, request, response)


def encode_part(msg: Any, part: Ros1Type) -> bytes:
    """A request or response object as ROS 1 bytes.

    Raises:
        TcprosError: the object does not serialize as ``part`` (names the type).
    """
    if _is_empty(part.ros2_name):
        return b""
    try:
        return bytes(cdr_to_ros1(serialize(msg), part))
    except MessageError as exc:
        msg_text = f"cannot serialize a {part.ros2_name}: {exc}"
        raise TcprosError(msg_text) from exc


def decode_part(data: bytes | bytearray | memoryview, part: Ros1Type) -> Any:
    """ROS 1 bytes of a request or response as a visnav message object.

    Raises:
        TcprosError: the bytes do not decode as ``part`` (names the type and length).
    """
    if _is_empty(part.ros2_name):
        return default_message(part.ros2_name)
    cdr = ros1_to_cdr(memoryview(data), part)
    try:
        return deserialize(cdr, part.ros2_name)
    except MessageError as exc:
        msg = f"{len(data)} bytes do not decode as ROS 1 {part.ros1_name}: {exc}"
        raise TcprosError(msg) from exc
