"""Fixtures of the Foxglove server tests: a spun graph context and a server on a free port."""

from __future__ import annotations

import asyncio
import json
import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from websockets.asyncio.client import ClientConnection, connect

from visnav.bridge.foxglove import FoxgloveOptions, FoxgloveServer
from visnav.graph import Context, Node


class Spun:
    """A context spun on a thread (as ``visnav foxglove`` spins its own)."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            self.ctx.spin_once(0.02)

    def stop(self) -> None:
        self._stop.set()
        self.ctx.wake()
        self._thread.join(timeout=5)


@pytest.fixture
def graph() -> Iterator[Spun]:
    """An in-process graph, spun on a thread."""
    ctx = Context(transport="local")
    spun = Spun(ctx)
    yield spun
    spun.stop()
    ctx.shutdown()


@pytest.fixture
def make_server(graph: Spun) -> Iterator[Callable[..., FoxgloveServer]]:
    """Start a Foxglove server on a free port of 127.0.0.1 (closed at the end)."""
    servers: list[FoxgloveServer] = []

    def make(*, use_sim_time: bool = False, **options: Any) -> FoxgloveServer:
        node = Node(f"foxglove_bridge{len(servers)}", context=graph.ctx, use_sim_time=use_sim_time)
        server = FoxgloveServer(node, FoxgloveOptions(**{"port": 0, **options}))
        server.start()
        servers.append(server)
        return server

    yield make
    for server in servers:
        server.close()


async def recv_json(ws: ClientConnection, op: str, timeout: float = 5.0) -> dict[str, Any]:
    """The next JSON message with ``op`` (other frames are skipped)."""
    async with asyncio.timeout(timeout):
        while True:
            frame = await ws.recv()
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get("op") == op:
                    return dict(msg)


async def recv_binary(ws: ClientConnection, opcode: int, timeout: float = 5.0) -> bytes:
    """The next binary frame with ``opcode``."""
    async with asyncio.timeout(timeout):
        while True:
            frame = await ws.recv()
            if isinstance(frame, bytes) and frame[:1] == bytes([opcode]):
                return frame


async def channels_until(
    ws: ClientConnection, topics: set[str], timeout: float = 5.0
) -> dict[str, dict[str, Any]]:
    """Collect advertised channels until every topic of ``topics`` is among them."""
    found: dict[str, dict[str, Any]] = {}
    async with asyncio.timeout(timeout):
        while not topics <= found.keys():
            msg = await recv_json(ws, "advertise", timeout)
            for ch in msg["channels"]:
                found[ch["topic"]] = ch
    return found


def client(url: str, subprotocol: str = "foxglove.websocket.v1") -> Any:
    """A websockets client context offering only ``subprotocol``."""
    return connect(url, subprotocols=[subprotocol], max_size=None)  # type: ignore[list-item]
