r"""Action servers (rclpy's ``ActionServer`` and ``ServerGoalHandle``).

A goal's life, as ROS 2's action design has it::

    send_goal --goal_callback--> rejected (no handle)
                             \\-> ACCEPTED --execute()--> EXECUTING --succeed()--> SUCCEEDED
                                    |                        |  \\----abort()-----> ABORTED
                                    \\--cancel request--> CANCELING --canceled()--> CANCELED
                                       (cancel_callback ACCEPT)    (or succeed() / abort())

* ``goal_callback(goal) -> GoalResponse`` (default: accept) and
  ``cancel_callback(goal_handle) -> CancelResponse`` (default: reject, as rclpy) run in
  the executor, as service callbacks; an exception in either answers the client with
  an error (its future fails) and is logged at the node's fault boundary.
* ``handle_accepted_callback(goal_handle)`` (default: ``goal_handle.execute()``) runs
  in the executor right after the acceptance was answered.
* ``execute_callback(goal_handle) -> Result`` runs on **a thread of its own per goal**
  (rclpy runs it in the executor, where a blocking callback stalls the node unless a
  MultiThreadedExecutor and a reentrant group are used): it may sleep, loop, publish
  feedback and poll ``is_cancel_requested``. It must end the goal with ``succeed()``,
  ``abort()`` or ``canceled()``; one that returns without doing so aborts the goal (a
  warning says so), and one that raises aborts it with a default result (the error is
  logged with node, action and goal id) so no client waits forever.
* The result is answered to every ``get_result`` request of the goal (those that came
  before the end wait for it) and kept ``result_timeout`` seconds after the end (rclpy's
  default 900 s); then the goal leaves the status list and a late ``get_result`` gets
  ``STATUS_UNKNOWN``.
* ``goal_handle.canceled()`` from EXECUTING (not allowed by rclpy, which needs a cancel
  request first) passes through CANCELING: a server may end a goal itself, as
  move_base does when a newer goal preempts the running one.
"""

from __future__ import annotations

import functools
import threading
import traceback
import weakref
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from visnav.graph.action_types import (
    TERMINAL,
    ActionError,
    CancelResponse,
    GoalResponse,
    GoalStatus,
    action_names,
    goal_id_hex,
    goal_key,
    qos_profile_action_status_default,
)
from visnav.graph.qos import QoSProfile, qos_profile_services_default, to_qos
from visnav.graph.service import Service, _Request
from visnav.msgs.action import ActionType, get_action_type
from visnav.msgs.construct import default_message, make
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time, time_to_ns

if TYPE_CHECKING:
    from visnav.graph.node import Node

__all__ = ["ActionServer", "ServerGoalHandle"]

_NS = 1_000_000_000

# Allowed transitions (rcl_action's goal state machine), event -> {from: to}.
_EXECUTE = {GoalStatus.STATUS_ACCEPTED: GoalStatus.STATUS_EXECUTING}
_CANCEL = {
    GoalStatus.STATUS_ACCEPTED: GoalStatus.STATUS_CANCELING,
    GoalStatus.STATUS_EXECUTING: GoalStatus.STATUS_CANCELING,
}
_SUCCEED = {
    GoalStatus.STATUS_EXECUTING: GoalStatus.STATUS_SUCCEEDED,
    GoalStatus.STATUS_CANCELING: GoalStatus.STATUS_SUCCEEDED,
}
_ABORT = {
    GoalStatus.STATUS_ACCEPTED: GoalStatus.STATUS_ABORTED,
    GoalStatus.STATUS_EXECUTING: GoalStatus.STATUS_ABORTED,
    GoalStatus.STATUS_CANCELING: GoalStatus.STATUS_ABORTED,
}
_CANCELED = {GoalStatus.STATUS_CANCELING: GoalStatus.STATUS_CANCELED}


class _ActionService(Service[Any, Any]):
    """A service whose handler answers when it is ready: ``handler(request, item)``."""

    def _serve(self, item: _Request) -> None:
        request = self._read_request(item)
        if request is None:
            return
        try:
            self.callback(request, item)
        except Exception as exc:
            item.fail(f"{self.describe()} raised {type(exc).__name__}: {exc}")
            raise


