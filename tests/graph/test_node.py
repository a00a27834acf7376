from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from visnav.graph import (
    Context,
    InvalidNameError,
    Node,
    QoSProfile,
    ReliabilityPolicy,
    TopicTypeConflictError,
)
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import Clock, Image, String, Twist, make, ns_to_time


@pytest.fixture
def ctx() -> Any:
    with Context(transport="local") as c:
        yield c


def test_in_process_delivery_is_zero_copy(ctx: Context) -> None:
    a, b = Node("a", context=ctx), Node("b", context=ctx)
    got: list[Any] = []
    pub = a.create_publisher(Image, "image", 1)
    b.create_subscription(Image, "image", got.append, 1)
    img = make(Image, height=1, width=1, encoding="mono8", step=1, data=np.zeros(1, np.uint8))
    pub.publish(img)
    assert ctx.spin_once(0) is True
    assert got[0] is img


def test_namespaces_private_names_and_remapping(ctx: Context) -> None:
    n = Node("cam", context=ctx, namespace="/robot", remappings={"image": "/other/image"})
    assert n.get_fully_qualified_name() == "/robot/cam"
    assert n.resolve_topic_name("image") == "/other/image"
    assert n.resolve_topic_name("info") == "/robot/info"
    assert n.resolve_topic_name("~/debug") == "/robot/cam/debug"
    assert n.resolve_topic_name("/abs") == "/abs"
    m = Node("x", context=ctx, remappings=["__ns:=/drone", "__node:=y"])
    assert m.get_fully_qualified_name() == "/drone/y"
    with pytest.raises(InvalidNameError):
        n.create_publisher(String, "bad//name", 10)


def test_second_type_on_topic_is_refused(ctx: Context) -> None:
    n = Node("n", context=ctx)
    n.create_publisher(String, "/t", 10)
    with pytest.raises(TopicTypeConflictError, match=r"msg/String.*geometry_msgs/msg/Twist"):
        n.create_publisher(Twist, "/t", 10)
    pub = n.create_publisher(String, "/t", 10)
    with pytest.raises(TopicTypeConflictError, match="was given geometry_msgs/msg/Twist"):
        pub.publish(make(Twist))  # type: ignore[arg-type]


def test_keep_last_depth_drops_oldest(ctx: Context) -> None:
    n = Node("n", context=ctx)
    got: list[str] = []
    pub = n.create_publisher(String, "/t", 10)
    n.create_subscription(String, "/t", lambda m: got.append(m.data), 2)
    for i in range(5):
        pub.publish(String(data=str(i)))
    ctx.spin_some()
    assert got == ["3", "4"]


def test_transient_local_late_joiner_and_incompatible_qos(ctx: Context) -> None:
    n = Node("n", context=ctx)
    latched = qos_profile_latched
    pub = n.create_publisher(String, "/latched", latched)
    pub.publish(String(data="old"))
    pub.publish(String(data="map"))
    late: list[str] = []
    volatile: list[str] = []
    n.create_subscription(String, "/latched", lambda m: late.append(m.data), latched)
    n.create_subscription(String, "/latched", lambda m: volatile.append(m.data), 10)
    ctx.spin_some()
    assert late == ["map"]
    assert volatile == []
    best_effort = QoSProfile(reliability=ReliabilityPolicy.BEST_EFFORT)
    be_pub = n.create_publisher(String, "/be", best_effort)
    rel: list[str] = []
    n.create_subscription(String, "/be", lambda m: rel.append(m.data), 10)
    be_pub.publish(String(data="x"))
    ctx.spin_some()
    assert rel == []  # best-effort publisher cannot feed a reliable subscription


def test_sim_time_timers_fire_in_sim_time(ctx: Context) -> None:
    sim = Node("sim", context=ctx)
    clock_pub = sim.create_publisher(Clock, "/clock", 10)
    user = Node("user", context=ctx, use_sim_time=True)
    fired: list[int] = []
    user.create_timer(0.1, lambda: fired.append(user.get_clock().now_ns()))
    for step in range(1, 26):  # 25 steps of 20 ms = 0.5 s of sim time
        clock_pub.publish(Clock(clock=ns_to_time(step * 20_000_000)))
        ctx.spin_some()
    assert fired == [100_000_000, 200_000_000, 300_000_000, 400_000_000, 500_000_000]


def test_executor_order_is_deterministic() -> None:
    def run() -> list[str]:
        out: list[str] = []
        with Context(transport="local") as c:
            sim = Node("sim", context=c)
            clock_pub = sim.create_publisher(Clock, "/clock", 10)
            n = Node("n", context=c, use_sim_time=True)
            p1 = n.create_publisher(String, "a", 10)
            p2 = n.create_publisher(String, "b", 10)
            n.create_subscription(String, "a", lambda m: out.append("a" + m.data), 10)
            n.create_subscription(String, "b", lambda m: out.append("b" + m.data), 10)
            n.create_timer(0.05, lambda: (p2.publish(String(data="t")), out.append("T")))
            for k in range(1, 11):
                clock_pub.publish(Clock(clock=ns_to_time(k * 10_000_000)))
                p1.publish(String(data=str(k)))
                c.spin_some()
        return out

    first = run()
    assert first == run()
    assert first.count("T") == 2
    assert first.index("T") < first.index("bt")


def test_parameters_and_use_sim_time_on_node(ctx: Context) -> None:
    n = Node("n", context=ctx, parameter_overrides={"scan_height": 10})
    assert n.declare_parameter("scan_height", 1).value == 10
    assert n.get_parameter("use_sim_time").value is False
    assert not n.get_clock().ros_time_is_active
    from visnav.graph import Parameter

    n.set_parameters([Parameter("use_sim_time", value=True)])
    assert n.get_clock().ros_time_is_active
    assert n.count_subscribers("/clock") == 1


def test_graph_queries_and_destroy(ctx: Context) -> None:
    n = Node("n", context=ctx, namespace="/ns")
    n.create_publisher(String, "chatter", 10)
    sub = n.create_subscription(String, "chatter", lambda m: None, 10)
    assert ("/ns/chatter", ["std_msgs/msg/String"]) in n.get_topic_names_and_types()
    assert n.count_publishers("chatter") == 1
    assert n.count_subscribers("/ns/chatter") == 1
    info = n.get_publishers_info_by_topic("chatter")[0]
    assert (info.node_name, info.node_namespace, info.depth) == ("n", "/ns", 10)
    sub.destroy()
    assert n.count_subscribers("chatter") == 0
    n.destroy_node()
    assert n.get_node_names() == []


def test_wall_timer_period(ctx: Context) -> None:
    n = Node("n", context=ctx)
    ticks: list[int] = []
    n.create_timer(0.01, lambda: ticks.append(1))
    ctx.spin_until(lambda: len(ticks) >= 5, 2.0)
    assert len(ticks) >= 5
