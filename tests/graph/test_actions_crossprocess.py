"""Actions between real processes (Zenoh, rmw_zenoh's layout) in a private domain."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.graph import Context, Node
from visnav.graph.action_client import ActionClient
from visnav.graph.action_types import GoalStatus, new_goal_id
from visnav.graph.keys import parse_liveliness_token
from visnav.graph.node import _service_key
from visnav.msgs.action import get_action_type
from visnav.msgs.construct import make
from visnav.msgs.serde import serialize

SCRIPTS = Path(__file__).parent / "scripts"
Fibonacci = get_action_type("example_interfaces/action/Fibonacci")
S = GoalStatus


@pytest.fixture
def server(start_script: Callable[..., subprocess.Popen[str]]) -> subprocess.Popen[str]:
    return start_script(SCRIPTS / "action_server.py", "60")


@pytest.fixture
def node(domain: int) -> Iterator[Node]:
    with Context(domain) as ctx:
        stop = threading.Event()

        def spin() -> None:
            while not stop.is_set():
                ctx.spin_once(0.05)

        t = threading.Thread(target=spin, daemon=True)
        t.start()
        yield Node("client", context=ctx, start_parameter_services=False)
        stop.set()
        t.join(2.0)


def _goal(order: int) -> Any:
    return make(Fibonacci.Goal, order=order)


def test_goal_feedback_result_reject_abort(server: subprocess.Popen[str], node: Node) -> None:
    client = ActionClient(node, Fibonacci, "/fibonacci")
    assert client.wait_for_server(10.0)
    feedback: list[list[int]] = []
    res = client.send_goal(
        _goal(10),
        feedback_callback=lambda m: feedback.append(list(m.feedback.sequence)),
        timeout_sec=10.0,
    )
    assert res.status == S.STATUS_SUCCEEDED
    assert list(res.result.sequence)[-1] == 55
    assert len(feedback) >= 5
    assert client.send_goal(_goal(41), timeout_sec=10.0) is None  # rejected
    assert client.send_goal(_goal(0), timeout_sec=10.0).status == S.STATUS_ABORTED
    # the graph shows the action's services and topics as rmw_zenoh writes them
    keys = list(node.context.graph._tokens)
    send = next(k for k in keys if "/SS/" in k and "%fibonacci%_action%send_goal" in k)
    token = parse_liveliness_token(send)
    assert token.type_name == "example_interfaces/action/Fibonacci_SendGoal"
    assert token.type_hash.startswith("RIHS01_d1a57fb2")
    status = next(k for k in keys if "/MP/" in k and "%fibonacci%_action%status" in k)
    assert parse_liveliness_token(status).type_name == "action_msgs/msg/GoalStatusArray"


def test_cancel_across_processes(server: subprocess.Popen[str], node: Node) -> None:
    client = ActionClient(node, Fibonacci, "/fibonacci")
    assert client.wait_for_server(10.0)
    sent = client.send_goal_async(_goal(40))
    assert sent.wait(10.0)
    handle = sent.result()
    assert handle is not None
    assert handle.accepted
    reply = handle.cancel_goal(timeout_sec=10.0)
    assert reply.return_code == 0
    assert len(reply.goals_canceling) == 1
    res = handle.get_result(timeout_sec=10.0)
    assert res.status == S.STATUS_CANCELED
    assert len(res.result.sequence) < 41


def test_cli_send_goal_list_info(server: subprocess.Popen[str], domain: int) -> None:
    def visnav(*args: str) -> str:
        out = subprocess.run(
            [sys.executable, "-m", "visnav.cli.main", *args],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert out.returncode == 0, out.stderr
        return out.stdout

    assert "/fibonacci [example_interfaces/action/Fibonacci]" in visnav("action", "list", "-t")
    info = visnav("action", "info", "/fibonacci")
    assert "Action servers: 1\n    /act/server" in info
    out = visnav(
        "action", "send_goal", "/fibonacci", "example_interfaces/action/Fibonacci",
        "{order: 5}", "--feedback",
    )  # fmt: skip
    assert "Sending goal:\n     order: 5" in out
    assert "Goal accepted with ID: " in out
    assert "Feedback:\n    sequence: [0, 1, 1, 2, 3, 5]" in out
    assert "Result:\n    sequence: [0, 1, 1, 2, 3, 5]" in out
    assert out.rstrip().endswith("Goal finished with status: SUCCEEDED")
    rejected = visnav(
        "action", "send_goal", "/fibonacci", "example_interfaces/action/Fibonacci", "{order: 50}"
    )
    assert "Goal was rejected." in rejected
    node_info = visnav("node", "info", "/act/server")
    assert "Action Servers:\n    /fibonacci: example_interfaces/action/Fibonacci" in node_info
    assert "_action" not in node_info


def _raw_get(session: zenoh.Session, key: str, payload: bytes) -> list[Any]:
    replies: list[Any] = []
    done = threading.Event()
    session.get(
        key, zenoh.handlers.Callback(replies.append, done.set), payload=payload, timeout=5.0
    )
    assert done.wait(10.0), "the server never finished the query"
    return replies


def test_malformed_requests_never_kill_the_server(
    server: subprocess.Popen[str], node: Node, domain: int
) -> None:
    z = node.context.zenoh
    assert z is not None
    client = ActionClient(node, Fibonacci, "/fibonacci")
    assert client.wait_for_server(10.0)
    types = {
        "send_goal": "example_interfaces/action/Fibonacci_SendGoal",
        "get_result": "example_interfaces/action/Fibonacci_GetResult",
        "cancel_goal": "action_msgs/srv/CancelGoal",
    }
    valid = serialize(client._send.srv_type.Request(goal_id=new_goal_id(), goal=_goal(3)))

    @settings(max_examples=40, deadline=None)
    @given(
        which=st.sampled_from(sorted(types)),
        payload=st.one_of(
            st.binary(max_size=80),
            st.builds(
                lambda cut, tail: valid[:cut] + tail,
                st.integers(0, len(valid)),
                st.binary(max_size=8),
            ),
        ),
    )
    def check(which: str, payload: bytes) -> None:
        key = _service_key(domain, f"/fibonacci/_action/{which}", types[which])
        replies = _raw_get(z.session, key, payload)
        assert len(replies) == 1  # an answer (a response or an error), never silence
        if replies[0].ok is None:
            assert "/fibonacci/_action/" in replies[0].err.payload.to_bytes().decode()

    check()
    assert server.poll() is None
    assert client.send_goal(_goal(3), timeout_sec=10.0).status == S.STATUS_SUCCEEDED


def _sigint_as_in_a_terminal() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_cli_ctrl_c_cancels_the_goal(server: subprocess.Popen[str], domain: int) -> None:
    proc = subprocess.Popen(
        [
            sys.executable, "-m", "visnav.cli.main", "action", "send_goal", "/fibonacci",
            "example_interfaces/action/Fibonacci", "{order: 40}",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # as from a terminal: a test run started as a background job (`cmd &` without job
        # control) hands its children an ignored SIGINT, which Python keeps ignoring
        preexec_fn=_sigint_as_in_a_terminal,  # noqa: PLW1509 - signal.signal only, before exec
    )  # fmt: skip
    assert proc.stdout is not None
    lines = []
    for line in proc.stdout:
        lines.append(line)
        if line.startswith("Goal accepted with ID: "):
            break
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, "".join(lines) + out + err
    assert "Canceling goal..." in out
    assert out.rstrip().endswith("Goal finished with status: CANCELED")
