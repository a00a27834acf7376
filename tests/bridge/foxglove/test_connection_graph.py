"""The ``connectionGraph`` capability: a whole graph on subscribe, then what changes."""

from __future__ import annotations

import asyncio
import json
import re
from collections.abc import Callable
from typing import Any

import pytest

from visnav.bridge.foxglove import FoxgloveServer, parse_client_message
from visnav.bridge.foxglove.connection_graph import (
    GraphSnapshot,
    full_update,
    graph_snapshot,
    graph_update,
)
from visnav.bridge.foxglove.protocol import SubscribeGraph
from visnav.graph import Context, Node
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type

from .conftest import Spun, client, recv_json

String = get_message_class("std_msgs/msg/String")
ALL = [re.compile(".*")]


def test_snapshot_of_a_graph() -> None:
    with Context(transport="local") as ctx:
        a = Node("talker", namespace="/ns", context=ctx)
        b = Node("listener", context=ctx)
        a.create_publisher(String, "/chatter", 1)
        b.create_subscription(String, "/chatter", lambda _m: None, 1)
        b.create_subscription(String, "/only_subscribed", lambda _m: None, 1)
        a.create_publisher(String, "/_hidden", 1)
        b.create_service(get_service_type("std_srvs/srv/Trigger"), "/reset", lambda _q, r: r)
        snap = graph_snapshot(ctx.graph, topic_whitelist=ALL, service_whitelist=ALL)
        assert snap.published["/chatter"] == ("/ns/talker",)
        assert snap.subscribed["/chatter"] == ("/listener",)
        assert snap.published["/only_subscribed"] == ()
        assert snap.subscribed["/only_subscribed"] == ("/listener",)
        assert "/_hidden" not in snap.published
        assert snap.services["/reset"] == ("/listener",)
        hidden = graph_snapshot(
            ctx.graph, topic_whitelist=ALL, service_whitelist=ALL, include_hidden=True
        )
        assert hidden.published["/_hidden"] == ("/ns/talker",)
        only = graph_snapshot(
            ctx.graph, topic_whitelist=[re.compile("/chat.*")], service_whitelist=[]
        )
        assert set(only.published) == {"/chatter"}
        assert only.services == {}


def test_update_diff_as_foxglove_bridge() -> None:
    old = GraphSnapshot(
        published={"/a": ("/n1",), "/gone": ("/n1",)},
        subscribed={"/a": (), "/gone": ()},
        services={"/s": ("/n2",), "/t": ("/n2",)},
    )
    new = GraphSnapshot(
        published={"/a": ("/n1", "/n3"), "/new": ("/n3",)},
        subscribed={"/a": (), "/new": ("/n1",)},
        services={"/s": ("/n2",)},
    )
    assert graph_update(old, old) is None
    assert graph_update(old, new) == {
        "op": "connectionGraphUpdate",
        "publishedTopics": [
            {"name": "/a", "publisherIds": ["/n1", "/n3"]},
            {"name": "/new", "publisherIds": ["/n3"]},
        ],
        "subscribedTopics": [{"name": "/new", "subscriberIds": ["/n1"]}],
        "advertisedServices": [],
        "removedTopics": ["/gone"],
        "removedServices": ["/t"],
    }
    full = full_update(new)
    assert full["removedTopics"] == []
    assert len(full["publishedTopics"]) == 2
    assert full["advertisedServices"] == [{"name": "/s", "providerIds": ["/n2"]}]


def test_parse_graph_ops() -> None:
    assert parse_client_message('{"op":"subscribeConnectionGraph"}') == SubscribeGraph(True)
    assert parse_client_message('{"op":"unsubscribeConnectionGraph"}') == SubscribeGraph(False)


def _topics(update: dict[str, Any], key: str, ids: str) -> dict[str, list[str]]:
    return {t["name"]: t[ids] for t in update[key]}


