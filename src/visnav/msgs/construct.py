"""Build messages from defaults and plain data, and turn messages back into plain data.

What ``ros2 topic pub`` and ``ros2 topic echo`` need: :func:`default_message`
(every field at its ROS default), :func:`message_from_dict` (YAML-like values onto
the defaults, with errors that name the field path) and :func:`message_to_dict`
(numpy arrays become lists, optionally truncated like ``--truncate-length``).
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

from visnav.msgs.errors import MessageError
from visnav.msgs.serde import get_message_class, msg_type_name, typestore

__all__ = [
    "default_message",
    "make",
    "get_field",
    "message_fields",
    "message_from_dict",
    "message_to_dict",
    "message_to_yaml",
]

MsgT = TypeVar("MsgT")

_NUMPY: dict[str, type[np.generic]] = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}
_NAME, _BASE, _ARRAY, _SEQUENCE = 2, 1, 3, 4


def message_fields(type_name: str) -> list[tuple[str, Any]]:
    """Return ``[(field, rosbags field description)]`` of a type."""
    get_message_class(type_name)
    return list(typestore().fielddefs[type_name][1])


# Field defaults that ROS 2 message definitions declare (``float64 w 1`` in
# geometry_msgs/Quaternion.msg): the rosbags type store keeps types, not default values, and
# rclpy's ``Quaternion()`` is the identity rotation.
_DECLARED_DEFAULTS: dict[str, dict[str, Any]] = {
    "geometry_msgs/msg/Quaternion": {"w": 1.0},
}


def _base_default(base: str) -> Any:
    if base in {"string", "wstring"}:
        return ""
    if base == "bool":
        return False
    if base.startswith("float"):
        return 0.0
    return 0


def _default_for(desc: Any) -> Any:
    kind, rest = int(desc[0]), desc[1]
    if kind == _BASE:
        return _base_default(rest[0])
    if kind == _NAME:
        return default_message(rest)
    sub, size = rest
    sub_kind = int(sub[0])
    if sub_kind == _BASE and sub[1][0] in _NUMPY:
        return np.zeros(size if kind == _ARRAY else 0, dtype=_NUMPY[sub[1][0]])
    if kind == _ARRAY:
        return [_default_for(sub) for _ in range(size)]
    return []


def default_message(type_name: str) -> Any:
    """Return a message of ``type_name`` with every field at its ROS default.

    Raises:
        UnknownMessageTypeError: no such type.
    """
    cls = get_message_class(type_name)
    values = {name: _default_for(desc) for name, desc in message_fields(type_name)}
    values.update(_DECLARED_DEFAULTS.get(type_name, {}))
    return cls(**values)


def make(msg_type: type[MsgT], **fields: Any) -> MsgT:
    """Construct a message with unspecified fields at their ROS defaults.

    rosbags' message classes need every field; rclpy's messages default them. ``make``
    gives the rclpy behaviour: ``make(Twist, linear=Vector3(x=0.5, y=0.0, z=0.0))``.

    Raises:
        MessageError: a field name that the type does not have.
    """
    type_name = msg_type_name(msg_type)
    defaults = {name: _default_for(desc) for name, desc in message_fields(type_name)}
    defaults.update(_DECLARED_DEFAULTS.get(type_name, {}))
    unknown = [k for k in fields if k not in defaults]
    if unknown:
        close = difflib.get_close_matches(unknown[0], list(defaults), n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        text = f"{type_name} has no field '{unknown[0]}': fields are {', '.join(defaults)}{hint}"
        raise MessageError(text)
    defaults.update(fields)
    return msg_type(**defaults)


def _convert(desc: Any, value: Any, path: str) -> Any:
    kind, rest = int(desc[0]), desc[1]
    if kind == _NAME:
        if not isinstance(value, Mapping):
            msg = f"field '{path}' is a {rest}: expected a mapping of its fields, got {value!r}"
            raise MessageError(msg)
        return message_from_dict(rest, value, path=path)
    if kind == _BASE:
        base = rest[0]
        try:
            if base in ("string", "wstring"):
                if not isinstance(value, str):
                    raise TypeError
                return value
            if base == "bool":
                if not isinstance(value, bool | int):
                    raise TypeError
                return bool(value)
            if base.startswith("float"):
                return float(value)
            if isinstance(value, float) and not value.is_integer():
                raise TypeError
            return int(value)
        except (TypeError, ValueError) as exc:
            msg = f"field '{path}' is {base}: got {value!r}"
            raise MessageError(msg) from exc
    sub, size = rest
    if not isinstance(value, list | tuple | np.ndarray):
        msg = f"field '{path}' is an array: expected a list, got {value!r}"
        raise MessageError(msg)
    if kind == _ARRAY and len(value) != size:
        msg = f"field '{path}' is a fixed array of {size}: got {len(value)} values"
        raise MessageError(msg)
    items = [_convert(sub, v, f"{path}[{i}]") for i, v in enumerate(value)]
    if int(sub[0]) == _BASE and sub[1][0] in _NUMPY:
        return np.array(items, dtype=_NUMPY[sub[1][0]])
    return items


def message_from_dict(type_name: str, values: Mapping[str, Any], *, path: str = "") -> Any:
    """Build a message from a (nested) mapping; unspecified fields keep their defaults.

    Args:
        type_name: ROS 2 type name.
        values: field values, nested mappings for sub-messages, lists for arrays.
        path: field path prefix for error messages.

    Raises:
        MessageError: an unknown field (closest names suggested) or a value of the wrong type.
    """
    fields = dict(message_fields(type_name))
    msg = default_message(type_name)
    for key, value in values.items():
        where = f"{path}.{key}" if path else str(key)
        if key not in fields:
            close = difflib.get_close_matches(str(key), list(fields), n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            text = f"{type_name} has no field '{where}': fields are {', '.join(fields)}{hint}"
            raise MessageError(text)
        setattr(msg, key, _convert(fields[key], value, where))
    return msg


def message_to_dict(
    msg: Any, *, truncate_length: int | None = None, time_offset_ns: int | None = None
) -> dict[str, Any]:
    """Return a message as nested plain data (dicts, lists, numbers, strings).

    Args:
        msg: the message.
        truncate_length: cut arrays and strings longer than this (with a trailing ``"..."``).
        time_offset_ns: if given, every ``builtin_interfaces/Time`` in the message becomes
            its offset from this time in float seconds (rostopic echo ``--offset``).
    """
    out: dict[str, Any] = {}
    for name, _desc in message_fields(msg_type_name(msg)):
        out[name] = _plain(getattr(msg, name), truncate_length, time_offset_ns)
    return out


def _plain(value: Any, limit: int | None, offset_ns: int | None = None) -> Any:
    if hasattr(value, "__msgtype__"):
        if offset_ns is not None and value.__msgtype__ == "builtin_interfaces/msg/Time":
            return (int(value.sec) * 1_000_000_000 + int(value.nanosec) - offset_ns) / 1e9
        return message_to_dict(value, truncate_length=limit, time_offset_ns=offset_ns)
    if isinstance(value, np.ndarray):
        items = value[:limit].tolist() if limit is not None else value.tolist()
        return [*items, "..."] if limit is not None and len(value) > limit else items
    if isinstance(value, list):
        cut = value[:limit] if limit is not None else value
        items = [_plain(v, limit, offset_ns) for v in cut]
        return [*items, "..."] if limit is not None and len(value) > limit else items
    if isinstance(value, str) and limit is not None and len(value) > limit:
        return value[:limit] + "..."
    if isinstance(value, np.generic):
        return value.item()
    return value


def get_field(msg: Any, field_path: str) -> Any:
    """Return a nested field by dotted path (``header.stamp.sec``).

    Raises:
        MessageError: a path element does not exist (names the valid fields).
    """
    value = msg
    for part in field_path.strip(".").split("."):
        if not hasattr(value, "__msgtype__") or not hasattr(value, part):
            names = (
                [n for n, _ in message_fields(msg_type_name(value))]
                if hasattr(value, "__msgtype__")
                else []
            )
            close = difflib.get_close_matches(part, names, n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            text = f"field '{field_path}': '{part}' does not exist{hint}"
            raise MessageError(text)
        value = getattr(value, part)
    return value


def _yaml_lines(value: Any, indent: int) -> list[str]:
    pad = "  " * indent
    lines: list[str] = []
    if isinstance(value, dict):
        for k, v in value.items():
            if isinstance(v, dict):
                lines.append(f"{pad}{k}:")
                lines.extend(_yaml_lines(v, indent + 1))
            elif isinstance(v, list) and v and isinstance(v[0], dict):
                lines.append(f"{pad}{k}:")
                for item in v:
                    sub = _yaml_lines(item, indent + 1)
                    if sub:
                        sub[0] = f"{pad}- " + sub[0].lstrip()
                    lines.extend(sub)
            else:
                lines.append(f"{pad}{k}: {_scalar(v)}")
    return lines


def _scalar(v: Any) -> str:
    if isinstance(v, str):
        return f"'{v}'" if v == "" or v.strip() != v or ":" in v else v
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(_scalar(x) if x != "..." else "..." for x in v) + "]"
    return str(v)


def message_to_yaml(
    msg: Any, *, truncate_length: int | None = 128, time_offset_ns: int | None = None
) -> str:
    """Return a message as YAML text in the layout of ``ros2 topic echo``.

    ``time_offset_ns`` as :func:`message_to_dict`'s.
    """
    data = message_to_dict(msg, truncate_length=truncate_length, time_offset_ns=time_offset_ns)
    return "\n".join(_yaml_lines(data, 0))
