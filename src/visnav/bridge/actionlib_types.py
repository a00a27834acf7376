"""ROS 1 actionlib message types of a visnav action, and their bytes.

ROS 1's actionlib carries an action ``pkg/Name`` on five topics; three of their types are
made from the action's goal, result and feedback (genaction's rule)::

    pkg/NameActionGoal      Header header, actionlib_msgs/GoalID goal_id, pkg/NameGoal goal
    pkg/NameActionResult    Header header, actionlib_msgs/GoalStatus status, pkg/NameResult result
    pkg/NameActionFeedback  Header header, actionlib_msgs/GoalStatus status,
                            pkg/NameFeedback feedback

:func:`actionlib_types` builds them from visnav's ``pkg/action/Name_Goal`` (etc.) in a type
store of their own (visnav's store is not changed), with ROS 1's definitions and MD5 sums
(``move_base_msgs/MoveBaseActionGoal`` equals Debian's ``python3-move-base-msgs``, tested).
ROS 2's ``structure_needs_at_least_one_member`` (an empty result) is no byte in ROS 1.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from visnav.bag.typeconv import HEADER, noetic_store
from visnav.bridge.errors import TcprosError, UnconvertibleTypeError
from visnav.bridge.srvmap import ROS2_ONLY_PACKAGES
from visnav.bridge.typemap import Ros1Type, ros1_type
from visnav.msgs.action import ActionType, get_action_type
from visnav.msgs.construct import default_message
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import deserialize, serialize, typestore

__all__ = ["ActionlibTypes", "actionlib_types"]

_PLACEHOLDER = "structure_needs_at_least_one_member"
_DECODE_ERRORS = (MessageError, ValueError, IndexError, KeyError, TypeError, AttributeError)


def _fields(name: str) -> list[tuple[str, Any]]:
    return [f for f in typestore().fielddefs[name][1] if f[0] != _PLACEHOLDER]


def _check(action: str, name: str) -> None:
    for field, (kind, args) in _fields(name):
        sub = args if kind == Nodetype.NAME else (args[0][1] if kind != Nodetype.BASE else None)
        if not isinstance(sub, str) or sub.startswith("builtin_interfaces/"):
            continue
        try:
            ros1_type(sub)
        except UnconvertibleTypeError as exc:
            msg = f"action type {action}: field {field!r} of {name} cannot cross to ROS 1: {exc}"
            raise UnconvertibleTypeError(msg) from exc


@dataclass(frozen=True)
class ActionlibTypes:
    """The actionlib types of one visnav action, and the store that converts them.

    Attributes:
        action: the visnav action type.
        goal: ``pkg/NameActionGoal`` (the ``goal`` topic).
        result: ``pkg/NameActionResult`` (``result``).
        feedback: ``pkg/NameActionFeedback`` (``feedback``).
        cancel: ``actionlib_msgs/GoalID`` (``cancel``).
        status: ``actionlib_msgs/GoalStatusArray`` (``status``).
        store: visnav's types plus the ones above (Humble's Header; converted to ROS 1's
            by rosbags' byte converters).
    """

    action: ActionType
    goal: Ros1Type
    result: Ros1Type
    feedback: Ros1Type
    cancel: Ros1Type
    status: Ros1Type
    store: Typestore

    def _to_ros1(self, msg: Any, rtype: Ros1Type) -> bytes:
        cdr = self.store.serialize_cdr(msg, rtype.ros2_name)
        return bytes(self.store.cdr_to_ros1(cdr, rtype.ros2_name))

    def _from_ros1(self, data: bytes, rtype: Ros1Type) -> Any:
        try:
            cdr = self.store.ros1_to_cdr(memoryview(data), rtype.ros2_name)
            return self.store.deserialize_cdr(cdr, rtype.ros2_name)
        except _DECODE_ERRORS as exc:
            msg = f"{len(data)} bytes do not decode as ROS 1 {rtype.ros1_name}: {exc}"
            raise TcprosError(msg) from exc
        except Exception as exc:  # rosbags' SerdeError and struct.error
            msg = f"{len(data)} bytes do not decode as ROS 1 {rtype.ros1_name}: {exc}"
            raise TcprosError(msg) from exc

    def decode_goal(self, data: bytes) -> tuple[Any, Any]:
        """ROS 1 ``NameActionGoal`` bytes -> ``(GoalID, visnav Goal)``.

        Raises:
            TcprosError: the bytes do not decode (names the type).
        """
        msg = self._from_ros1(data, self.goal)
        goal_type = f"{self.action.name}_Goal"
        if not _fields(goal_type):
            return msg.goal_id, default_message(goal_type)
        cdr = self.store.serialize_cdr(msg.goal, _short(self.goal.ros2_name, "Goal"))
        try:
            return msg.goal_id, deserialize(cdr, goal_type)
        except MessageError as exc:  # pragma: no cover - same layout in both stores
            text = f"the goal of a ROS 1 {self.goal.ros1_name} does not convert: {exc}"
            raise TcprosError(text) from exc

    def decode_cancel(self, data: bytes) -> Any:
        """ROS 1 ``actionlib_msgs/GoalID`` bytes -> a GoalID (``.stamp``, ``.id``)."""
        return self._from_ros1(data, self.cancel)

    def goal_id(self, stamp: Any, goal_id: str) -> Any:
        """An ``actionlib_msgs/GoalID`` of this store."""
        return self.store.types["actionlib_msgs/msg/GoalID"](stamp=stamp, id=goal_id)

    def goal_status(self, goal_id: Any, status: int, text: str = "") -> Any:
        """An ``actionlib_msgs/GoalStatus`` of this store."""
        cls = self.store.types["actionlib_msgs/msg/GoalStatus"]
        return cls(goal_id=goal_id, status=status, text=text)

    def header(self, stamp: Any, frame_id: str = "") -> Any:
        """A ``std_msgs/Header`` of this store."""
        return self.store.types[HEADER](stamp=stamp, frame_id=frame_id)

    def encode_status(self, header: Any, statuses: list[Any]) -> bytes:
        """A ``GoalStatusArray`` as ROS 1 bytes."""
        cls = self.store.types["actionlib_msgs/msg/GoalStatusArray"]
        return self._to_ros1(cls(header=header, status_list=statuses), self.status)

    def encode_feedback(self, header: Any, status: Any, feedback: Any) -> bytes:
        """``NameActionFeedback`` bytes from a visnav ``Name_Feedback``."""
        cls = self.store.types[self.feedback.ros2_name]
        inner = self._inner(feedback, "Feedback")
        return self._to_ros1(cls(header=header, status=status, feedback=inner), self.feedback)

    def encode_result(self, header: Any, status: Any, result: Any) -> bytes:
        """``NameActionResult`` bytes from a visnav ``Name_Result`` (None: a default one)."""
        cls = self.store.types[self.result.ros2_name]
        inner = self._inner(result, "Result")
        return self._to_ros1(cls(header=header, status=status, result=inner), self.result)

    def _inner(self, msg: Any, part: str) -> Any:
        """A visnav Goal/Result/Feedback as this store's ``pkg/msg/NamePart``."""
        name = _short(self.goal.ros2_name, part)
        visnav_type = f"{self.action.name}_{part}"
        if not _fields(visnav_type):
            return self.store.types[name]()  # ROS 1's empty message
        if msg is None:
            msg = default_message(visnav_type)
        return self.store.deserialize_cdr(serialize(msg), name)


