"""Action types: ``pkg/action/Name`` as ROS 2 derives its messages and services.

An ``.action`` file has three parts (goal ``---`` result ``---`` feedback). ROS 2
(rosidl) turns it into the messages ``Name_Goal``, ``Name_Result``, ``Name_Feedback``,
``Name_FeedbackMessage`` (``unique_identifier_msgs/UUID goal_id`` + feedback), and two
services: ``Name_SendGoal`` (goal id + goal -> ``bool accepted``, ``builtin_interfaces/Time
stamp``) and ``Name_GetResult`` (goal id -> ``int8 status``, result). This module
registers those, the services' ``_Event`` messages and the ``Name_SendGoal`` /
``Name_GetResult`` / ``Name`` structs (REP 2016 hashes them) into visnav's type
store, for the actions of :data:`ACTION_DEFINITIONS`. Cancelling uses
``action_msgs/srv/CancelGoal`` (:mod:`visnav.msgs.srv`).

:func:`get_action_type` returns an :class:`ActionType` with ``Goal``, ``Result`` and
``Feedback`` classes, as ``from nav2_msgs.action import NavigateToPose`` does::

    NavigateToPose = get_action_type("nav2_msgs/action/NavigateToPose")
    goal = NavigateToPose.Goal()
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
from typing import TYPE_CHECKING, Any

from rosbags.typesys import get_types_from_msg

from visnav.msgs.errors import UnknownMessageTypeError

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = [
    "ACTION_DEFINITIONS",
    "ActionType",
    "action_type_names",
    "get_action_type",
    "register_actions",
]

ACTION_DEFINITIONS: dict[str, str] = {
    "nav2_msgs/action/NavigateToPose": (
        "geometry_msgs/PoseStamped pose\nstring behavior_tree\n"
        "---\nstd_msgs/Empty result\n"
        "---\ngeometry_msgs/PoseStamped current_pose\n"
        "builtin_interfaces/Duration navigation_time\n"
        "builtin_interfaces/Duration estimated_time_remaining\n"
        "int16 number_of_recoveries\nfloat32 distance_remaining\n"
    ),
    "move_base_msgs/action/MoveBase": (
        "geometry_msgs/PoseStamped target_pose\n---\n---\ngeometry_msgs/PoseStamped base_position\n"
    ),
    "example_interfaces/action/Fibonacci": (
        "int32 order\n---\nint32[] sequence\n---\nint32[] sequence\n"
    ),
}
"""Action type name -> ``.action`` text (Humble's NavigateToPose; ROS 1's MoveBase)."""

_EMPTY = "uint8 structure_needs_at_least_one_member\n"
_UUID = "unique_identifier_msgs/UUID"


def _action_parts(name: str, text: str) -> dict[str, str]:
    """``short name -> .msg text`` of every message an action derives (references 2-part)."""
    parts = text.split("---")
    if len(parts) != 3:
        msg = f"action definition of {name} has {len(parts) - 1} '---' lines, expected 2"
        raise UnknownMessageTypeError(msg)
    pkg, _, short = name.split("/")
    goal, result, feedback = (p if p.strip() else _EMPTY for p in parts)
    ref = f"{pkg}/{short}"
    out = {
        f"{short}_Goal": goal,
        f"{short}_Result": result,
        f"{short}_Feedback": feedback,
        f"{short}_FeedbackMessage": f"{_UUID} goal_id\n{ref}_Feedback feedback\n",
        f"{short}_SendGoal_Request": f"{_UUID} goal_id\n{ref}_Goal goal\n",
        f"{short}_SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp\n",
        f"{short}_GetResult_Request": f"{_UUID} goal_id\n",
        f"{short}_GetResult_Response": f"int8 status\n{ref}_Result result\n",
    }
    for srv in ("SendGoal", "GetResult"):
        base = f"{ref}_{srv}"
        out[f"{short}_{srv}_Event"] = (
            f"service_msgs/ServiceEventInfo info\n{base}_Request[<=1] request\n"
            f"{base}_Response[<=1] response\n"
        )
        out[f"{short}_{srv}"] = (
            f"{base}_Request request_message\n{base}_Response response_message\n"
            f"{base}_Event event_message\n"
        )
    out[short] = (
        f"{ref}_Goal goal\n{ref}_Result result\n{ref}_Feedback feedback\n"
        f"{ref}_SendGoal send_goal_service\n{ref}_GetResult get_result_service\n"
        f"{ref}_FeedbackMessage feedback_message\n"
    )
    return out


def _move_to_action(types: dict[str, Any], names: set[str]) -> dict[str, Any]:
    """Rename ``pkg/msg/X`` (as rosbags parsed them) to ``pkg/action/X`` for X in ``names``."""
    table = {n.replace("/action/", "/msg/", 1): n for n in names}

    def fix(desc: Any) -> Any:
        if isinstance(desc, tuple):
            return tuple(fix(d) for d in desc)
        if isinstance(desc, str):
            return table.get(desc, desc)
        return desc

    return {
        table.get(k, k): (consts, [(f, fix(d)) for f, d in fields])
        for k, (consts, fields) in types.items()
    }


def register_actions(store: Typestore) -> None:
    """Add :data:`ACTION_DEFINITIONS` and their derived types to ``store`` (idempotent)."""
    types: dict[str, Any] = {}
    names: set[str] = set()
    for name, text in ACTION_DEFINITIONS.items():
        if f"{name}_Goal" in store.fielddefs:
            continue
        pkg = name.split("/")[0]
        for short, msg_text in _action_parts(name, text).items():
            types.update(get_types_from_msg(msg_text, f"{pkg}/msg/{short}"))
            names.add(f"{pkg}/action/{short}")
    if types:
        store.register(_move_to_action(types, names))


@dataclasses.dataclass(frozen=True)
class ActionType:
    """An action type: its name and its message classes (rclpy's generated action class).

    Attributes:
        name: e.g. ``nav2_msgs/action/NavigateToPose``.
        Goal: the goal message class (``..._Goal``).
        Result: the result message class.
        Feedback: the feedback message class.
        FeedbackMessage: goal id + feedback (what the ``feedback`` topic carries).
    """

    name: str
    Goal: type[Any]
    Result: type[Any]
    Feedback: type[Any]
    FeedbackMessage: type[Any]

    @property
    def send_goal_service(self) -> str:
        """``pkg/action/Name_SendGoal`` (a service type name)."""
        return f"{self.name}_SendGoal"

    @property
    def get_result_service(self) -> str:
        """``pkg/action/Name_GetResult`` (a service type name)."""
        return f"{self.name}_GetResult"

    @property
    def feedback_message_type(self) -> str:
        """``pkg/action/Name_FeedbackMessage``."""
        return f"{self.name}_FeedbackMessage"

    def __repr__(self) -> str:
        return f"ActionType({self.name!r})"


def action_type_names() -> list[str]:
    """Every action type the store knows, sorted (``pkg/action/Name``)."""
    from visnav.msgs.serde import typestore  # noqa: PLC0415 - serde imports this module

    defs = typestore().fielddefs
    return sorted(k for k in defs if "/action/" in k and f"{k}_SendGoal_Request" in defs)


@functools.cache
def _lookup(name: str) -> ActionType:
    from visnav.msgs.serde import typestore  # noqa: PLC0415 - serde imports this module

    types = typestore().types
    return ActionType(
        name,
        types[f"{name}_Goal"],
        types[f"{name}_Result"],
        types[f"{name}_Feedback"],
        types[f"{name}_FeedbackMessage"],
    )


def get_action_type(type_name: str | ActionType) -> ActionType:
    """Look an action type up by name.

    Args:
        type_name: ``pkg/action/Name`` (or the ROS 1 spelling ``pkg/Name``, or ROS 1's
            ``pkg/NameAction``), or an :class:`ActionType` (returned as it is).

    Returns:
        The action type with its ``Goal``, ``Result`` and ``Feedback`` classes.

    Raises:
        UnknownMessageTypeError: no such action; the message suggests close names.
    """
    if isinstance(type_name, ActionType):
        return type_name
    name = str(type_name).strip()
    parts = name.split("/")
    if len(parts) == 2:
        short = parts[1].removesuffix("Action") if parts[1] != "Action" else parts[1]
        name = f"{parts[0]}/action/{short}"
    known = action_type_names()
    if name not in known:
        close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        msg = (
            f"unknown action type {type_name!r}: expected a name like "
            f"'nav2_msgs/action/NavigateToPose'{hint} (known: {', '.join(known)})"
        )
        raise UnknownMessageTypeError(msg)
    return _lookup(name)
