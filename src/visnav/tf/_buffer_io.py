"""Argument conversion, result messages and frame listings of :class:`visnav.tf.Buffer`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from visnav.msgs.errors import MessageError
from visnav.msgs.time import duration_to_ns, time_to_ns
from visnav.msgs.types import (
    Duration,
    Header,
    Quaternion,
    Time,
    Transform,
    TransformStamped,
    Vector3,
)
from visnav.tf._scalar import Pose7
from visnav.tf._tree import fmt_time
from visnav.tf.errors import InvalidArgumentException

__all__ = [
    "FrameInfo",
    "TimeLike",
    "frames_yaml",
    "inverse_to_msg",
    "pose_to_msg",
    "timeout_s",
    "to_ns",
]

_NS_PER_S = 1_000_000_000


@runtime_checkable
class _HasNanoseconds(Protocol):
    @property
    def nanoseconds(self) -> int: ...


TimeLike = int | Time
"""A time: integer nanoseconds (0 = latest) or a ``builtin_interfaces/Time`` message."""


@dataclass(frozen=True)
class FrameInfo:
    """What the buffer knows about one child frame (the data of ``all_frames_as_yaml``).

    Attributes:
        frame_id: the child frame.
        parent: the parent of its newest sample.
        authority: who inserted the newest sample (tf2's "broadcaster").
        is_static: the frame came from a static transform.
        rate_hz: samples per second of stamp time (tf2's figure; 10000 for a static frame).
        most_recent_ns: newest stamp (0 for a static frame, as tf2).
        oldest_ns: oldest stamp kept (0 for a static frame).
        num_samples: samples kept.
    """

    frame_id: str
    parent: str
    authority: str
    is_static: bool
    rate_hz: float
    most_recent_ns: int
    oldest_ns: int
    num_samples: int

    @property
    def buffer_length_s(self) -> float:
        """Seconds of stamp time between the oldest and the newest sample."""
        return (self.most_recent_ns - self.oldest_ns) / _NS_PER_S


def to_ns(value: object, name: str) -> int:
    """Convert a time argument to integer nanoseconds (see the module docs)."""
    if type(value) is int:
        ns = value
    elif isinstance(value, Time):
        try:
            ns = time_to_ns(value)
        except MessageError as exc:
            msg = f"{name}: {exc}"
            raise InvalidArgumentException(msg) from exc
    elif isinstance(value, bool | float):
        msg = (
            f"{name} is {value!r}: expected int nanoseconds (0 = latest) or a "
            "builtin_interfaces/Time; convert seconds with visnav.msgs.sec_to_ns"
        )
        raise InvalidArgumentException(msg)
    elif isinstance(value, _HasNanoseconds):
        ns = int(value.nanoseconds)
    elif hasattr(value, "__index__"):
        ns = int(value.__index__())
    else:
        msg = (
            f"{name} is {value!r} of type {type(value).__name__}: expected int nanoseconds "
            "or a builtin_interfaces/Time"
        )
        raise InvalidArgumentException(msg)
    if ns < 0:
        msg = f"{name} is {ns} ns: expected a time >= 0 (0 = latest)"
        raise InvalidArgumentException(msg)
    return ns


def timeout_s(value: object) -> float:
    if isinstance(value, Duration):
        return duration_to_ns(value) / _NS_PER_S
    if isinstance(value, _HasNanoseconds):
        return int(value.nanoseconds) / _NS_PER_S
    if isinstance(value, int | float) and not isinstance(value, bool):
        seconds = float(value)
        if math.isfinite(seconds) and seconds >= 0.0:
            return seconds
    msg = f"timeout is {value!r}: expected seconds >= 0 or a builtin_interfaces/Duration"
    raise InvalidArgumentException(msg)


_new = object.__new__


def pose_to_msg(pose: Pose7, target: str, source: str, time_ns: int) -> TransformStamped:
    """Build the result message: equal to the constructors' (tests/tf check), half the cost.

    The message classes are plain dataclasses without ``__post_init__``: their
    ``__init__`` only assigns the fields, so assigning them on a bare instance builds
    the same object without six Python-level ``__init__`` calls. Stored stamps are
    validated on insertion, so the time always fits a ``Time``.
    """
    stamp = _new(Time)
    stamp.sec, stamp.nanosec = divmod(time_ns, _NS_PER_S)
    header = _new(Header)
    header.stamp = stamp
    header.frame_id = target
    translation = _new(Vector3)
    rotation = _new(Quaternion)
    (
        translation.x,
        translation.y,
        translation.z,
        rotation.x,
        rotation.y,
        rotation.z,
        rotation.w,
    ) = pose
    transform = _new(Transform)
    transform.translation = translation
    transform.rotation = rotation
    msg = _new(TransformStamped)
    msg.header = header
    msg.child_frame_id = source
    msg.transform = transform
    return msg


def inverse_to_msg(pose: Pose7, target: str, source: str, time_ns: int) -> TransformStamped:
    """:func:`pose_to_msg` of the inverse of ``pose`` (computed in place: no extra tuple)."""
    tx, ty, tz, x, y, z, w = pose
    cx = 2.0 * (y * tz - z * ty)
    cy = 2.0 * (z * tx - x * tz)
    cz = 2.0 * (x * ty - y * tx)
    stamp = _new(Time)
    stamp.sec, stamp.nanosec = divmod(time_ns, _NS_PER_S)
    header = _new(Header)
    header.stamp = stamp
    header.frame_id = target
    translation = _new(Vector3)
    translation.x = w * cx - tx - y * cz + z * cy
    translation.y = w * cy - ty - z * cx + x * cz
    translation.z = w * cz - tz - x * cy + y * cx
    rotation = _new(Quaternion)
    rotation.x, rotation.y, rotation.z, rotation.w = -x, -y, -z, w
    transform = _new(Transform)
    transform.translation = translation
    transform.rotation = rotation
    msg = _new(TransformStamped)
    msg.header = header
    msg.child_frame_id = source
    msg.transform = transform
    return msg


def frames_yaml(infos: dict[str, FrameInfo], now: int | None) -> str:
    """tf2's ``allFramesAsYAML`` text for ``infos`` (``transform_delay`` when ``now``)."""
    if not infos:
        return "[]"
    lines: list[str] = []
    for info in infos.values():
        broadcaster = (info.authority or "no recorded authority").replace("'", "''")
        parent = info.parent.replace("'", "''")
        lines.append(f"{info.frame_id}:")
        lines.append(f"  parent: '{parent}'")
        lines.append(f"  broadcaster: '{broadcaster}'")
        lines.append(f"  rate: {info.rate_hz:.3f}")
        lines.append(f"  most_recent_transform: {fmt_time(info.most_recent_ns)}")
        lines.append(f"  oldest_transform: {fmt_time(info.oldest_ns)}")
        if now:
            lines.append(f"  transform_delay: {(now - info.most_recent_ns) / _NS_PER_S:.3f}")
        lines.append(f"  buffer_length: {info.buffer_length_s:.3f}")
    return "\n".join(lines) + "\n"
