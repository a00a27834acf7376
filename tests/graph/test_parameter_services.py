"""Parameters over the graph: rcl_interfaces' services, /parameter_events, refusals' reasons."""

from __future__ import annotations

import subprocess
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.graph import Context, Node, ParamBinding, Parameter, param
from visnav.graph.param_client import ParameterClient
from visnav.graph.param_services import PARAMETER_SERVICES, msg_to_value, value_to_msg
from visnav.graph.qos import QoSProfile
from visnav.msgs.serde import get_message_class

SCRIPTS = Path(__file__).parent / "scripts"
ParameterEvent = get_message_class("rcl_interfaces/msg/ParameterEvent")


@dataclass(frozen=True)
class DemoParams:
    rate: float = param(10.0, description="loop rate (Hz)", range=(0.1, 100.0))
    frame: str = param("map", description="frame", read_only=True)
    sizes: list[int] = param([1, 2])  # noqa: RUF009


@pytest.fixture
def spinning(domain: int) -> Iterator[tuple[Context, Node]]:
    """A node with a params dataclass, its context spun by a thread."""
    with Context(domain) as ctx:
        node = Node("demo", namespace="/ns", context=ctx)
        ParamBinding(node, DemoParams, prefix="demo.")
        stop = threading.Event()
        thread = threading.Thread(target=lambda: ctx.spin_until(stop.is_set, 60))
        thread.start()
        try:
            yield ctx, node
        finally:
            stop.set()
            thread.join()


@given(
    st.one_of(
        st.booleans(),
        st.integers(-(2**63), 2**63 - 1),
        st.floats(allow_nan=False),
        st.text(),
        st.binary(max_size=32),
        st.lists(st.booleans(), min_size=1, max_size=5),
        st.lists(st.integers(-(2**63), 2**63 - 1), min_size=1, max_size=5),
        st.lists(st.floats(allow_nan=False), min_size=1, max_size=5),
        st.lists(st.text(), max_size=5),
    )
)
def test_parameter_values_round_trip(value: Any) -> None:
    assert msg_to_value(value_to_msg(value)) == value


def test_every_node_serves_the_six_services_unless_told_not_to() -> None:
    with Context(transport="local") as ctx:
        Node("on", context=ctx)
        Node("off", context=ctx, start_parameter_services=False)
        names = dict(ctx.graph.service_names_and_types())
    for suffix, type_name in PARAMETER_SERVICES:
        assert names[f"/on/{suffix}"] == [type_name]
        assert f"/off/{suffix}" not in names


def test_list_get_describe_in_process(spinning: tuple[Context, Node], domain: int) -> None:
    _ctx, _node = spinning
    with Context(domain) as other:
        client = ParameterClient(
            Node("tool", context=other, start_parameter_services=False), "/ns/demo"
        )
        assert client.wait_for_services(10.0)
        assert client.list_parameters() == ["demo.frame", "demo.rate", "demo.sizes", "use_sim_time"]
        assert client.list_parameters(prefixes=["demo"]) == [
            "demo.frame",
            "demo.rate",
            "demo.sizes",
        ]
        assert client.get_parameters(["demo.rate", "demo.sizes", "nope"]) == [10.0, [1, 2], None]
        assert client.get_parameter_types(["demo.rate", "demo.frame", "nope"]) == [3, 4, 0]
        (rate, frame) = client.describe_parameters(["demo.rate", "demo.frame"])
        assert rate.description == "loop rate (Hz)"
        assert (rate.floating_point_range[0].from_value, rate.floating_point_range[0].to_value) == (
            0.1,
            100.0,
        )
        assert frame.read_only


def test_set_reaches_the_node_and_refusals_carry_their_reason(
    spinning: tuple[Context, Node], domain: int
) -> None:
    _ctx, node = spinning
    with Context(domain) as other:
        client = ParameterClient(
            Node("tool", context=other, start_parameter_services=False), "/ns/demo"
        )
        assert client.wait_for_services(10.0)
        ok, too_big, read_only, wrong_type, undeclared = client.set_parameters(
            [
                Parameter("demo.rate", 20),  # an int widens to the declared double
                Parameter("demo.rate", 500.0),
                Parameter("demo.frame", "odom"),
                Parameter("demo.rate", "fast"),
                Parameter("demo.nope", 1),
            ]
        )
        assert ok.successful
        assert node.get_parameter("demo.rate").value == 20.0
        assert not too_big.successful
        assert "expected a value in [0.1, 100.0]" in too_big.reason
        assert not read_only.successful
        assert "read-only" in read_only.reason
        assert not wrong_type.successful
        assert "'demo.rate'" in wrong_type.reason
        assert not undeclared.successful
        assert "not declared" in undeclared.reason
        atomic = client.set_parameters_atomically(
            [Parameter("demo.rate", 30.0), Parameter("demo.rate", 1000.0)]
        )
        assert not atomic.successful
        assert node.get_parameter("demo.rate").value == 20.0  # all or none


def test_parameter_events_on_declare_and_set(domain: int) -> None:
    with Context(transport="local") as ctx:
        listener = Node("listener", context=ctx, start_parameter_services=False)
        events: list[Any] = []
        listener.create_subscription(
            ParameterEvent, "/parameter_events", events.append, QoSProfile(depth=100)
        )
        node = Node("talker", context=ctx)
        node.declare_parameter("speed", 1.5)
        node.set_parameters([Parameter("speed", 2.5)])
        ctx.spin_some()
    news = [p.name for e in events for p in e.new_parameters]
    changes = [(p.name, msg_to_value(p.value)) for e in events for p in e.changed_parameters]
    assert "speed" in news
    assert ("speed", 2.5) in changes
    assert all(e.node == "/talker" for e in events if e.changed_parameters)


def test_set_from_another_process_reaches_the_node(
    start_script: Callable[..., subprocess.Popen[str]], domain: int
) -> None:
    start_script(SCRIPTS / "service_server.py", "60")
    with Context(domain) as ctx:
        node = Node("watcher", context=ctx, start_parameter_services=False)
        events: list[Any] = []
        node.create_subscription(
            ParameterEvent, "/parameter_events", events.append, QoSProfile(depth=100)
        )
        client = ParameterClient(node, "/srv/server", timeout_sec=10.0)
        assert client.wait_for_services(10.0)
        # the server creates its /parameter_events publisher for the first event that has
        # a subscription in its graph: the ParameterClient's own calls went first
        (result,) = client.set_parameters([Parameter("gain", 2.5)])
        assert result.successful
        assert client.get_parameters(["gain"]) == [2.5]
        (refused,) = client.set_parameters([Parameter("mode", "slow")])
        assert not refused.successful
        assert "read-only" in refused.reason
        assert ctx.spin_until(
            lambda: any(
                e.node == "/srv/server" and [p.name for p in e.changed_parameters] == ["gain"]
                for e in events
            ),
            10.0,
        )