def test_server_sends_the_graph_and_its_changes(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    robot = Node("robot", context=graph.ctx)
    robot.create_publisher(String, "/status", 1)
    server = make_server()

    async def go() -> tuple[dict[str, Any], dict[str, Any], dict[str, Any], list[str]]:
        async with client(server.url) as ws:
            await ws.send(json.dumps({"op": "subscribeConnectionGraph"}))
            first = await recv_json(ws, "connectionGraphUpdate")
            pub = robot.create_publisher(String, "/appeared", 1)
            robot.create_service(get_service_type("std_srvs/srv/Trigger"), "/go", lambda _q, r: r)
            second: dict[str, Any] = {"publishedTopics": [], "advertisedServices": []}
            while "/appeared" not in _topics(second, "publishedTopics", "publisherIds"):
                second = await recv_json(ws, "connectionGraphUpdate")
            services = second["advertisedServices"]
            while not services:
                services = (await recv_json(ws, "connectionGraphUpdate"))["advertisedServices"]
            robot.destroy_publisher(pub)
            third = await recv_json(ws, "connectionGraphUpdate")
            while "/appeared" not in third["removedTopics"]:
                third = await recv_json(ws, "connectionGraphUpdate")
            await ws.send(json.dumps({"op": "unsubscribeConnectionGraph"}))
            await ws.send(json.dumps({"op": "unsubscribeConnectionGraph"}))
            status = await recv_json(ws, "status")
            robot.create_publisher(String, "/after", 1)
            later: list[str] = []
            try:
                async with asyncio.timeout(1.0):
                    while True:
                        frame = await ws.recv()
                        if isinstance(frame, str):
                            later.append(json.loads(frame)["op"])
            except TimeoutError:
                pass
            return first, second, {"services": services, "status": status}, later

    first, second, rest, later = asyncio.run(go())
    assert first["removedTopics"] == []
    assert first["removedServices"] == []
    assert _topics(first, "publishedTopics", "publisherIds")["/status"] == ["/robot"]
    assert _topics(second, "publishedTopics", "publisherIds")["/appeared"] == ["/robot"]
    assert "/status" not in _topics(second, "publishedTopics", "publisherIds")  # unchanged
    assert {"name": "/go", "providerIds": ["/robot"]} in rest["services"]
    assert "not subscribed" in rest["status"]["message"]
    assert "connectionGraphUpdate" not in later  # unsubscribed: no more updates
    assert "advertise" in later  # the channel is advertised all the same


def test_two_subscribers_each_get_the_whole_graph_first(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    robot = Node("robot2", context=graph.ctx)
    robot.create_publisher(String, "/one", 1)
    server = make_server()

    async def go() -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        async with client(server.url) as a, client(server.url) as b:
            await a.send(json.dumps({"op": "subscribeConnectionGraph"}))
            first_a = await recv_json(a, "connectionGraphUpdate")
            robot.create_publisher(String, "/two", 1)
            await asyncio.sleep(0.6)
            await b.send(json.dumps({"op": "subscribeConnectionGraph"}))
            first_b = await recv_json(b, "connectionGraphUpdate")
            upd = await recv_json(a, "connectionGraphUpdate")
            return first_a, first_b, upd

    first_a, first_b, upd = asyncio.run(go())
    assert "/two" not in _topics(first_a, "publishedTopics", "publisherIds")
    assert _topics(first_b, "publishedTopics", "publisherIds")["/two"] == ["/robot2"]
    assert _topics(upd, "publishedTopics", "publisherIds") == {"/two": ["/robot2"]}


@pytest.mark.parametrize("caps", [("clientPublish",)])
def test_graph_capability_off(make_server: Callable[..., FoxgloveServer], caps: tuple[str]) -> None:
    server = make_server(capabilities=caps)

    async def go() -> dict[str, Any]:
        async with client(server.url) as ws:
            await ws.send(json.dumps({"op": "subscribeConnectionGraph"}))
            return await recv_json(ws, "status")

    assert "'connectionGraph' capability" in asyncio.run(go())["message"]