class ServerGoalHandle:
    """One accepted goal on the server side (rclpy's ``ServerGoalHandle``).

    Attributes:
        goal_id: the ``unique_identifier_msgs/msg/UUID`` the client chose.
        request: the goal message.
        stamp_ns: when the server accepted the goal (the node's clock).
    """

    def __init__(self, server: ActionServer, goal_id: Any, request: Any, stamp_ns: int) -> None:
        self._server = server
        self.goal_id = goal_id
        self.request = request
        self.stamp_ns = stamp_ns
        self._status = GoalStatus.STATUS_ACCEPTED
        self._cancel_requested = False

    @property
    def status(self) -> int:
        """The goal's ``action_msgs/msg/GoalStatus`` code."""
        return int(self._status)

    @property
    def is_active(self) -> bool:
        """ACCEPTED, EXECUTING or CANCELING."""
        return self._status not in TERMINAL

    @property
    def is_executing(self) -> bool:
        """EXECUTING (rclpy's name)."""
        return self._status is GoalStatus.STATUS_EXECUTING

    @property
    def is_cancel_requested(self) -> bool:
        """Whether a cancel request was accepted for this goal (it is CANCELING)."""
        return self._status is GoalStatus.STATUS_CANCELING

    def describe(self) -> str:
        """``goal <hex id> of action '/name'`` (for logs)."""
        return f"goal {goal_id_hex(self.goal_id)} of action '{self._server.action_name}'"

    def _transition(self, table: dict[GoalStatus, GoalStatus], event: str) -> None:
        with self._server.lock:
            new = table.get(self._status)
            if new is None:
                msg = (
                    f"{self.describe()}: cannot {event} a goal that is "
                    f"{self._status.name.removeprefix('STATUS_')}"
                )
                raise ActionError(msg)
            self._status = new
        self._server.publish_status()

    def execute(self, execute_callback: Callable[[ServerGoalHandle], Any] | None = None) -> None:
        """Start executing: EXECUTING, then the execute callback on its own thread."""
        self._transition(_EXECUTE, "execute")
        self._server.start_execute(self, execute_callback)

    def publish_feedback(self, feedback: Any) -> None:
        """Publish ``feedback`` (the action's ``Feedback`` message) for this goal."""
        self._server.publish_feedback(self, feedback)

    def succeed(self) -> None:
        """End the goal as SUCCEEDED (the execute callback's return value is its result)."""
        self._transition(_SUCCEED, "succeed")

    def abort(self) -> None:
        """End the goal as ABORTED."""
        self._transition(_ABORT, "abort")

    def canceled(self) -> None:
        """End the goal as CANCELED (from CANCELING; from EXECUTING through CANCELING)."""
        with self._server.lock:
            if self._status is GoalStatus.STATUS_EXECUTING:
                self._status = GoalStatus.STATUS_CANCELING
        self._transition(_CANCELED, "cancel")

    def request_cancel(self) -> bool:
        """Move an active goal to CANCELING (what an accepted cancel request does)."""
        with self._server.lock:
            new = _CANCEL.get(self._status)
            if new is None:
                return self._status is GoalStatus.STATUS_CANCELING
            self._status = new
        self._server.publish_status()
        return True

    def __repr__(self) -> str:
        return f"<ServerGoalHandle {goal_id_hex(self.goal_id)} {self._status.name}>"


def _accept_all(_goal: Any) -> GoalResponse:
    return GoalResponse.ACCEPT


def _reject_cancel(_handle: ServerGoalHandle) -> CancelResponse:
    return CancelResponse.REJECT


def _execute_now(handle: ServerGoalHandle) -> None:
    handle.execute()


