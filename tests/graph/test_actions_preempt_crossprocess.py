"""A newer goal preempts the running one across processes; feedback reaches the client."""

from __future__ import annotations

import subprocess
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from visnav.graph import Context, Node
from visnav.graph.action_client import ActionClient
from visnav.graph.action_types import GoalStatus
from visnav.msgs.action import get_action_type
from visnav.msgs.construct import make

SCRIPTS = Path(__file__).parent / "scripts"
Fibonacci = get_action_type("example_interfaces/action/Fibonacci")


@pytest.fixture
def client(
    start_script: Callable[..., subprocess.Popen[str]], domain: int
) -> Iterator[ActionClient]:
    start_script(SCRIPTS / "preempt_server.py", "60")
    with Context(domain) as ctx:
        stop = threading.Event()

        def spin() -> None:
            while not stop.is_set():
                ctx.spin_once(0.05)

        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        node = Node("client", context=ctx, start_parameter_services=False)
        yield ActionClient(node, Fibonacci, "/nav")
        stop.set()
        spinner.join(2.0)


def test_newer_goal_preempts_the_running_one_with_feedback(client: ActionClient) -> None:
    assert client.wait_for_server(10.0)
    feedback: dict[str, list[int]] = {"first": [], "second": []}

    def sender(name: str) -> Any:
        return lambda m: feedback[name].append(int(m.feedback.sequence[0]))

    first = client.send_goal_async(make(Fibonacci.Goal, order=1), feedback_callback=sender("first"))
    assert first.wait(10.0)
    first_handle = first.result()
    assert first_handle is not None
    assert first_handle.accepted
    deadline = threading.Event()
    for _ in range(200):  # until the first goal's feedback flows
        if len(feedback["first"]) >= 3:
            break
        deadline.wait(0.05)
    assert len(feedback["first"]) >= 3

    second = client.send_goal_async(
        make(Fibonacci.Goal, order=2), feedback_callback=sender("second")
    )
    assert second.wait(10.0)
    second_handle = second.result()
    assert second_handle is not None
    assert second_handle.accepted
    old = first_handle.get_result(timeout_sec=10.0)
    assert old.status == GoalStatus.STATUS_CANCELED
    assert list(old.result.sequence) == [-1]  # preempted, not cancelled by the client

    for _ in range(200):
        if len(feedback["second"]) >= 3:
            break
        deadline.wait(0.05)
    assert len(feedback["second"]) >= 3
    reply = second_handle.cancel_goal(timeout_sec=10.0)
    assert len(reply.goals_canceling) == 1
    res = second_handle.get_result(timeout_sec=10.0)
    assert res.status == GoalStatus.STATUS_CANCELED
    assert list(res.result.sequence) == [42]
