"""static_transform_publisher as a node, and its command-line forms as parameters.

The node publishes one transform ``frame_id -> child_frame_id`` on ``/tf_static``
(transient local, so late subscribers get it) from parameters that mirror the
ROS 2 tool's flags: ``x y z`` (metres), ``yaw pitch roll`` (radians) or
``qx qy qz qw``, ``frame_id``, ``child_frame_id``.

:func:`static_transform_params_from_args` turns the tool's argument lists into
those parameters, for launch files written for ROS:

* tf2_ros: ``x y z yaw pitch roll frame child`` or ``x y z qx qy qz qw frame child``;
* tf (ROS 1): the same followed by ``period_ms`` (ignored: ``/tf_static`` is latched);
* ROS 2 flags: ``--x 1 --yaw 0.5 --frame-id base --child-frame-id cam`` (also
  ``--qx ... --qw``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, Quaternion, Transform, TransformStamped, Vector3
from visnav.tf.errors import TransformException
from visnav.tf.ros import StaticTransformBroadcaster
from visnav.tf.transforms import quaternion_from_euler

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "StaticTransformError",
    "StaticTransformParams",
    "StaticTransformPublisherNode",
    "static_transform_params_from_args",
    "static_transform_from_params",
]

_FLAGS = ("x", "y", "z", "yaw", "pitch", "roll", "qx", "qy", "qz", "qw")
_FRAME_FLAGS = {"frame-id": "frame_id", "child-frame-id": "child_frame_id"}
_FORMS = (
    "'x y z yaw pitch roll FRAME CHILD', 'x y z qx qy qz qw FRAME CHILD' (each optionally "
    "followed by the ROS 1 period in ms), or ROS 2 flags '--x X ... --frame-id F "
    "--child-frame-id C'"
)


class StaticTransformError(TransformException, ValueError):
    """static_transform_publisher arguments or parameters that do not make a transform."""


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        msg = f"static_transform_publisher: {what} is {text!r}: expected a number ({_FORMS})"
        raise StaticTransformError(msg) from None
    if not math.isfinite(value):
        msg = f"static_transform_publisher: {what} is {text!r}: expected a finite number"
        raise StaticTransformError(msg)
    return value


def _from_flags(args: Sequence[str]) -> dict[str, Any]:
    params: dict[str, Any] = {}
    i = 0
    while i < len(args):
        flag = args[i]
        key = flag[2:] if flag.startswith("--") else ""
        if (key not in _FLAGS and key not in _FRAME_FLAGS) or i + 1 >= len(args):
            msg = f"static_transform_publisher: cannot read {flag!r} in {list(args)}: use {_FORMS}"
            raise StaticTransformError(msg)
        value = args[i + 1]
        if key in _FRAME_FLAGS:
            params[_FRAME_FLAGS[key]] = value
        else:
            params[key] = _number(value, key)
        i += 2
    return params


def static_transform_params_from_args(args: Sequence[str]) -> dict[str, Any]:
    """Parse static_transform_publisher's arguments into the node's parameters.

    Args:
        args: the argument list (see the module docstring for the accepted forms).

    Returns:
        ``{x, y, z, yaw, pitch, roll | qx, qy, qz, qw, frame_id, child_frame_id}``
        (flag form: only the flags given).

    Raises:
        StaticTransformError: a wrong count, a value that is not a number, an unknown flag.
    """
    args = list(args)
    if any(a.startswith("--") for a in args):
        return _from_flags(args)
    numbers_first = 0
    while numbers_first < len(args):
        try:
            float(args[numbers_first])
        except ValueError:
            break
        numbers_first += 1
    tail = args[numbers_first:]
    # ROS 1 tf adds a trailing period in ms after the two frames.
    if len(tail) == 3 and numbers_first in (6, 7):
        _number(tail[2], "period_ms")
        tail = tail[:2]
    if numbers_first not in (6, 7) or len(tail) != 2:
        msg = f"static_transform_publisher got {len(args)} arguments {args}: expected {_FORMS}"
        raise StaticTransformError(msg)
    nums = [_number(a, "value") for a in args[:numbers_first]]
    names = (
        ("x", "y", "z", "yaw", "pitch", "roll") if numbers_first == 6 else _FLAGS[:3] + _FLAGS[6:]
    )
    params: dict[str, Any] = dict(zip(names, nums, strict=True))
    params["frame_id"], params["child_frame_id"] = tail
    return params


def static_transform_from_params(params: dict[str, Any], *, stamp_ns: int = 0) -> TransformStamped:
    """Build the transform from the node's parameters.

    Raises:
        StaticTransformError: a missing frame, both Euler angles and a quaternion, a zero
            quaternion.
    """
    frame, child = str(params.get("frame_id", "")), str(params.get("child_frame_id", ""))
    if not frame or not child or frame == child:
        msg = (
            f"static_transform_publisher: frame_id {frame!r} and child_frame_id {child!r}: "
            "expected two different, non-empty frame ids"
        )
        raise StaticTransformError(msg)
    euler = [float(params.get(k, 0.0)) for k in ("roll", "pitch", "yaw")]
    quat = [float(params.get(k, 0.0)) for k in ("qx", "qy", "qz")] + [float(params.get("qw", 1.0))]
    quat_given = quat != [0.0, 0.0, 0.0, 1.0]
    if quat_given and any(euler):
        msg = (
            f"static_transform_publisher {frame} -> {child}: both yaw/pitch/roll {euler[::-1]} "
            f"and a quaternion {quat} given: give one rotation"
        )
        raise StaticTransformError(msg)
    if quat_given:
        norm = math.sqrt(sum(v * v for v in quat))
        if norm < 1e-9:
            msg = (
                f"static_transform_publisher {frame} -> {child}: quaternion {quat} has zero length"
            )
            raise StaticTransformError(msg)
        qx, qy, qz, qw = (v / norm for v in quat)
    else:
        qx, qy, qz, qw = (float(v) for v in quaternion_from_euler(*euler))
    return TransformStamped(
        header=Header(stamp=ns_to_time(stamp_ns), frame_id=frame),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(
                x=float(params.get("x", 0.0)),
                y=float(params.get("y", 0.0)),
                z=float(params.get("z", 0.0)),
            ),
            rotation=Quaternion(x=qx, y=qy, z=qz, w=qw),
        ),
    )


@dataclass(frozen=True)
class StaticTransformParams:
    """static_transform_publisher's parameters (the ROS 2 tool's flags; read once at start)."""

    x: float = param(0.0, description="translation x (m)")
    y: float = param(0.0, description="translation y (m)")
    z: float = param(0.0, description="translation z (m)")
    yaw: float = param(0.0, description="rotation about z (rad); or give qx..qw")
    pitch: float = param(0.0, description="rotation about y (rad); or give qx..qw")
    roll: float = param(0.0, description="rotation about x (rad); or give qx..qw")
    qx: float = param(0.0, description="rotation quaternion x; or give yaw/pitch/roll")
    qy: float = param(0.0, description="rotation quaternion y")
    qz: float = param(0.0, description="rotation quaternion z")
    qw: float = param(1.0, description="rotation quaternion w")
    frame_id: str = param("", description="the parent frame (required)")
    child_frame_id: str = param("", description="the child frame (required)")


class StaticTransformPublisherNode(Node):
    """Publish one static transform from parameters (see the module docstring).

    Args:
        name: node name (default ``static_transform_publisher``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (context, namespace, ...).

    Raises:
        StaticTransformError: the parameters do not make a transform.
    """

    def __init__(
        self, name: str = "static_transform_publisher", **node_kwargs: Unpack[NodeOptions]
    ) -> None:
        super().__init__(name, **node_kwargs)
        params = dataclasses.asdict(declare_params(self, StaticTransformParams))
        self.transform = static_transform_from_params(params, stamp_ns=self.get_clock().now_ns())
        self._broadcaster = StaticTransformBroadcaster(self)
        self._broadcaster.send_transform(self.transform)
