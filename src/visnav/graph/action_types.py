"""Pieces actions' servers and clients share: status codes, responses, names, goal ids.

An action ``/name`` is three services and two topics (ROS 2's layout, which rmw_zenoh
and every ROS 2 tool expect):

* ``/name/_action/send_goal`` (``pkg/action/X_SendGoal``): goal id + goal -> accepted, stamp;
* ``/name/_action/cancel_goal`` (``action_msgs/srv/CancelGoal``);
* ``/name/_action/get_result`` (``pkg/action/X_GetResult``): goal id -> status, result
  (answered when the goal ends);
* ``/name/_action/feedback`` (``pkg/action/X_FeedbackMessage``): goal id + feedback;
* ``/name/_action/status`` (``action_msgs/msg/GoalStatusArray``, transient local).
"""

from __future__ import annotations

import enum
import uuid
from typing import Any

import numpy as np

from visnav.graph.errors import GraphError
from visnav.graph.qos import DurabilityPolicy, QoSProfile
from visnav.msgs.serde import get_message_class

__all__ = [
    "ACTION_INFIX",
    "ActionError",
    "CancelResponse",
    "GoalResponse",
    "GoalStatus",
    "TERMINAL",
    "action_names",
    "goal_id_from_bytes",
    "goal_id_hex",
    "goal_key",
    "new_goal_id",
    "qos_profile_action_status_default",
]

ACTION_INFIX = "/_action/"
"""What separates an action's name from its services' and topics' names."""

qos_profile_action_status_default = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""The status topic's QoS (rclpy's): reliable, transient local, depth 1."""


class ActionError(GraphError):
    """An action goal could not be sent, or a goal handle was used out of its state."""


class GoalStatus(enum.IntEnum):
    """``action_msgs/msg/GoalStatus`` codes."""

    STATUS_UNKNOWN = 0
    STATUS_ACCEPTED = 1
    STATUS_EXECUTING = 2
    STATUS_CANCELING = 3
    STATUS_SUCCEEDED = 4
    STATUS_CANCELED = 5
    STATUS_ABORTED = 6


TERMINAL = frozenset(
    {GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED, GoalStatus.STATUS_ABORTED}
)


class GoalResponse(enum.Enum):
    """What a server's ``goal_callback`` returns (rclpy's values)."""

    REJECT = 1
    ACCEPT = 2


class CancelResponse(enum.Enum):
    """What a server's ``cancel_callback`` returns (rclpy's values)."""

    REJECT = 1
    ACCEPT = 2


def action_names(action_name: str) -> dict[str, str]:
    """The names of an action's services and topics, keyed by role.

    Args:
        action_name: the action's (resolved or relative) name, e.g. ``/navigate_to_pose``.

    Returns:
        ``{"send_goal", "cancel_goal", "get_result", "feedback", "status"}`` -> name.
    """
    base = action_name.rstrip("/") or action_name
    return {
        role: f"{base}{ACTION_INFIX}{role}"
        for role in ("send_goal", "cancel_goal", "get_result", "feedback", "status")
    }


_UUID_CLS: list[type[Any]] = []


def _uuid_cls() -> type[Any]:
    if not _UUID_CLS:
        _UUID_CLS.append(get_message_class("unique_identifier_msgs/msg/UUID"))
    return _UUID_CLS[0]


def new_goal_id() -> Any:
    """A random ``unique_identifier_msgs/msg/UUID`` (version 4, as rclpy makes them)."""
    return goal_id_from_bytes(uuid.uuid4().bytes)


def goal_id_from_bytes(data: bytes) -> Any:
    """A ``unique_identifier_msgs/msg/UUID`` holding these 16 bytes."""
    if len(data) != 16:
        msg = f"a goal id is 16 bytes, got {len(data)}"
        raise ActionError(msg)
    return _uuid_cls()(uuid=np.frombuffer(data, dtype=np.uint8).copy())


def goal_id_hex(goal_id: Any) -> str:
    """A goal id as ``ros2 action send_goal`` prints it (32 hex digits)."""
    return goal_key(goal_id).hex()


def goal_key(goal_id: Any) -> bytes:
    """The 16 bytes of a ``UUID`` message (a dictionary key)."""
    raw = goal_id.uuid
    if isinstance(raw, (bytes, bytearray)):
        return bytes(raw)
    return bytes(np.asarray(raw, dtype=np.uint8))