def _short(goal_type: str, part: str) -> str:
    """``pkg/msg/NameActionGoal`` -> ``pkg/msg/NameGoal`` (``part``)."""
    return goal_type.removesuffix("ActionGoal") + part


@functools.cache
def actionlib_types(action_name: str) -> ActionlibTypes:
    """The actionlib types of a visnav action type.

    Args:
        action_name: ``pkg/action/Name`` (or ``pkg/Name``).

    Raises:
        UnconvertibleTypeError: not a known action type, a ROS 2-only package, or a field of
            the goal, result or feedback has no ROS 1 counterpart.
    """
    try:
        action = get_action_type(action_name)
    except MessageError as exc:
        msg = f"{action_name} is not an action type visnav knows: {exc}"
        raise UnconvertibleTypeError(msg) from exc
    pkg, _, short = action.name.split("/")
    if pkg in ROS2_ONLY_PACKAGES:
        msg = f"action type {action.name} exists only in ROS 2 (ROS 1 has no {pkg})"
        raise UnconvertibleTypeError(msg)
    for part in ("Goal", "Result", "Feedback"):
        _check(action.name, f"{action.name}_{part}")
    base = f"{pkg}/msg/{short}"
    goal_id = (Nodetype.NAME, "actionlib_msgs/msg/GoalID")
    status = (Nodetype.NAME, "actionlib_msgs/msg/GoalStatus")
    header = ("header", (Nodetype.NAME, HEADER))
    own: dict[str, Any] = {
        f"{base}{p}": (
            list(typestore().fielddefs[f"{action.name}_{p}"][0]),
            _fields(f"{action.name}_{p}"),
        )
        for p in ("Goal", "Result", "Feedback")
    }
    own[f"{base}ActionGoal"] = (
        [],
        [header, ("goal_id", goal_id), ("goal", (Nodetype.NAME, f"{base}Goal"))],
    )
    own[f"{base}ActionResult"] = (
        [],
        [header, ("status", status), ("result", (Nodetype.NAME, f"{base}Result"))],
    )
    own[f"{base}ActionFeedback"] = (
        [],
        [header, ("status", status), ("feedback", (Nodetype.NAME, f"{base}Feedback"))],
    )
    store = get_typestore(Stores.EMPTY)
    store.register({**typestore().fielddefs, **own})
    md5_store = get_typestore(Stores.EMPTY)
    md5_store.register({**typestore().fielddefs, **own, HEADER: noetic_store().fielddefs[HEADER]})

    def rtype(name: str) -> Ros1Type:
        definition, md5 = md5_store.generate_msgdef(name, ros_version=1)
        return Ros1Type(name, f"{pkg}/{name.rsplit('/', 1)[1]}", md5, definition, header_first=True)

    return ActionlibTypes(
        action=action,
        goal=rtype(f"{base}ActionGoal"),
        result=rtype(f"{base}ActionResult"),
        feedback=rtype(f"{base}ActionFeedback"),
        cancel=ros1_type("actionlib_msgs/msg/GoalID"),
        status=ros1_type("actionlib_msgs/msg/GoalStatusArray"),
        store=store,
    )
