"""A visnav action offered to ROS 1 as an actionlib server (``<name>/goal``, ``cancel``, ...).

ROS 1's actionlib is five topics under the action's name: the client publishes
``goal`` (``pkg/NameActionGoal``) and ``cancel`` (``actionlib_msgs/GoalID``); the server
publishes ``status`` (``actionlib_msgs/GoalStatusArray``, 5 Hz), ``feedback`` and
``result``. For each visnav action server (a ``<name>/_action/send_goal`` service of type
``pkg/action/Name_SendGoal``) the bridge is that ROS 1 server: a goal becomes a visnav
``send_goal`` with a goal id of its own (the ROS 1 id is kept for the replies), feedback and
the result go out with the ROS 1 id, and a cancel becomes ``cancel_goal``. Status codes:

=================  ========================================================
visnav (ROS 2)     actionlib
=================  ========================================================
(sent, no answer)  PENDING 0
ACCEPTED           PENDING 0
EXECUTING          ACTIVE 1
CANCELING          PREEMPTING 6 (RECALLING 7 before it executed)
SUCCEEDED          SUCCEEDED 3
CANCELED           PREEMPTED 2 (RECALLED 8 before it executed)
ABORTED            ABORTED 4
(rejected)         REJECTED 5
=================  ========================================================

A finished goal stays in ``status`` for 5 s (actionlib's ``status_list_timeout``).
"""

from __future__ import annotations

import threading
import time
import uuid
from dataclasses import dataclass
from typing import Any

from visnav.bridge.actionlib_types import ActionlibTypes, actionlib_types
from visnav.bridge.errors import BridgeError, TcprosError, UnconvertibleTypeError
from visnav.bridge.ros1_node import Ros1Node
from visnav.bridge.srvmap import ROS2_ONLY_PACKAGES
from visnav.graph import Node
from visnav.graph.action_client import ActionClient, ClientGoalHandle
from visnav.graph.action_types import ACTION_INFIX, GoalStatus, goal_id_from_bytes
from visnav.msgs.time import ns_to_time, time_to_ns

__all__ = ["PENDING", "ActionlibBridge", "ActionlibServer", "ros1_status"]

PENDING, ACTIVE, PREEMPTED, SUCCEEDED, ABORTED, REJECTED = 0, 1, 2, 3, 4, 5
PREEMPTING, RECALLING, RECALLED = 6, 7, 8
ROLES = ("goal", "cancel", "status", "feedback", "result")
"""actionlib's five topics under an action's name."""
STATUS_PERIOD_S = 0.2
"""``status`` is published at 5 Hz (actionlib's ``status_frequency``)."""
KEEP_FINISHED_S = 5.0
"""A finished goal stays in ``status`` this long (actionlib's ``status_list_timeout``)."""
_SUFFIX = "_SendGoal"


def ros1_status(status: int, *, executed: bool) -> int:
    """The actionlib status code of a visnav goal status (see the module's table)."""
    if status == GoalStatus.STATUS_EXECUTING:
        return ACTIVE
    if status == GoalStatus.STATUS_CANCELING:
        return PREEMPTING if executed else RECALLING
    if status == GoalStatus.STATUS_SUCCEEDED:
        return SUCCEEDED
    if status == GoalStatus.STATUS_CANCELED:
        return PREEMPTED if executed else RECALLED
    if status == GoalStatus.STATUS_ABORTED:
        return ABORTED
    return PENDING


@dataclass
class _Goal:
    ros1_id: Any  # actionlib_msgs/GoalID of the ActionlibTypes store
    uuid: Any
    status: int = PENDING
    executed: bool = False
    handle: ClientGoalHandle | None = None
    cancel_asked: bool = False
    finished_at: float | None = None
    text: str = ""


