"""Actions in one process: rclpy's ActionServer / ActionClient, the goal state machine."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.graph import Context, Node
from visnav.graph.action_client import ActionClient
from visnav.graph.action_server import ActionServer, ServerGoalHandle
from visnav.graph.action_types import (
    ActionError,
    CancelResponse,
    GoalResponse,
    GoalStatus,
    action_names,
    goal_id_from_bytes,
    goal_id_hex,
)
from visnav.graph.errors import ServiceError
from visnav.msgs.action import ACTION_DEFINITIONS, get_action_type
from visnav.msgs.construct import make, message_from_dict
from visnav.msgs.errors import UnknownMessageTypeError
from visnav.msgs.serde import deserialize, serialize, typestore

Fibonacci = get_action_type("example_interfaces/action/Fibonacci")
S = GoalStatus


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        stop = threading.Event()
        spinner = threading.Thread(target=_spin, args=(c, stop), daemon=True)
        spinner.start()
        yield c
        stop.set()
        spinner.join(2.0)


def _spin(ctx: Context, stop: threading.Event) -> None:
    while not stop.is_set() and ctx.ok:
        ctx.spin_once(0.02)


def _fib(handle: ServerGoalHandle) -> Any:
    seq = [0, 1]
    for i in range(1, handle.request.order):
        if handle.is_cancel_requested:
            handle.canceled()
            return make(Fibonacci.Result, sequence=seq)
        seq.append(seq[i] + seq[i - 1])
        handle.publish_feedback(make(Fibonacci.Feedback, sequence=seq))
        time.sleep(0.01)
    handle.succeed()
    return make(Fibonacci.Result, sequence=seq)


def _goal(order: int) -> Any:
    return make(Fibonacci.Goal, order=order)


def test_action_types_hash_as_jazzy_and_round_trip() -> None:
    store = typestore()
    # RIHS01 hashes of ROS 2 Jazzy's generated example_interfaces / action_msgs
    assert store.hash_rihs01("example_interfaces/action/Fibonacci_SendGoal") == (
        "RIHS01_d1a57fb2a4afe8c21e34fb10db206f16ce6729b28531141472df92277c55b557"
    )
    assert store.hash_rihs01("example_interfaces/action/Fibonacci_GetResult") == (
        "RIHS01_1b0de0d5d29dc955d92f546706568428632771db13ec84c15ec1c1a59f424a57"
    )
    assert store.hash_rihs01("example_interfaces/action/Fibonacci_FeedbackMessage") == (
        "RIHS01_c1de71afd52e49a89c53d8262366884185bc0a02f78ce051c4e46b0a7fe59bb2"
    )
    assert store.hash_rihs01("action_msgs/srv/CancelGoal") == (
        "RIHS01_573d8b0a534451d7bc2ac8c5ffde8ac14b8593b7001175d0cd6516dcbeb8689a"
    )
    assert store.hash_rihs01("action_msgs/msg/GoalStatusArray") == (
        "RIHS01_6c1684b00f177d37438febe6e709fc4e2b0d4248dca4854946f9ed8b30cda83e"
    )
    for name in ACTION_DEFINITIONS:
        for suffix in ("_SendGoal_Request", "_GetResult_Response", "_FeedbackMessage"):
            msg = message_from_dict(f"{name}{suffix}", {})
            data = serialize(msg)
            assert serialize(deserialize(data, f"{name}{suffix}")) == data
    assert get_action_type("move_base_msgs/MoveBaseAction").name == "move_base_msgs/action/MoveBase"
    with pytest.raises(UnknownMessageTypeError, match="did you mean nav2_msgs/action/Navigate"):
        get_action_type("nav2_msgs/action/NavigateToPos")
    assert action_names("/a")["status"] == "/a/_action/status"


def test_goal_feedback_result(ctx: Context) -> None:
    server = Node("server", context=ctx)
    ActionServer(server, Fibonacci, "fibonacci", _fib)
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/fibonacci")
    assert client.wait_for_server(2.0)
    feedback: list[list[int]] = []
    future = client.send_goal_async(
        _goal(5), feedback_callback=lambda m: feedback.append(list(m.feedback.sequence))
    )
    assert future.wait(2.0)
    handle = future.result()
    assert handle is not None
    assert handle.accepted
    assert len(goal_id_hex(handle.goal_id)) == 32
    response = handle.get_result(timeout_sec=2.0)
    assert response.status == S.STATUS_SUCCEEDED
    assert list(response.result.sequence) == [0, 1, 1, 2, 3, 5]
    deadline = time.monotonic() + 2.0
    while len(feedback) < 4 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert feedback[-1] == [0, 1, 1, 2, 3, 5]
    assert feedback[0] == [0, 1, 1]


def test_send_goal_blocking_and_reject(ctx: Context) -> None:
    server = Node("server", context=ctx)
    ActionServer(
        server,
        Fibonacci,
        "fib",
        _fib,
        goal_callback=lambda g: GoalResponse.REJECT if g.order > 10 else GoalResponse.ACCEPT,
    )
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/fib")
    result = client.send_goal(_goal(3), timeout_sec=2.0)
    assert result.status == S.STATUS_SUCCEEDED
    assert client.send_goal(_goal(11), timeout_sec=2.0) is None
    future = client.send_goal_async(_goal(11))
    assert future.wait(2.0)
    handle = future.result()
    assert handle is not None
    assert not handle.accepted
    with pytest.raises(ActionError, match="rejected"):
        handle.get_result_async()


def _slow(handle: ServerGoalHandle) -> Any:
    while not handle.is_cancel_requested:
        time.sleep(0.005)
        if not handle.is_active:
            return make(Fibonacci.Result, sequence=[-1])
    handle.canceled()
    return make(Fibonacci.Result, sequence=[42])


def test_cancel_accepted_and_rejected(ctx: Context) -> None:
    server = Node("server", context=ctx)
    allow = {"cancel": True}
    ActionServer(
        server,
        Fibonacci,
        "slow",
        _slow,
        cancel_callback=lambda h: (
            CancelResponse.ACCEPT if allow["cancel"] else CancelResponse.REJECT
        ),
    )
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/slow")
    fut = client.send_goal_async(_goal(1))
    assert fut.wait(2.0)
    handle = fut.result()
    assert handle is not None
    allow["cancel"] = False
    reply = handle.cancel_goal(timeout_sec=2.0)
    assert reply.return_code == 1  # ERROR_REJECTED
    assert list(reply.goals_canceling) == []
    allow["cancel"] = True
    reply = handle.cancel_goal(timeout_sec=2.0)
    assert reply.return_code == 0
    assert len(reply.goals_canceling) == 1
    result = handle.get_result(timeout_sec=2.0)
    assert result.status == S.STATUS_CANCELED
    assert list(result.result.sequence) == [42]
    # the goal is over: cancelling it again names that
    assert handle.cancel_goal(timeout_sec=2.0).return_code == 3  # ERROR_GOAL_TERMINATED
    unknown = client.cancel_goal_async(goal_id_from_bytes(bytes(range(1, 17))))
    assert unknown.wait(2.0)
    assert unknown.result().return_code == 2  # ERROR_UNKNOWN_GOAL_ID


def test_cancel_all_goals(ctx: Context) -> None:
    server = Node("server", context=ctx)
    ActionServer(server, Fibonacci, "slow", _slow, cancel_callback=lambda h: CancelResponse.ACCEPT)
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/slow")
    futures = [client.send_goal_async(_goal(1)) for _ in range(3)]
    handles = []
    for f in futures:
        assert f.wait(2.0)
        handles.append(f.result())
    zero = make(type(handles[0].goal_id))
    reply = client.cancel_goal_async(zero)
    assert reply.wait(2.0)
    assert len(reply.result().goals_canceling) == 3
    for h in handles:
        assert h.get_result(timeout_sec=2.0).status == S.STATUS_CANCELED


def test_preempt_the_running_goal(ctx: Context) -> None:
    server = Node("server", context=ctx)
    running: list[ServerGoalHandle] = []
    lock = threading.Lock()

    def accepted(handle: ServerGoalHandle) -> None:
        with lock:
            for old in running:
                if old.is_active:
                    old.canceled()  # server-side preemption, as move_base does
            running.append(handle)
        handle.execute()

    ActionServer(server, Fibonacci, "nav", _slow, handle_accepted_callback=accepted)
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/nav")
    first = client.send_goal_async(_goal(1))
    assert first.wait(2.0)
    second = client.send_goal_async(_goal(2))
    assert second.wait(2.0)
    old = first.result().get_result(timeout_sec=2.0)
    assert old.status == S.STATUS_CANCELED
    assert list(old.result.sequence) == [-1]
    assert second.result().accepted
    assert running[1].is_executing


def test_abort_and_exceptions_never_hang_the_client(ctx: Context) -> None:
    server = Node("server", context=ctx)

    def boom(handle: ServerGoalHandle) -> Any:
        if handle.request.order == 1:
            raise RuntimeError("motor on fire")
        if handle.request.order == 2:
            handle.abort()
            return make(Fibonacci.Result, sequence=[2])
        if handle.request.order == 3:
            return make(Fibonacci.Result, sequence=[3])  # forgot succeed(): aborted
        return "not a result"  # after succeed(): a default result is sent

    def check(goal: Any) -> GoalResponse:
        if goal.order == 99:
            raise ValueError("goal_callback broke")
        return GoalResponse.ACCEPT

    ActionServer(server, Fibonacci, "boom", boom, goal_callback=check)
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/boom")
    assert client.send_goal(_goal(1), timeout_sec=2.0).status == S.STATUS_ABORTED
    res = client.send_goal(_goal(2), timeout_sec=2.0)
    assert res.status == S.STATUS_ABORTED
    assert list(res.result.sequence) == [2]
    assert client.send_goal(_goal(3), timeout_sec=2.0).status == S.STATUS_ABORTED
    assert client.send_goal(_goal(4), timeout_sec=2.0).status == S.STATUS_ABORTED
    future = client.send_goal_async(_goal(99))
    assert future.wait(2.0)
    assert isinstance(future.exception(), ServiceError)
    assert "goal_callback broke" in str(future.exception())
    # the server still serves
    assert client.send_goal(_goal(2), timeout_sec=2.0).status == S.STATUS_ABORTED


def test_goal_handle_state_machine(ctx: Context) -> None:
    server = Node("server", context=ctx)
    handles: list[ServerGoalHandle] = []
    ActionServer(server, Fibonacci, "sm", _fib, handle_accepted_callback=handles.append)
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/sm")
    f = client.send_goal_async(_goal(2))
    assert f.wait(2.0)
    h = handles[0]
    assert h.status == S.STATUS_ACCEPTED
    with pytest.raises(ActionError, match="cannot succeed a goal that is ACCEPTED"):
        h.succeed()
    h.execute(lambda gh: (gh.succeed(), make(Fibonacci.Result, sequence=[7]))[1])
    res = f.result().get_result(timeout_sec=2.0)
    assert res.status == S.STATUS_SUCCEEDED
    assert list(res.result.sequence) == [7]
    with pytest.raises(ActionError, match="cannot abort a goal that is SUCCEEDED"):
        h.abort()
    with pytest.raises(ActionError, match="feedback is a"):
        h.publish_feedback(_goal(1))


def test_result_retention_and_status(ctx: Context) -> None:
    server = Node("server", context=ctx)
    action = ActionServer(server, Fibonacci, "keep", _fib, result_timeout=0.3)
    cnode = Node("client", context=ctx)
    client = ActionClient(cnode, Fibonacci, "/keep")
    statuses: list[list[int]] = []
    cnode.create_subscription(
        action._status_pub.msg_type,
        "/keep/_action/status",
        lambda m: statuses.append([int(s.status) for s in m.status_list]),
        10,
    )
    f = client.send_goal_async(_goal(2))
    assert f.wait(2.0)
    handle = f.result()
    assert handle.get_result(timeout_sec=2.0).status == S.STATUS_SUCCEEDED
    # a second client asks after the end: still there
    again = client.get_result_async(handle.goal_id)
    assert again.wait(2.0)
    assert again.result().status == S.STATUS_SUCCEEDED
    assert len(action.goal_handles) == 1
    time.sleep(0.5)
    assert action.goal_handles == []
    late = client.get_result_async(handle.goal_id)
    assert late.wait(2.0)
    assert late.result().status == S.STATUS_UNKNOWN
    deadline = time.monotonic() + 1.0
    while (not statuses or statuses[-1] != []) and time.monotonic() < deadline:
        time.sleep(0.01)
    seen = {s for st in statuses for s in st}
    assert {S.STATUS_ACCEPTED, S.STATUS_EXECUTING, S.STATUS_SUCCEEDED} <= seen
    assert statuses[-1] == []
    assert handle.status == S.STATUS_SUCCEEDED


def test_goal_of_wrong_type_is_refused(ctx: Context) -> None:
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/none")
    with pytest.raises(ActionError, match="expected example_interfaces/action/Fibonacci_Goal"):
        client.send_goal_async(make(get_action_type("move_base_msgs/action/MoveBase").Goal))
    assert not client.wait_for_server(0.05)


def test_destroy_fails_waiting_results_and_leaves_the_graph(ctx: Context) -> None:
    server = Node("server", context=ctx)
    action = ActionServer(server, Fibonacci, "gone", _slow)
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/gone")
    sent = client.send_goal_async(_goal(1))
    assert sent.wait(2.0)
    result = sent.result().get_result_async()
    time.sleep(0.1)
    action.destroy()
    assert result.wait(2.0)
    assert isinstance(result.exception(), ServiceError)
    assert "destroyed before the goal ended" in str(result.exception())
    assert not client.server_is_ready()
    client.destroy()
    assert not [s for s in server.services if "_action" in s.srv_name]


_OUTCOMES = {
    "succeed": S.STATUS_SUCCEEDED,
    "abort": S.STATUS_ABORTED,
    "forget": S.STATUS_ABORTED,
    "raise": S.STATUS_ABORTED,
    "wait_cancel": S.STATUS_CANCELED,
}


def test_any_mix_of_goals_always_ends_every_client_future(ctx: Context) -> None:
    scripts: dict[int, str] = {}
    names = sorted(_OUTCOMES)

    def execute(handle: ServerGoalHandle) -> Any:
        script = scripts[handle.request.order]
        if script == "raise":
            raise RuntimeError("scripted failure")
        if script == "succeed":
            handle.succeed()
        elif script == "abort":
            handle.abort()
        elif script == "wait_cancel":
            deadline = time.monotonic() + 5.0
            while not handle.is_cancel_requested and time.monotonic() < deadline:
                time.sleep(0.002)
            handle.canceled()
        return make(Fibonacci.Result)

    server = Node("server", context=ctx)
    ActionServer(
        server, Fibonacci, "mix", execute, cancel_callback=lambda _h: CancelResponse.ACCEPT
    )
    client = ActionClient(Node("client", context=ctx), Fibonacci, "/mix")
    counter = [0]

    @settings(max_examples=25, deadline=None)
    @given(st.lists(st.sampled_from(names), min_size=1, max_size=6))
    def check(plan: list[str]) -> None:
        futures = []
        for script in plan:
            counter[0] += 1
            scripts[counter[0]] = script
            futures.append((script, client.send_goal_async(_goal(counter[0]))))
        handles = []
        for script, f in futures:
            assert f.wait(2.0)
            handle = f.result()
            assert handle is not None
            assert handle.accepted
            handles.append((script, handle, handle.get_result_async()))
        for script, handle, _ in handles:
            if script == "wait_cancel":
                reply = handle.cancel_goal(timeout_sec=2.0)
                assert reply.return_code in (0, 3)
        for script, _, result in handles:
            assert result.wait(6.0), script
            assert result.result().status == _OUTCOMES[script], script

    check()
