"""The WebSocket side of the Foxglove server: one asyncio loop on its own thread.

:class:`WebSocketServer` accepts connections offering ``foxglove.websocket.v1`` or
``foxglove.sdk.v1`` (a client offering neither is refused with HTTP 400, as foxglove_bridge
does), parses every frame with :func:`~visnav.bridge.foxglove.protocol.parse_client_message`
and hands the result to a handler; a malformed frame is answered with an error ``status``
and the connection stays open. Sending is thread-safe: graph callbacks call
:meth:`ClientConnection.send` from the executor, which queues the frame for the loop.

Each client has a send buffer bounded by ``send_buffer_limit`` bytes (foxglove_bridge's
parameter, default 10 MB): a message that does not fit is dropped and counted, so a slow
client (a browser over Wi-Fi) never makes the graph wait or the server's memory grow.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import threading
from collections.abc import Callable
from typing import Any, Protocol

from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.exceptions import ConnectionClosed
from websockets.typing import Subprotocol

from visnav.bridge.foxglove.errors import FoxgloveError, FoxgloveProtocolError
from visnav.bridge.foxglove.protocol import (
    SUBPROTOCOLS,
    ClientMessage,
    json_text,
    parse_client_message,
)

__all__ = ["ClientConnection", "ClientHandler", "WebSocketServer"]

_log = logging.getLogger("visnav.foxglove")
_STATUS_ERROR = 2
_STATUS_WARNING = 1
_CLOSE_TIMEOUT_S = 2.0
MAX_CLIENT_FRAME = 64 << 20
"""Largest frame a client may send (64 MiB: a published image fits)."""


class ClientHandler(Protocol):
    """What the server calls (on its loop thread) for each client event."""

    def on_connect(self, client: ClientConnection) -> None:
        """A client connected (its serverInfo is sent already)."""

    def on_message(self, client: ClientConnection, message: ClientMessage) -> None:
        """A parsed client message; may raise a VisnavError (sent to the client as a status)."""

    def on_disconnect(self, client: ClientConnection) -> None:
        """The client is gone."""


class ClientConnection:
    """One connected client: its send queue and its per-client state.

    Attributes:
        id: a number unique in this server.
        address: ``host:port`` of the peer.
        subprotocol: the subprotocol agreed on.
        dropped: messages dropped because the send buffer was full.
        state: handler-owned per-client data.
    """

    def __init__(
        self,
        ws: ServerConnection,
        loop: asyncio.AbstractEventLoop,
        client_id: int,
        *,
        send_buffer_limit: int,
    ) -> None:
        self._ws = ws
        self._loop = loop
        self._queue: asyncio.Queue[str | bytes | None] = asyncio.Queue()
        self._limit = send_buffer_limit
        self._pending = 0
        self._lock = threading.Lock()
        self._closed = False
        self.id = client_id
        peer = ws.remote_address
        self.address = f"{peer[0]}:{peer[1]}" if peer else "?"
        self.subprotocol = str(ws.subprotocol or "")
        self.dropped = 0
        self.sent = 0
        self.state: dict[str, Any] = {}

    @property
    def pending_bytes(self) -> int:
        """Bytes queued for this client and not yet written to its socket."""
        return self._pending

    def send(self, frame: str | bytes, *, droppable: bool = True) -> bool:
        """Queue a frame for the client (any thread).

        Args:
            frame: a JSON text or a binary frame.
            droppable: message data may be dropped when the send buffer is full; control
                messages (advertise, status, responses) are always queued.

        Returns:
            False if the frame was dropped (buffer full, or the client is gone).
        """
        size = len(frame)
        with self._lock:
            if self._closed:
                return False
            if droppable and self._pending and self._pending + size > self._limit:
                self.dropped += 1
                return False
            self._pending += size
        try:
            self._loop.call_soon_threadsafe(self._queue.put_nowait, frame)
        except RuntimeError:  # the loop is closed: the server is stopping
            return False
        return True

    def send_json(self, obj: dict[str, Any]) -> None:
        """Queue a JSON message (never dropped)."""
        self.send(json_text(obj), droppable=False)

    def status(self, level: int, text: str) -> None:
        """Queue a ``status`` message (0 info, 1 warning, 2 error)."""
        self.send_json({"op": "status", "level": level, "message": text})

    async def _sender(self) -> None:
        while True:
            frame = await self._queue.get()
            if frame is None:
                return
            try:
                await self._ws.send(frame)
                self.sent += 1
            finally:
                with self._lock:
                    self._pending -= len(frame)

    def _close(self) -> None:
        with self._lock:
            self._closed = True
        self._queue.put_nowait(None)


class WebSocketServer:
    """Serve the Foxglove WebSocket protocol on ``address:port`` from a thread of its own.

    Args:
        handler: receives client events (on the server's loop thread).
        server_info: the ``serverInfo`` message sent first to every client.
        address: the address to bind (``127.0.0.1``: this machine only).
        port: the TCP port (0: any free port, see :attr:`port`).
        send_buffer_limit: per-client bytes queued before message data is dropped.
        compression: offer permessage-deflate (costly for images; off by default).

    Raises:
        FoxgloveError: (from :meth:`start`) the address cannot be bound.
    """

    def __init__(
        self,
        handler: ClientHandler,
        server_info: dict[str, Any],
        *,
        address: str = "127.0.0.1",
        port: int = 8765,
        send_buffer_limit: int = 10_000_000,
        compression: bool = False,
    ) -> None:
        self._handler = handler
        self._info = server_info
        self.address = address
        self.port = port
        self._limit = send_buffer_limit
        self._compression = compression
        self._loop = asyncio.new_event_loop()
        self._thread: threading.Thread | None = None
        self._server: Server | None = None
        self._ids = itertools.count(1)
        self._clients: dict[int, ClientConnection] = {}
        self._stopped: asyncio.Event | None = None
        self.internal_errors = 0
        """Client messages whose handling raised something other than a VisnavError."""

    @property
    def clients(self) -> list[ClientConnection]:
        """The connected clients."""
        return list(self._clients.values())

    @property
    def url(self) -> str:
        """``ws://address:port`` of the running server."""
        host = f"[{self.address}]" if ":" in self.address else self.address
        return f"ws://{host}:{self.port}"

    def start(self) -> None:
        """Bind and start serving; returns once the port is bound.

        Raises:
            FoxgloveError: the address/port cannot be bound (names them and the fix).
        """
        ready = threading.Event()
        errors: list[OSError] = []
        self._thread = threading.Thread(
            target=self._run, args=(ready, errors), name="foxglove-ws", daemon=True
        )
        self._thread.start()
        ready.wait()
        if errors:
            self._thread.join(timeout=5)
            self._thread = None
            exc = errors[0]
            msg = (
                f"Foxglove server: cannot listen on {self.address}:{self.port} ({exc}); "
                "another server (foxglove_bridge?) may use the port: pick another with "
                "--port / the 'port' parameter, or 0 for any free port"
            )
            raise FoxgloveError(msg) from exc

    def _run(self, ready: threading.Event, errors: list[OSError]) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._main(ready, errors))
            tasks = asyncio.all_tasks(self._loop)
            for task in tasks:  # handlers of clients that did not close in time
                task.cancel()
            if tasks:
                gathered = asyncio.gather(*tasks, return_exceptions=True)
                self._loop.run_until_complete(gathered)
        finally:
            ready.set()
            self._loop.close()

    async def _main(self, ready: threading.Event, errors: list[OSError]) -> None:
        self._stopped = asyncio.Event()
        try:
            self._server = await serve(
                self._serve_client,
                self.address,
                self.port,
                subprotocols=[Subprotocol(s) for s in SUBPROTOCOLS],
                compression="deflate" if self._compression else None,
                max_size=MAX_CLIENT_FRAME,
                max_queue=64,
                close_timeout=_CLOSE_TIMEOUT_S,
            )
        except OSError as exc:
            errors.append(exc)
            return
        sockets = list(self._server.sockets)
        if sockets:
            self.port = int(sockets[0].getsockname()[1])
        ready.set()
        await self._stopped.wait()
        self._server.close(close_connections=True)
        with contextlib.suppress(Exception):
            await asyncio.wait_for(self._server.wait_closed(), timeout=3.0)

    async def _serve_client(self, ws: ServerConnection) -> None:
        client = ClientConnection(ws, self._loop, next(self._ids), send_buffer_limit=self._limit)
        self._clients[client.id] = client
        sender = asyncio.ensure_future(client._sender())
        _log.info("Foxglove client %s connected (%s)", client.address, client.subprotocol)
        try:
            client.send_json(self._info)
            self._call(self._handler.on_connect, client)
            async for frame in ws:
                self._dispatch(client, frame)
        except ConnectionClosed:
            pass
        finally:
            self._clients.pop(client.id, None)
            client._close()
            self._call(self._handler.on_disconnect, client)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, ConnectionClosed):
                await sender
            _log.info("Foxglove client %s disconnected", client.address)

    def _dispatch(self, client: ClientConnection, frame: str | bytes) -> None:
        try:
            message = parse_client_message(frame)
        except FoxgloveProtocolError as exc:
            client.status(_STATUS_ERROR, str(exc))
            return
        self._call(self._handler.on_message, client, message)

    def _call(self, fn: Callable[..., None], client: ClientConnection, *args: Any) -> None:
        from visnav.errors import VisnavError  # noqa: PLC0415 - keep the module light

        try:
            fn(client, *args)
        except VisnavError as exc:
            client.status(_STATUS_WARNING, str(exc))
        except Exception as exc:  # noqa: BLE001 - the server keeps serving: log and tell the client
            self.internal_errors += 1
            _log.exception("Foxglove server: handling a message of %s failed", client.address)
            client.status(_STATUS_ERROR, f"internal error: {type(exc).__name__}: {exc}")

    def call_soon(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` on the server's loop thread (from any thread)."""
        with contextlib.suppress(RuntimeError):
            self._loop.call_soon_threadsafe(fn)

    def stop(self) -> None:
        """Close every connection and stop the thread (idempotent)."""
        thread = self._thread
        if thread is None:
            return
        self._thread = None
        stopped = self._stopped
        if stopped is not None:
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(stopped.set)
        thread.join(timeout=5.0)
