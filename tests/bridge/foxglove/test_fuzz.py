"""Fuzzing the server's handling of client frames: only visnav errors, and it keeps serving."""

from __future__ import annotations

import asyncio
import json
import struct
from collections.abc import Callable
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.bridge.foxglove import FoxgloveProtocolError, FoxgloveServer, parse_client_message
from visnav.graph import Node
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type

from .conftest import Spun, client

OPS = [
    "subscribe",
    "unsubscribe",
    "advertise",
    "unadvertise",
    "getParameters",
    "setParameters",
    "subscribeParameterUpdates",
    "unsubscribeParameterUpdates",
    "subscribeConnectionGraph",
    "unsubscribeConnectionGraph",
    "fetchAsset",
    "nonsense",
]
FIELDS = [
    "subscriptions",
    "subscriptionIds",
    "channels",
    "channelIds",
    "parameterNames",
    "parameters",
    "id",
    "channelId",
    "topic",
    "encoding",
    "schemaName",
    "schema",
    "name",
    "value",
    "type",
    "uri",
    "requestId",
]
_scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**40), 2**40),
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from(["cdr", "json", "/map", "/x.y", "geometry_msgs/msg/PoseStamped", "float64"]),
    st.sampled_from(
        [
            "package://turtlebot3_description/meshes/bases/burger_base.stl",
            "package://turtlebot3_description/../../../etc/passwd",
            "package://x/%2e%2e/y.stl",
            "file:///etc/passwd",
            "file:///dev/zero",
        ]
    ),
    st.text(max_size=12),
)
_json = st.recursive(
    _scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(st.sampled_from(FIELDS), inner, max_size=5),
    ),
    max_leaves=20,
)
_op_objects = st.builds(
    lambda op, rest: json.dumps({"op": op, **rest}),
    st.sampled_from(OPS),
    st.dictionaries(st.sampled_from(FIELDS), _json, max_size=5),
)
_binary = st.one_of(
    st.binary(max_size=64),
    st.builds(
        lambda op, a, b, tail: bytes([op]) + struct.pack("<II", a, b) + tail,
        st.sampled_from([1, 2, 3]),
        st.integers(0, 2**32 - 1),
        st.integers(0, 40),
        st.binary(max_size=48),
    ),
    # valid-looking publish on client channels 0..3 with random CDR
    st.builds(
        lambda cid, tail: b"\x01" + struct.pack("<I", cid) + b"\x00\x01\x00\x00" + tail,
        st.integers(0, 3),
        st.binary(max_size=64),
    ),
)
FRAMES = st.one_of(_op_objects, _binary, st.text(max_size=40), _json.map(json.dumps))


@settings(max_examples=50, deadline=None)
@given(FRAMES)
def test_parser_raises_only_protocol_errors(frame: str | bytes) -> None:
    try:
        parse_client_message(frame)
    except FoxgloveProtocolError as exc:
        text = str(exc)
    else:
        return
    assert text.startswith("client message ")


# frames that set up state for the random ones to hit: advertised client channels and
# subscriptions, a service call on service ids 1..40
_SETUP = [
    json.dumps(
        {
            "op": "advertise",
            "channels": [
                {
                    "id": 0,
                    "topic": "/fz/goal",
                    "encoding": "cdr",
                    "schemaName": "geometry_msgs/msg/PoseStamped",
                },
                {
                    "id": 1,
                    "topic": "/fz/json",
                    "encoding": "json",
                    "schemaName": "geometry_msgs/msg/Twist",
                },
            ],
        }
    ),
    json.dumps(
        {"op": "subscribe", "subscriptions": [{"id": i, "channelId": i} for i in range(1, 20)]}
    ),
]


@settings(
    max_examples=15,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(st.lists(FRAMES, min_size=1, max_size=25))
def test_server_keeps_serving_whatever_clients_send(
    graph: Spun, make_server: Callable[..., FoxgloveServer], frames: list[str | bytes]
) -> None:
    server = getattr(graph, "fuzz_server", None)
    if server is None:
        node = Node("fz", context=graph.ctx)
        node.declare_parameter("gain", 1.0)
        node.create_publisher(get_message_class("std_msgs/msg/String"), "/fz/chatter", 1)

        def answer(_req: Any, resp: Any) -> Any:
            return resp

        node.create_service(get_service_type("std_srvs/srv/Trigger"), "/fz/trigger", answer)
        server = make_server(service_timeout_s=0.5)
        graph.fuzz_server = server  # type: ignore[attr-defined]

    async def go() -> list[dict[str, Any]]:
        statuses: list[dict[str, Any]] = []
        async with client(server.url) as ws:
            for frame in [*_SETUP, *frames]:
                await ws.send(frame)
            ask = {"op": "getParameters", "parameterNames": ["/fz.gain"], "id": "alive"}
            await ws.send(json.dumps(ask))
            async with asyncio.timeout(10):
                while True:
                    raw = await ws.recv()
                    if not isinstance(raw, str):
                        continue
                    msg = json.loads(raw)
                    if msg.get("op") == "status":
                        statuses.append(msg)
                    if msg.get("op") == "parameterValues" and msg.get("id") == "alive":
                        assert msg["parameters"] == [
                            {"name": "/fz.gain", "value": 1.0, "type": "float64"}
                        ]
                        return statuses

    statuses = asyncio.run(go())
    internal = [s["message"] for s in statuses if "internal error" in s["message"]]
    assert internal == []
    server._graph_worker.submit(lambda: None).result(timeout=10)  # what was queued has run
    assert server.ws.internal_errors == 0
