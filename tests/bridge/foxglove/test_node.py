"""The ``foxglove_bridge`` node type (launch files) and ``visnav foxglove``."""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys

import pytest

from visnav.bridge.foxglove import FoxgloveBridgeNode, FoxgloveError, FoxgloveParams
from visnav.graph import Context
from visnav.node_registry import resolve_node_class

from .conftest import client, recv_json


def test_registered_with_foxglove_bridge_defaults() -> None:
    assert resolve_node_class("foxglove_bridge") is FoxgloveBridgeNode
    params = FoxgloveParams()
    assert params.port == 8765
    assert params.address == "127.0.0.1"  # visnav servers bind loopback unless asked
    assert params.send_buffer_limit == 10_000_000
    assert params.topic_whitelist == (".*",)
    assert params.max_qos_depth == 25


def test_node_serves_with_its_parameters() -> None:
    with Context(transport="local") as ctx:
        node = FoxgloveBridgeNode(
            context=ctx,
            parameter_overrides={
                "port": 0,
                "topic_whitelist": ["/rosout", "/parameter_events"],
                "capabilities": ["parameters"],
            },
        )
        try:
            assert node.server.url.startswith("ws://127.0.0.1:")
            assert node.server.capabilities == ("parameters",)

            async def go() -> dict[str, object]:
                async with client(node.server.url) as ws:
                    return await recv_json(ws, "serverInfo")

            info = asyncio.run(go())
            assert info["name"] == "/foxglove_bridge"
            assert info["capabilities"] == ["parameters"]
        finally:
            node.destroy_node()
        assert node.server.ws.clients == []


def test_node_refuses_a_bad_capability() -> None:
    with Context(transport="local") as ctx, pytest.raises(FoxgloveError, match="playback"):
        FoxgloveBridgeNode(context=ctx, parameter_overrides={"capabilities": ["playback"]})


@pytest.mark.slow
def test_cli_serves_and_stops(domain: int) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", "foxglove", "--port", "0", "--duration", "3",
         "--wall-time", "--topics", "/nothing"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    assert proc.stdout is not None
    first = proc.stdout.readline()
    url = next(w for w in first.split() if w.startswith("ws://"))
    assert url.startswith("ws://127.0.0.1:")
    assert "wall clock" in first

    async def go() -> dict[str, object]:
        async with client(url) as ws:
            return await recv_json(ws, "serverInfo")

    assert "clientPublish" in asyncio.run(go())["capabilities"]
    assert proc.wait(timeout=20) == 0, proc.stderr.read() if proc.stderr else ""