class ActionServer:
    """Serves one action (rclpy's ``ActionServer`` signature).

    Args:
        node: the node the action's services and topics belong to.
        action_type: an :class:`~visnav.msgs.action.ActionType` or its name
            (``"nav2_msgs/action/NavigateToPose"``).
        action_name: the action's name (expanded and remapped as a topic name).
        execute_callback: ``execute_callback(goal_handle) -> Result`` (own thread).
        goal_callback: ``goal_callback(goal) -> GoalResponse`` (default: accept).
        handle_accepted_callback: ``(goal_handle) -> None`` (default: execute it).
        cancel_callback: ``cancel_callback(goal_handle) -> CancelResponse``
            (default: reject).
        goal_service_qos_profile: QoS of the send_goal service (its queue depth).
        result_service_qos_profile: QoS of the get_result service.
        cancel_service_qos_profile: QoS of the cancel_goal service.
        feedback_pub_qos_profile: QoS of the feedback topic (default depth 10).
        status_pub_qos_profile: QoS of the status topic (default transient local, 1).
        result_timeout: seconds a finished goal's result is kept (rclpy: 900).
        callback_group: accepted for rclpy compatibility and ignored.

    Raises:
        UnknownMessageTypeError: an unknown action type.
    """

    def __init__(
        self,
        node: Node,
        action_type: ActionType | str,
        action_name: str,
        execute_callback: Callable[[ServerGoalHandle], Any],
        *,
        callback_group: object = None,
        goal_callback: Callable[[Any], Any] = _accept_all,
        handle_accepted_callback: Callable[[ServerGoalHandle], Any] = _execute_now,
        cancel_callback: Callable[[ServerGoalHandle], Any] = _reject_cancel,
        goal_service_qos_profile: QoSProfile | int = qos_profile_services_default,
        result_service_qos_profile: QoSProfile | int = qos_profile_services_default,
        cancel_service_qos_profile: QoSProfile | int = qos_profile_services_default,
        feedback_pub_qos_profile: QoSProfile | int = 10,
        status_pub_qos_profile: QoSProfile | int = qos_profile_action_status_default,
        result_timeout: float = 900.0,
    ) -> None:
        del callback_group
        self.node = node
        self.action_type = get_action_type(action_type)
        self.action_name = node.resolve_topic_name(action_name)
        self.execute_callback = execute_callback
        self.goal_callback = goal_callback
        self.handle_accepted_callback = handle_accepted_callback
        self.cancel_callback = cancel_callback
        self.result_timeout = float(result_timeout)
        self.lock = threading.RLock()
        self._goals: dict[bytes, ServerGoalHandle] = {}
        self._results: dict[bytes, Any] = {}
        self._waiting: dict[bytes, list[_Request]] = {}
        self._expiry_ns: dict[bytes, int] = {}
        self._status_cache: weakref.WeakKeyDictionary[ServerGoalHandle, Any] = (
            weakref.WeakKeyDictionary()
        )
        """Finished goals -> when (node clock) their result is dropped."""
        self._threads: list[threading.Thread] = []
        self._destroyed = False
        names = action_names(self.action_name)
        at = self.action_type
        self._send_type = get_service_type(at.send_goal_service)
        self._result_type = get_service_type(at.get_result_service)
        self._cancel_type = get_service_type("action_msgs/srv/CancelGoal")
        self._status_cls = get_message_class("action_msgs/msg/GoalStatus")
        self._info_cls = get_message_class("action_msgs/msg/GoalInfo")
        self._array_cls = get_message_class("action_msgs/msg/GoalStatusArray")
        add = functools.partial(node._add_service, service_cls=_ActionService)
        self._services = [
            add(self._send_type, names["send_goal"], self._on_send_goal,
                to_qos(goal_service_qos_profile)),
            add(self._cancel_type, names["cancel_goal"], self._on_cancel,
                to_qos(cancel_service_qos_profile)),
            add(self._result_type, names["get_result"], self._on_get_result,
                to_qos(result_service_qos_profile)),
        ]  # fmt: skip
        self._feedback_pub = node.create_publisher(
            at.FeedbackMessage, names["feedback"], feedback_pub_qos_profile
        )
        self._status_pub = node.create_publisher(
            self._array_cls, names["status"], status_pub_qos_profile
        )
        # one timer of the node expires kept results (node clock: sim time when it is used)
        period = min(max(self.result_timeout / 4, 0.01), 1.0)
        self._expiry_timer = node.create_timer(period, self._expire_due)
        self._expiry_timer.cancel()  # runs only while results are kept

    def describe(self) -> str:
        """``action '/name' (pkg/action/Type)`` (for logs)."""
        return f"action '{self.action_name}' ({self.action_type.name})"

    @property
    def goal_handles(self) -> list[ServerGoalHandle]:
        """Goals the server knows: active ones and finished ones still kept."""
        with self.lock:
            return list(self._goals.values())

    # ------------------------------------------------------------------ services
    def _on_send_goal(self, request: Any, item: _Request) -> None:
        key = goal_key(request.goal_id)
        response = default_message(self._send_type.response_type_name)
        with self.lock:
            duplicate = key in self._goals
        if duplicate:
            self.node.get_logger().warning(
                f"{self.describe()}: rejected a goal whose id {key.hex()} is already in use"
            )
            item.respond(response)
            return
        verdict = self.goal_callback(request.goal)
        accepted = verdict is GoalResponse.ACCEPT or verdict is True
        if not accepted and not (verdict is GoalResponse.REJECT or verdict is False):
            msg = (
                f"{self.describe()}: goal_callback returned {verdict!r}, expected "
                "GoalResponse.ACCEPT or GoalResponse.REJECT"
            )
            raise ActionError(msg)
        now = self.node.get_clock().now_ns()
        response.accepted = accepted
        response.stamp = ns_to_time(now)
        if not accepted:
            item.respond(response)
            return
        handle = ServerGoalHandle(self, request.goal_id, request.goal, now)
        with self.lock:
            self._goals[key] = handle
        item.respond(response)
        self.publish_status()
        try:
            self.handle_accepted_callback(handle)
        except Exception:
            self._fail_goal(handle, "handle_accepted_callback")
            raise

    def _candidates(self, request: Any) -> tuple[list[ServerGoalHandle], int]:
        """Goals a cancel request names, and the error code if there are none."""
        err = self._cancel_type.Response
        info = request.goal_info
        key = goal_key(info.goal_id)
        stamp = time_to_ns(info.stamp)
        with self.lock:
            goals = list(self._goals.values())
        zero_id = not any(key)
        picked = [
            g
            for g in goals
            if (zero_id and stamp == 0)
            or (not zero_id and goal_key(g.goal_id) == key)
            or (stamp != 0 and g.stamp_ns <= stamp)
        ]
        active = [g for g in picked if g.is_active]
        if active:
            return active, err.ERROR_NONE
        if not zero_id and not picked:
            return [], err.ERROR_UNKNOWN_GOAL_ID
        if picked:
            return [], err.ERROR_GOAL_TERMINATED
        return [], err.ERROR_NONE

    def _on_cancel(self, request: Any, item: _Request) -> None:
        response = default_message(self._cancel_type.response_type_name)
        candidates, code = self._candidates(request)
        canceling = []
        for g in candidates:
            if g.is_cancel_requested:
                canceling.append(g)
                continue
            verdict = self.cancel_callback(g)
            if (verdict is CancelResponse.ACCEPT or verdict is True) and g.request_cancel():
                canceling.append(g)
        response.goals_canceling = [
            make(self._info_cls, goal_id=g.goal_id, stamp=ns_to_time(g.stamp_ns)) for g in canceling
        ]
        if candidates and not canceling:
            code = self._cancel_type.Response.ERROR_REJECTED
        response.return_code = code
        item.respond(response)

    def _on_get_result(self, request: Any, item: _Request) -> None:
        key = goal_key(request.goal_id)
        with self.lock:
            result = self._results.get(key)
            if result is None and key in self._goals:
                self._waiting.setdefault(key, []).append(item)
                return
        if result is None:
            result = default_message(self._result_type.response_type_name)
            result.status = int(GoalStatus.STATUS_UNKNOWN)
        item.respond(result)

    # ------------------------------------------------------------------ goals
    def start_execute(
        self, handle: ServerGoalHandle, execute_callback: Callable[[ServerGoalHandle], Any] | None
    ) -> None:
        """Run the execute callback for ``handle`` on its own thread."""
        callback = execute_callback or self.execute_callback
        thread = threading.Thread(
            target=self._run_execute,
            args=(handle, callback),
            name=f"action {self.action_name} {goal_id_hex(handle.goal_id)[:8]}",
            daemon=True,
        )
        with self.lock:
            self._threads = [t for t in self._threads if t.is_alive()]
            self._threads.append(thread)
        thread.start()

    def _run_execute(
        self, handle: ServerGoalHandle, callback: Callable[[ServerGoalHandle], Any]
    ) -> None:
        try:
            result = callback(handle)
        except Exception:  # noqa: BLE001 - logged, and the goal ends so no client hangs
            self._fail_goal(handle, "execute_callback")
            return
        if handle.is_active:
            self.node.get_logger().warning(
                f"{handle.describe()}: the execute callback returned without succeed(), "
                "abort() or canceled(); aborting the goal"
            )
            handle.abort()
        if not isinstance(result, self.action_type.Result):
            if result is not None:
                self.node.get_logger().error(
                    f"{handle.describe()}: the execute callback returned "
                    f"{type(result).__name__}, expected {self.action_type.name}.Result; "
                    "sending a default result"
                )
            result = default_message(f"{self.action_type.name}_Result")
        self.set_result(handle, result)

    def _fail_goal(self, handle: ServerGoalHandle, where: str) -> None:
        self.node.get_logger().error(
            f"{handle.describe()}: {where} raised; aborting the goal\n{traceback.format_exc()}"
        )
        if handle.is_active:
            handle.abort()
        self.set_result(handle, default_message(f"{self.action_type.name}_Result"))

    def set_result(self, handle: ServerGoalHandle, result: Any) -> None:
        """Store a finished goal's result and answer its waiting ``get_result`` requests."""
        key = goal_key(handle.goal_id)
        response = default_message(self._result_type.response_type_name)
        response.status = handle.status
        response.result = result
        with self.lock:
            if key in self._results or self._destroyed:
                return
            self._results[key] = response
            waiting = self._waiting.pop(key, [])
            self._expiry_ns[key] = self.node.get_clock().now_ns() + round(
                max(self.result_timeout, 0.0) * 1e9
            )
            if self._expiry_timer.is_canceled():
                self._expiry_timer.reset()
        for item in waiting:
            item.respond(response)

    def _expire_due(self) -> None:
        """Drop the results kept longer than ``result_timeout`` (a timer of the node)."""
        now = self.node.get_clock().now_ns()
        with self.lock:
            due = [k for k, t in self._expiry_ns.items() if t <= now]
            for key in due:
                self._goals.pop(key, None)
                self._results.pop(key, None)
                del self._expiry_ns[key]
            if not self._expiry_ns:
                self._expiry_timer.cancel()
        if due:
            self.publish_status()

    # ------------------------------------------------------------------ topics
    def publish_feedback(self, handle: ServerGoalHandle, feedback: Any) -> None:
        """Publish ``feedback`` for ``handle``'s goal."""
        if not isinstance(feedback, self.action_type.Feedback):
            got = getattr(feedback, "__msgtype__", type(feedback).__name__)
            msg = (
                f"{self.describe()}: feedback is a {got}, expected {self.action_type.name}_Feedback"
            )
            raise ActionError(msg)
        self._feedback_pub.publish(
            self.action_type.FeedbackMessage(goal_id=handle.goal_id, feedback=feedback)
        )

    def publish_status(self) -> None:
        """Publish the status of every known goal (on every state change)."""
        if self._destroyed:
            return
        with self.lock:
            statuses = [self._status_message(g) for g in self._goals.values()]
            self._status_pub.publish(self._array_cls(status_list=statuses))

    def _status_message(self, goal: ServerGoalHandle) -> Any:
        """The goal's ``GoalStatus`` message, made again only when its status changed."""
        cached = self._status_cache.get(goal)
        if cached is None or cached.status != goal.status:
            if cached is None:
                info = self._info_cls(goal_id=goal.goal_id, stamp=ns_to_time(goal.stamp_ns))
            else:
                info = cached.goal_info
            cached = self._status_cls(goal_info=info, status=goal.status)
            self._status_cache[goal] = cached
        return cached

    def destroy(self) -> None:
        """Remove the action's services and topics.

        Active goals are aborted (an execute callback that polls ``is_active`` ends) and
        waiting ``get_result`` requests fail.
        """
        with self.lock:
            if self._destroyed:
                return
            self._destroyed = True
            for goal in self._goals.values():
                if goal.is_active:
                    goal._status = GoalStatus.STATUS_ABORTED  # no status topic any more
            waiting = [i for items in self._waiting.values() for i in items]
            self._waiting.clear()
        for item in waiting:
            item.fail(f"{self.describe()} was destroyed before the goal ended")
        for srv in self._services:
            self.node.destroy_service(srv)
        self.node.destroy_publisher(self._feedback_pub)
        self.node.destroy_publisher(self._status_pub)
        self.node.destroy_timer(self._expiry_timer)