class ActionlibServer:
    """One visnav action offered to ROS 1 under ``name`` (see the module).

    Args:
        node: the bridge's visnav node (its executor runs the replies).
        ros1: the bridge's ROS 1 node.
        name: the action's name, e.g. ``/move_base``.
        types: its actionlib types.
    """

    def __init__(self, node: Node, ros1: Ros1Node, name: str, types: ActionlibTypes) -> None:
        self.node = node
        self.ros1 = ros1
        self.name = name
        self.types = types
        self.client = ActionClient(node, types.action.name, name)
        self._lock = threading.Lock()
        self._goals: dict[str, _Goal] = {}
        self._seq = {"status": 0, "feedback": 0, "result": 0}
        self.goals_received = 0
        self.bad_messages = 0
        ros1.advertise(self.topic("status"), types.status)
        ros1.advertise(self.topic("feedback"), types.feedback)
        ros1.advertise(self.topic("result"), types.result)
        ros1.subscribe(self.topic("goal"), types.goal, self._on_goal)
        ros1.subscribe(self.topic("cancel"), types.cancel, self._on_cancel)
        self._timer = node.create_timer(STATUS_PERIOD_S, self.publish_status)

    def topic(self, role: str) -> str:
        """``<name>/<role>``."""
        return f"{self.name.rstrip('/')}/{role}"

    def _now(self) -> Any:
        return ns_to_time(time.time_ns())

    def _publish(self, role: str, payload: bytes) -> None:
        with self._lock:
            self._seq[role] += 1
            seq = self._seq[role]
        self.ros1.publish(self.topic(role), payload, seq=seq)

    def _bad(self, what: str, exc: Exception) -> None:
        self.bad_messages += 1
        if self.bad_messages == 1:
            self.node.get_logger().warning(
                f"actionlib {self.name}: dropped a {what}: {exc} (further ones are only counted)"
            )

    # ------------------------------------------------------------------ ROS 1 -> visnav
    def _on_goal(self, raw: bytearray) -> None:
        """A ROS 1 goal (on its TCPROS thread): send it to the visnav action."""
        try:
            ros1_id, goal = self.types.decode_goal(bytes(raw))
        except TcprosError as exc:
            self._bad("goal", exc)
            return
        if not ros1_id.id:  # actionlib's server names goals that come without an id
            ros1_id = self.types.goal_id(ros1_id.stamp, f"{self.ros1.name}-{uuid.uuid4().hex}")
        if time_to_ns(ros1_id.stamp) == 0:
            ros1_id = self.types.goal_id(self._now(), ros1_id.id)
        record = _Goal(ros1_id, goal_id_from_bytes(uuid.uuid4().bytes))
        with self._lock:
            self._goals[ros1_id.id] = record
            self.goals_received += 1
        future = self.client.send_goal_async(
            goal, feedback_callback=lambda fb: self._on_feedback(record, fb), goal_uuid=record.uuid
        )
        future.add_done_callback(lambda f: self._on_answer(record, f))

    def _on_answer(self, record: _Goal, future: Any) -> None:
        exc = future.exception()
        if exc is not None:
            self._finish(record, REJECTED, None, f"the visnav action did not take it: {exc}")
            return
        handle: ClientGoalHandle = future.result()
        if not handle.accepted:
            self._finish(record, REJECTED, None, "rejected by the visnav action server")
            return
        with self._lock:
            record.handle = handle
            cancel = record.cancel_asked
        if cancel:
            handle.cancel_goal_async()
        handle.get_result_async().add_done_callback(lambda f: self._on_result(record, f))
        self.publish_status()

    def _on_feedback(self, record: _Goal, message: Any) -> None:
        record.executed = True
        status = self.types.goal_status(record.ros1_id, self._status_of(record))
        try:
            payload = self.types.encode_feedback(
                self.types.header(self._now()), status, message.feedback
            )
        except Exception as exc:  # noqa: BLE001 - one bad feedback must not stop the goal
            self._bad("feedback", exc)
            return
        self._publish("feedback", payload)

    def _on_result(self, record: _Goal, future: Any) -> None:
        exc = future.exception()
        if exc is not None:
            self._finish(record, ABORTED, None, f"no result from the visnav action: {exc}")
            return
        response = future.result()
        executed = record.executed or int(response.status) != GoalStatus.STATUS_CANCELED
        code = ros1_status(int(response.status), executed=executed)
        if code == PENDING:  # STATUS_UNKNOWN: the server forgot it
            code = ABORTED
        self._finish(record, code, response.result, "")

    def _finish(self, record: _Goal, code: int, result: Any, text: str) -> None:
        with self._lock:
            record.status = code
            record.text = text
            record.finished_at = time.monotonic()
        status = self.types.goal_status(record.ros1_id, code, text)
        try:
            payload = self.types.encode_result(self.types.header(self._now()), status, result)
        except Exception as exc:  # noqa: BLE001 - the client still gets the status
            self._bad("result", exc)
            payload = self.types.encode_result(self.types.header(self._now()), status, None)
        self._publish("result", payload)
        self.publish_status()

    def _on_cancel(self, raw: bytearray) -> None:
        """A ROS 1 cancel (actionlib's rules: an id, a stamp, or both empty: every goal)."""
        try:
            msg = self.types.decode_cancel(bytes(raw))
        except TcprosError as exc:
            self._bad("cancel", exc)
            return
        stamp_ns = time_to_ns(msg.stamp)
        with self._lock:
            chosen = [
                g
                for g in self._goals.values()
                if g.finished_at is None
                and (
                    (not msg.id and stamp_ns == 0)
                    or g.ros1_id.id == msg.id
                    or (stamp_ns and time_to_ns(g.ros1_id.stamp) <= stamp_ns)
                )
            ]
            for g in chosen:
                g.cancel_asked = True
        for g in chosen:
            if g.handle is not None:
                g.handle.cancel_goal_async()

    # ------------------------------------------------------------------ status
    def _status_of(self, record: _Goal) -> int:
        if record.finished_at is not None:
            return record.status
        code = PENDING
        handle = record.handle
        if handle is not None:
            if int(handle.status) == GoalStatus.STATUS_EXECUTING:
                record.executed = True
            code = ros1_status(int(handle.status), executed=record.executed)
            if code in (SUCCEEDED, PREEMPTED, RECALLED, ABORTED):
                code = ACTIVE  # ended in visnav: the result is on its way
        if code == PENDING and record.executed:  # feedback came before the acceptance
            code = ACTIVE
        if record.cancel_asked and code in (PENDING, ACTIVE):
            return PREEMPTING if record.executed else RECALLING
        return code

    def publish_status(self) -> None:
        """Publish the ``status`` list (the 5 Hz timer, and at once on each change)."""
        now = time.monotonic()
        with self._lock:
            for key in [
                k
                for k, g in self._goals.items()
                if g.finished_at is not None and now - g.finished_at > KEEP_FINISHED_S
            ]:
                del self._goals[key]
            goals = list(self._goals.values())
        statuses = [self.types.goal_status(g.ros1_id, self._status_of(g), g.text) for g in goals]
        self._publish("status", self.types.encode_status(self.types.header(self._now()), statuses))

    def close(self) -> None:
        """Leave ROS 1 (the five topics) and destroy the visnav client."""
        self._timer.cancel()
        for role in ("status", "feedback", "result"):
            self.ros1.unadvertise(self.topic(role))
        for role in ("goal", "cancel"):
            self.ros1.unsubscribe(self.topic(role))
        self.client.destroy()


