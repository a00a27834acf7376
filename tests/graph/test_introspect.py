"""new_published_topics: the scan tools use to take every topic as it appears."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from visnav.graph import Context, Node
from visnav.graph.introspect import new_published_topics, subscription_qos_for
from visnav.graph.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_latched
from visnav.msgs import String


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def test_only_published_unknown_visible_topics(ctx: Context) -> None:
    app = Node("app", context=ctx)
    app.create_publisher(String, "/chatter", 10)
    app.create_subscription(String, "/only_subscribed", lambda m: None, 10)
    app.create_publisher(String, "/_hidden/x", 10)
    tool = Node("_visnav_tool", context=ctx)
    tool.create_publisher(String, "/from_tool", 10)

    names = [t.name for t in new_published_topics(ctx, set())]
    assert "/chatter" in names
    assert "/from_tool" in names
    assert "/only_subscribed" not in names
    assert "/_hidden/x" not in names
    assert "/chatter" not in [t.name for t in new_published_topics(ctx, {"/chatter"})]
    assert "/_hidden/x" in [t.name for t in new_published_topics(ctx, (), include_hidden=True)]
    no_tools = [t.name for t in new_published_topics(ctx, (), include_tool_publishers=False)]
    assert "/from_tool" not in no_tools
    assert "/chatter" in no_tools
    (chatter,) = [t for t in new_published_topics(ctx, ()) if t.name == "/chatter"]
    assert chatter.types == ("std_msgs/msg/String",)
    assert [e.node_name for e in chatter.publishers] == ["app"]


def test_subscription_qos_matches_every_publisher(ctx: Context) -> None:
    latched = qos_profile_latched
    best_effort = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    Node("a", context=ctx).create_publisher(String, "/latched", latched)
    qos = subscription_qos_for(ctx, "/latched")
    assert qos.durability is DurabilityPolicy.TRANSIENT_LOCAL
    assert qos.reliability is ReliabilityPolicy.RELIABLE
    Node("b", context=ctx).create_publisher(String, "/latched", best_effort)
    qos = subscription_qos_for(ctx, "/latched")
    assert qos.durability is DurabilityPolicy.VOLATILE
    assert qos.reliability is ReliabilityPolicy.BEST_EFFORT
