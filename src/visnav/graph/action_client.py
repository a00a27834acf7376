"""Action clients (rclpy's ``ActionClient`` and ``ClientGoalHandle``).

``send_goal_async(goal, feedback_callback=...)`` picks a random goal id, calls the
server's ``send_goal`` service and returns a future of a :class:`ClientGoalHandle`
(accepted or not). ``goal_handle.get_result_async()`` calls ``get_result`` (the server
answers when the goal ends) and ``goal_handle.cancel_goal_async()`` calls
``cancel_goal``. Feedback arrives on the ``feedback`` topic and status on ``status``;
both are matched to goals by id and their callbacks run in the executor (so spin the
client's context to receive feedback). The futures complete on the transport's
thread, so ``send_goal`` (blocking) works from a thread that is not the executor's, as
``Client.call`` does.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from visnav.graph.action_types import (
    ActionError,
    GoalStatus,
    action_names,
    goal_id_hex,
    goal_key,
    new_goal_id,
)
from visnav.graph.errors import GraphError
from visnav.graph.future import Future
from visnav.graph.qos import QoSProfile, qos_profile_services_default
from visnav.msgs.action import ActionType, get_action_type
from visnav.msgs.construct import make
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type

if TYPE_CHECKING:
    from visnav.graph.node import Node
    from visnav.graph.service import Client

__all__ = ["ActionClient", "ClientGoalHandle"]


class ClientGoalHandle:
    """A goal as its client sees it (rclpy's ``ClientGoalHandle``).

    Attributes:
        goal_id: the goal's ``unique_identifier_msgs/msg/UUID``.
        stamp: when the server accepted it (``builtin_interfaces/msg/Time``).
        accepted: whether the server accepted it.
        status: the latest status code the server published (``GoalStatus``).
    """

    def __init__(self, client: ActionClient, goal_id: Any, response: Any) -> None:
        self._client = client
        self.goal_id = goal_id
        self.stamp = response.stamp
        self.accepted = bool(response.accepted)
        self.status = int(
            GoalStatus.STATUS_ACCEPTED if self.accepted else GoalStatus.STATUS_UNKNOWN
        )
        self._result_future: Future[Any] | None = None

    def get_result_async(self, *, timeout_sec: float | None = None) -> Future[Any]:
        """A future of the ``GetResult`` response (``.status`` and ``.result``)."""
        if not self.accepted:
            msg = f"goal {goal_id_hex(self.goal_id)} was rejected: it has no result"
            raise ActionError(msg)
        if self._result_future is None or (
            self._result_future.done() and self._result_future.exception() is not None
        ):
            self._result_future = self._client.get_result_async(self.goal_id, timeout_sec)
        return self._result_future

    def get_result(self, timeout_sec: float | None = None) -> Any:
        """Block until the result (from a thread other than the executor's)."""
        return _wait(self.get_result_async(), timeout_sec, f"the result of {self}")

    def cancel_goal_async(self) -> Future[Any]:
        """A future of the ``action_msgs/srv/CancelGoal`` response."""
        return self._client.cancel_goal_async(self.goal_id)

    def cancel_goal(self, timeout_sec: float | None = None) -> Any:
        """Request cancelling and block until the server answers."""
        return _wait(self.cancel_goal_async(), timeout_sec, f"cancelling {self}")

    def __repr__(self) -> str:
        state = "accepted" if self.accepted else "rejected"
        return f"<ClientGoalHandle {goal_id_hex(self.goal_id)} {state} status={self.status}>"


def _wait(future: Future[Any], timeout_sec: float | None, what: str) -> Any:
    if not future.wait(timeout_sec):
        future.cancel()
        msg = f"{what}: no answer within {timeout_sec:g} s"
        raise ActionError(msg)
    return future.result()


class ActionClient:
    """Sends goals to one action (rclpy's ``ActionClient`` signature).

    Args:
        node: the node the client's services and subscriptions belong to.
        action_type: an :class:`~visnav.msgs.action.ActionType` or its name.
        action_name: the action's name (expanded and remapped as a topic name).
        goal_service_qos_profile: QoS of the send_goal client.
        result_service_qos_profile: QoS of the get_result client.
        cancel_service_qos_profile: QoS of the cancel_goal client.
        feedback_sub_qos_profile: QoS of the feedback subscription.
        status_sub_qos_profile: QoS of the status subscription.
        callback_group: accepted for rclpy compatibility and ignored.
    """

    def __init__(
        self,
        node: Node,
        action_type: ActionType | str,
        action_name: str,
        *,
        callback_group: object = None,
        goal_service_qos_profile: QoSProfile | int = qos_profile_services_default,
        result_service_qos_profile: QoSProfile | int = qos_profile_services_default,
        cancel_service_qos_profile: QoSProfile | int = qos_profile_services_default,
        feedback_sub_qos_profile: QoSProfile | int = 10,
        status_sub_qos_profile: QoSProfile | int | None = None,
    ) -> None:
        from visnav.graph.action_types import (  # noqa: PLC0415 - keep the import list short
            qos_profile_action_status_default,
        )

        del callback_group
        self.node = node
        self.action_type = get_action_type(action_type)
        self.action_name = node.resolve_topic_name(action_name)
        names = action_names(self.action_name)
        at = self.action_type
        self._send: Client[Any, Any] = node.create_client(
            get_service_type(at.send_goal_service),
            names["send_goal"],
            qos_profile=goal_service_qos_profile,
        )
        self._cancel: Client[Any, Any] = node.create_client(
            get_service_type("action_msgs/srv/CancelGoal"),
            names["cancel_goal"],
            qos_profile=cancel_service_qos_profile,
        )
        self._result: Client[Any, Any] = node.create_client(
            get_service_type(at.get_result_service),
            names["get_result"],
            qos_profile=result_service_qos_profile,
        )
        self._lock = threading.Lock()
        self._handles: dict[bytes, ClientGoalHandle] = {}
        self._feedback_callbacks: dict[bytes, Callable[[Any], Any]] = {}
        self._feedback_sub = node.create_subscription(
            at.FeedbackMessage, names["feedback"], self._on_feedback, feedback_sub_qos_profile
        )
        self._status_sub = node.create_subscription(
            get_message_class("action_msgs/msg/GoalStatusArray"),
            names["status"],
            self._on_status,
            status_sub_qos_profile or qos_profile_action_status_default,
        )
        self._info_cls = get_message_class("action_msgs/msg/GoalInfo")

    def describe(self) -> str:
        """``client of action '/name' (pkg/action/Type)``."""
        return f"client of action '{self.action_name}' ({self.action_type.name})"

    # ------------------------------------------------------------------ readiness
    def server_is_ready(self) -> bool:
        """Whether the action's three services have a server in the graph."""
        return all(c.service_is_ready() for c in (self._send, self._cancel, self._result))

    def wait_for_server(self, timeout_sec: float | None = None) -> bool:
        """Wait until the server is ready; False after ``timeout_sec`` (None: forever)."""
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not self.server_is_ready():
            if deadline is not None and time.monotonic() >= deadline:
                return self.server_is_ready()
            if not self.node.context.ok:
                return False
            self.node.context.wait_graph_change(0.05)
        return True

    # ------------------------------------------------------------------ goals
    def send_goal_async(
        self,
        goal: Any,
        feedback_callback: Callable[[Any], Any] | None = None,
        goal_uuid: Any = None,
        *,
        timeout_sec: float | None = None,
    ) -> Future[ClientGoalHandle]:
        """Send a goal; the future completes with its :class:`ClientGoalHandle`.

        Args:
            goal: the action's ``Goal`` message.
            feedback_callback: ``callback(feedback_message)`` for this goal's feedback
                (``.goal_id`` and ``.feedback``), run in the executor.
            goal_uuid: a ``unique_identifier_msgs/msg/UUID`` (default: a random one).
            timeout_sec: a visnav addition: fail if the server does not answer in time.

        Raises:
            ActionError: ``goal`` is not of the action's goal type.
        """
        if not isinstance(goal, self.action_type.Goal):
            got = getattr(goal, "__msgtype__", type(goal).__name__)
            msg = f"{self.describe()}: the goal is a {got}, expected {self.action_type.name}_Goal"
            raise ActionError(msg)
        goal_id = goal_uuid if goal_uuid is not None else new_goal_id()
        key = goal_key(goal_id)
        if feedback_callback is not None:
            with self._lock:
                self._feedback_callbacks[key] = feedback_callback
        request = self._send.srv_type.Request(goal_id=goal_id, goal=goal)
        outer: Future[ClientGoalHandle] = Future(self._send._dispatch)
        inner = self._send.call_async(request, timeout_sec=timeout_sec)

        def done() -> None:
            exc = inner.exception()
            if exc is not None or inner.cancelled():
                with self._lock:
                    self._feedback_callbacks.pop(key, None)
                outer.set_exception(exc or ActionError(f"{self.describe()}: cancelled"))
                return
            handle = ClientGoalHandle(self, goal_id, inner.result())
            with self._lock:
                if handle.accepted:
                    self._handles[key] = handle
                else:
                    self._feedback_callbacks.pop(key, None)
            outer.set_result(handle)

        inner.on_complete(done)
        return outer

    def send_goal(
        self,
        goal: Any,
        feedback_callback: Callable[[Any], Any] | None = None,
        goal_uuid: Any = None,
        *,
        timeout_sec: float | None = None,
    ) -> Any:
        """Send a goal and block until its result (rclpy's ``send_goal``).

        Returns:
            The ``GetResult`` response (``.status``, ``.result``), or None when the
            server rejected the goal.

        Raises:
            GraphError: called from a callback of the client's own executor.
            ActionError: no answer within ``timeout_sec`` (each of the two calls).
        """
        if self.node.context.in_callback():
            msg = (
                f"{self.describe()}: send_goal() from inside a callback of the same executor "
                "would wait for itself; use send_goal_async()"
            )
            raise GraphError(msg)
        handle = _wait(
            self.send_goal_async(goal, feedback_callback, goal_uuid, timeout_sec=timeout_sec),
            timeout_sec,
            f"{self.describe()}: sending the goal",
        )
        if not handle.accepted:
            return None
        return handle.get_result(timeout_sec)

    def get_result_async(self, goal_id: Any, timeout_sec: float | None = None) -> Future[Any]:
        """Call ``get_result`` for ``goal_id``; the goal's feedback callback is dropped after."""
        request = self._result.srv_type.Request(goal_id=goal_id)
        future = self._result.call_async(request, timeout_sec=timeout_sec)
        key = goal_key(goal_id)

        def forget() -> None:
            if future.exception() is None and not future.cancelled():
                response = future.result()
                with self._lock:
                    handle = self._handles.pop(key, None)
                    self._feedback_callbacks.pop(key, None)
                if handle is not None and response is not None:
                    handle.status = int(response.status)

        future.on_complete(forget)
        return future

    def cancel_goal_async(self, goal_id: Any, stamp: Any = None) -> Future[Any]:
        """Call ``cancel_goal`` for ``goal_id`` (an all-zero id with a stamp: earlier goals)."""
        info = make(self._info_cls, goal_id=goal_id)
        if stamp is not None:
            info.stamp = stamp
        return self._cancel.call_async(self._cancel.srv_type.Request(goal_info=info))

    # ------------------------------------------------------------------ topics
    def _on_feedback(self, msg: Any) -> None:
        with self._lock:
            callback = self._feedback_callbacks.get(goal_key(msg.goal_id))
        if callback is not None:
            callback(msg)

    def _on_status(self, msg: Any) -> None:
        with self._lock:
            for status in msg.status_list:
                handle = self._handles.get(goal_key(status.goal_info.goal_id))
                if handle is not None:
                    handle.status = int(status.status)

    def destroy(self) -> None:
        """Remove the client's services and subscriptions."""
        for client in (self._send, self._cancel, self._result):
            self.node.destroy_client(client)
        self.node.destroy_subscription(self._feedback_sub)
        self.node.destroy_subscription(self._status_sub)