class ActionlibBridge:
    """Offers every selected visnav action to ROS 1 as an actionlib server.

    Args:
        node: the bridge's visnav node.
        ros1: the bridge's ROS 1 node.
        selected: ``selected(action_name) -> bool`` (``--actions`` / ``--exclude``).
        release: ``release(topics)``, called before an action takes its five ROS 1 topics:
            the topic bridge stops bridging them (a visnav ``/move_base/status`` of the
            navigator's own would otherwise reach ROS 1 beside actionlib's, and rospy's
            client would take its goal for lost).
    """

    def __init__(self, node: Node, ros1: Ros1Node, *, selected: Any, release: Any = None) -> None:
        self.node = node
        self.ros1 = ros1
        self.selected = selected
        self.release = release
        self._fqn = node.get_fully_qualified_name()
        self._servers: dict[str, ActionlibServer] = {}
        self._refused: set[tuple[str, str]] = set()

    def actions(self) -> list[str]:
        """Names of the actions offered to ROS 1."""
        return sorted(self._servers)

    def owned_topics(self) -> set[str]:
        """The ROS 1 topics the offered actions use (no topic bridging on them)."""
        return {s.topic(r) for s in self._servers.values() for r in ROLES}

    def server(self, name: str) -> ActionlibServer:
        """The actionlib server of an action."""
        return self._servers[name]

    def scan(self) -> None:
        """Offer new visnav actions, withdraw gone ones.

        Raises:
            BridgeError: the master failed (the caller logs it once and retries).
        """
        found: dict[str, str] = {}
        suffix = f"{ACTION_INFIX}send_goal"
        for e in self.node.context.graph.service_endpoints():
            if e.kind != "service_server" or e.node_fqn == self._fqn:
                continue
            if not e.topic.endswith(suffix) or not e.type_name.endswith(_SUFFIX):
                continue
            name = e.topic[: -len(suffix)] or "/"
            if self.selected(name):
                found[name] = e.type_name[: -len(_SUFFIX)]
        for name in list(self._servers):
            if name not in found:
                self._servers.pop(name).close()
                self.node.get_logger().info(f"visnav -> ROS 1: action {name} gone")
        for name, type_name in sorted(found.items()):
            if name in self._servers:
                continue
            try:
                types = actionlib_types(type_name)
            except UnconvertibleTypeError as exc:
                if (name, type_name) not in self._refused:
                    self._refused.add((name, type_name))
                    text = f"not bridging action {name}: {exc}"
                    if type_name.partition("/")[0] in ROS2_ONLY_PACKAGES:  # nav2's: no ROS 1
                        self.node.get_logger().debug(text)
                    else:
                        self.node.get_logger().warning(text)
                continue
            if self.release is not None:
                self.release([f"{name.rstrip('/')}/{role}" for role in ROLES])
            try:
                self._servers[name] = ActionlibServer(self.node, self.ros1, name, types)
            except BridgeError:
                for role in ("status", "feedback", "result"):
                    self.ros1.unadvertise(f"{name.rstrip('/')}/{role}")
                raise
            self.node.get_logger().info(
                f"visnav -> ROS 1: action {name} [{types.goal.ros1_name.removesuffix('Goal')}] "
                "as actionlib topics"
            )

    def close(self) -> None:
        """Withdraw every action."""
        for name in list(self._servers):
            self._servers.pop(name).close()
