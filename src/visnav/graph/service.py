"""Services: a server answers requests, a client calls it (rclpy's Service and Client).

How a call travels
------------------
* **In process** (server and client in one :class:`~visnav.graph.Context`): the
  request object itself goes into the server's queue and the response object comes
  back (no serialization, as topics deliver in process).
* **Between processes** (Zenoh, rmw_zenoh's layout): the server declares a queryable
  on the service key ``<domain>/<name>/<pkg>::srv::dds_::<Name>_/<type hash>`` and a
  liveliness token ``SS``; a client declares a token ``SC`` and sends each request as
  a Zenoh ``get`` whose payload is the request's CDR and whose attachment carries
  rmw_zenoh's sequence number, source timestamp and client GID. The server replies
  with the response's CDR (same attachment layout); when its callback raises, it
  replies with an *error* carrying the exception's text, so the client's future fails
  with a :class:`~visnav.graph.errors.ServiceError` naming the service instead of
  waiting forever (rmw_zenoh's servers send nothing then).

The executor serves requests like messages: each service has its own queue, bounded
by its QoS depth (a request pushed out of a full keep-last queue is answered with an
error, counted in :attr:`Service.dropped`), and takes one request per turn of the
fair ring. An exception in a server callback is answered to the client and then goes
to the fault boundary (logged with node, service and type; the node keeps running).

A request from another process runs no Python on Zenoh's thread: the queryable's
callback is the context's inbox (a ``queue.SimpleQueue``'s ``put``), which also wakes
the executor; the executor routes each query to its service's queue by the query's
key before it takes its next callback, and reads the request (CDR) itself. So a
request that pushes an older one out of a full queue does so, and that caller is
answered, when the executor next takes work. Requests and replies are sent as Zenoh
*express* messages (at once, not held back for batching).

A client's :class:`~visnav.graph.future.Future` completes on the transport's thread,
so :meth:`Client.call` works from any thread that is not running a callback of the
client's own executor (there it would wait for itself: refused with an error); the
future's done callbacks run in the executor. A blocking :meth:`Client.call` to another
process needs no future: the reply waits in a Zenoh channel that the calling thread
reads and decodes itself, so no Python code runs on Zenoh's thread for it. A server
that goes away mid-call ends the Zenoh query without a reply: the future (or call) fails
with "no response" at once, or at the call's timeout at the latest.

Actions build on this module: an action is three services (``send_goal``,
``cancel_goal``, ``get_result``) and two topics, all on one node.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import itertools
import struct
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import zenoh

from visnav.graph.errors import GraphError, ServiceError, ServiceTimeoutError
from visnav.graph.future import Future
from visnav.graph.qos import QoSProfile
from visnav.graph.service_codec import Decoder, Encoder, message_factory
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import serialize
from visnav.msgs.srv import ServiceType

if TYPE_CHECKING:
    from visnav.graph.node import Node

__all__ = [
    "Client",
    "Service",
    "decode_service_attachment",
    "encode_service_attachment",
    "entity_gid",
]

ReqT = TypeVar("ReqT")
RespT = TypeVar("RespT")

_ATTACH = struct.Struct("<qq")
_GID_SIZE = 16
_FOREVER_S = 24 * 3600.0
"""Zenoh query timeout of a call without one (Zenoh needs a finite value)."""


def entity_gid(zid: str, entity_id: int) -> bytes:
    """A 16-byte GID for an entity (rmw's ``source_gid``), stable for its session."""
    return hashlib.blake2b(f"{zid}/{entity_id}".encode(), digest_size=_GID_SIZE).digest()


def encode_service_attachment(sequence: int, source_ns: int, gid: bytes) -> bytes:
    """rmw_zenoh's request/reply attachment: int64 sequence, int64 source time, 16-byte GID.

    Serialized as zenoh-ext does: two little-endian int64, then the GID as a sequence
    (LEB128 length 16, then the bytes).
    """
    return _ATTACH.pack(sequence, source_ns) + bytes([_GID_SIZE]) + gid[:_GID_SIZE]


def decode_service_attachment(data: bytes | None) -> tuple[int, int, bytes] | None:
    """``(sequence, source time ns, gid)`` of :func:`encode_service_attachment`, else None."""
    if data is None or len(data) != _ATTACH.size + 1 + _GID_SIZE or data[_ATTACH.size] != 16:
        return None
    seq, stamp = _ATTACH.unpack_from(data)
    return seq, stamp, bytes(data[_ATTACH.size + 1 :])


def _reply_attachment(request_attachment: bytes | None) -> bytes | None:
    """The reply's attachment: the request's sequence number and GID, a new source time."""
    if (
        request_attachment is None
        or len(request_attachment) != _ATTACH_SIZE
        or request_attachment[_ATTACH.size] != _GID_SIZE
    ):
        return None
    return request_attachment[:8] + _STAMP_PACK(time.time_ns()) + request_attachment[16:]


_ATTACH_SIZE = _ATTACH.size + 1 + _GID_SIZE
_STAMP_PACK = struct.Struct("<q").pack
_BEST_MATCHING = zenoh.QueryTarget.BEST_MATCHING
_NO_CONSOLIDATION = zenoh.ConsolidationMode.NONE
_Callback = zenoh.handlers.Callback


class _Request:
    """A request waiting in a server's queue, with the way back to its caller.

    An in-process request carries the request message and a future; a remote one
    carries only its Zenoh query, whose payload and attachment are read in the
    executor (:meth:`cdr`, :meth:`respond`): the transport's thread only queues it.
    """

    __slots__ = ("future", "payload", "query", "remote")

    def __init__(self, payload: Any, future: Future[Any] | None = None, query: Any = None) -> None:
        self.payload = payload  # the request message (in process), or None (remote)
        self.remote = query is not None
        self.future = future
        self.query = query

    def cdr(self) -> bytes:
        """A remote request's CDR bytes (empty when the query carried no payload)."""
        data = self.payload
        if data is None:
            query = self.query
            payload = query.payload if query is not None else None
            data = self.payload = payload.to_bytes() if payload is not None else b""
        return data  # type: ignore[no-any-return]

    def respond(
        self, response: Any, encode: Callable[[Any], bytes | bytearray] = serialize
    ) -> None:
        if self.future is not None:
            self.future.set_result(response)
            return
        data = encode(response)
        query, self.query = self.query, None
        if query is None:
            return
        try:  # inline rather than through _reply: this is a call's hot path
            att = query.attachment
            query.reply(
                query.key_expr,
                data,
                attachment=_reply_attachment(att.to_bytes()) if att is not None else None,
                express=True,  # sent at once, not held back for batching
            )
        except Exception:  # noqa: BLE001, S110 - the caller went away (timeout, exit)
            pass
        finally:
            query.drop()

    def fail(self, text: str) -> None:
        if self.future is not None:
            self.future.set_exception(ServiceError(text))
            return
        self._reply(lambda q: q.reply_err(text.encode()))

    def _reply(self, send: Callable[[Any], None]) -> None:
        query, self.query = self.query, None
        if query is None:
            return
        try:
            send(query)
        except Exception:  # noqa: BLE001, S110 - the caller went away (timeout, exit)
            pass
        finally:
            query.drop()


class Service(Generic[ReqT, RespT]):
    """Answers requests of one service type; made by :meth:`Node.create_service`.

    ``callback(request, response) -> response`` runs in the executor; ``response`` is
    a fresh default response to fill in (rclpy's convention).

    A visnav addition: the callback may instead return a :class:`~visnav.graph.future.Future`
    (a *deferred response*) and complete it later from any thread, with the response or
    an exception; the caller is answered then, and the executor serves other callbacks
    meanwhile (rclpy gets this from ``async def`` callbacks). The ROS 1 bridge hands slow
    ROS 1 calls to worker threads this way.
    """

    def __init__(
        self,
        node: Node,
        srv_type: ServiceType,
        srv_name: str,
        callback: Callable[[Any, Any], Any],
        qos: QoSProfile,
    ) -> None:
        self.node = node
        self.srv_type = srv_type
        self.srv_name = srv_name
        self.callback = callback
        self.qos = qos
        self.entity_id = node.context.next_id()
        self.queue: deque[_Request] = deque()
        self._queue_limit = qos.queue_limit  # QoSProfile is frozen
        self.dropped = 0
        """Requests pushed out of the full queue (their callers got an error)."""
        self.bad_requests = 0
        """Remote requests that did not decode (answered with an error, logged once)."""
        self._queryable: Any = None
        self._key: str | None = None
        self._deliver = node.context.deliver_request
        self._response_cls = srv_type.Response
        self._new_response = message_factory(srv_type.response_type_name)
        self._decode_request = Decoder(srv_type.request_type_name)
        self._encode_response = Encoder(srv_type.response_type_name)

    @property
    def service_name(self) -> str:
        """The fully qualified service name."""
        return self.srv_name

    def describe(self) -> str:
        """``service '/name' (pkg/srv/Type)`` (for logs)."""
        return f"service '{self.srv_name}' ({self.srv_type.name})"

    # ------------------------------------------------------------------ queue (context lock held)
    def enqueue(self, request: _Request) -> None:
        """Queue a request; a full keep-last queue answers its oldest one with an error."""
        limit = self._queue_limit
        if limit is not None and len(self.queue) >= limit:
            old = self.queue.popleft()
            self.dropped += 1
            old.fail(
                f"{self.describe()} dropped the request: its queue (depth {limit}) was full; "
                "call it less often or create it with a deeper qos_profile"
            )
        self.queue.append(request)

    def pending(self) -> bool:
        """Whether requests wait."""
        return bool(self.queue)

    def take_call(self) -> Callable[[], None] | None:
        """The oldest request as a ready-to-run callback, or None."""
        if not self.queue:
            return None
        return functools.partial(self._serve, self.queue.popleft())

    def _read_request(self, item: _Request) -> Any | None:
        """The request of ``item``; None after answering a payload that does not decode."""
        if not item.remote:
            return item.payload
        try:
            return self._decode_request(item.cdr())
        except MessageError as exc:
            self.bad_requests += 1
            text = f"{self.describe()} could not read the request: {exc}"
            if self.bad_requests == 1:
                self.node.get_logger().warning(f"{text} (further ones are only counted)")
            item.fail(text)
            return None

    def _serve(self, item: _Request) -> None:
        request = self._read_request(item)
        if request is None:
            return
        response = self._new_response()
        try:
            result = self.callback(request, response)
        except Exception as exc:
            item.fail(f"{self.describe()} raised {type(exc).__name__}: {exc}")
            raise
        if type(result) is Future:
            # a deferred response: answered from the thread that completes the future
            result.on_complete(functools.partial(self._finish_deferred, item, result))
            return
        self._answer(item, result)

    def _answer(self, item: _Request, result: Any) -> None:
        """Send ``result`` (what the callback produced) to ``item``'s caller."""
        if type(result) is not self._response_cls:
            got = getattr(result, "__msgtype__", type(result).__name__)
            text = (
                f"{self.describe()}: the callback returned {got}, expected "
                f"{self.srv_type.response_type_name}; return the response it was given"
            )
            item.fail(text)
            raise ServiceError(text)
        try:
            item.respond(result, self._encode_response)
        except MessageError as exc:
            item.fail(f"{self.describe()} could not send its response: {exc}")
            raise

    def _finish_deferred(self, item: _Request, future: Future[Any]) -> None:
        """Answer a deferred call once its future completed (in the completing thread)."""
        exc = future.exception()
        if future.cancelled():
            item.fail(f"{self.describe()} cancelled the call before answering")
            return
        if exc is not None:
            item.fail(f"{self.describe()} raised {type(exc).__name__}: {exc}")
            self._log_deferred(exc)
            return
        try:
            self._answer(item, future.result())
        except Exception as error:  # noqa: BLE001 - answered by _answer; log, as the executor would
            self._log_deferred(error)

    def _log_deferred(self, exc: BaseException) -> None:
        self.node.get_logger().error(
            f"{self.describe()}: its deferred response failed: {type(exc).__name__}: {exc}"
        )

    # ------------------------------------------------------------------ transport
    def attach_transport(self, session: zenoh.Session, key: str) -> None:
        """Declare the queryable that takes requests from other processes.

        Its callback is the context's inbox (:meth:`Context.route_queries`): Zenoh's
        thread only queues the query, running no Python code, and the executor routes
        it to this service by its key.
        """
        ctx = self.node.context
        self._key = key
        self._queryable = session.declare_queryable(
            key,
            # direct: only a queue's put (an indirect handler costs a Python thread each)
            zenoh.handlers.Callback(ctx.route_queries(self, key), indirect=False),
            allowed_origin=zenoh.Locality.REMOTE,
        )

    def accept_query(self, query: Any) -> None:
        """Queue a request from another process (context lock held; see ``enqueue``)."""
        self.enqueue(_Request(None, None, query))

    def _on_query(self, query: Any) -> None:
        """A request from another process that arrived through a shared queryable.

        (A node's parameter services share one queryable, which calls this.) Only
        queued here; it is read in the executor.
        """
        self._deliver(self, _Request(None, None, query))

    def close_transport(self) -> None:
        """Undeclare the queryable; queued remote requests are answered with an error."""
        if self._queryable is not None:
            with contextlib.suppress(Exception):  # the session is already closed
                self._queryable.undeclare()
            self._queryable = None
        if self._key is not None:
            self.node.context.forget_queries(self._key)
            self._key = None

    def destroy(self) -> None:
        """Remove the service."""
        self.node.destroy_service(self)


class Client(Generic[ReqT, RespT]):
    """Calls one service; made by :meth:`Node.create_client`."""

    def __init__(self, node: Node, srv_type: ServiceType, srv_name: str, qos: QoSProfile) -> None:
        self.node = node
        self.srv_type = srv_type
        self.srv_name = srv_name
        self.qos = qos
        self.entity_id = node.context.next_id()
        self._key: str | None = None
        self._session: zenoh.Session | None = None
        self._seq = itertools.count(1)
        self._gid = entity_gid(node.context.zid, self.entity_id)
        self._callbacks: deque[Future[Any]] = deque()
        self._request_cls = srv_type.Request
        self._decode_response = Decoder(srv_type.response_type_name)
        self._encode_request = Encoder(srv_type.request_type_name)
        self._gid_tail = bytes([_GID_SIZE]) + self._gid[:_GID_SIZE]
        self._pending: set[Future[Any]] = set()
        self._lock = threading.Lock()

    @property
    def service_name(self) -> str:
        """The fully qualified service name."""
        return self.srv_name

    def describe(self) -> str:
        """``client of '/name' (pkg/srv/Type)`` (for logs)."""
        return f"client of '{self.srv_name}' ({self.srv_type.name})"

    def attach_transport(self, session: zenoh.Session, key: str) -> None:
        """Use ``session`` to reach servers in other processes on ``key``."""
        self._session = session
        self._key = key

    # ------------------------------------------------------------------ readiness
    def service_is_ready(self) -> bool:
        """Whether a server of this service (and type) is in the graph now."""
        return self.node.context.service_is_ready(self.srv_name, self.srv_type.name)

    def wait_for_service(self, timeout_sec: float | None = None) -> bool:
        """Wait until a server is ready; return False after ``timeout_sec`` (None: forever)."""
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not self.service_is_ready():
            if deadline is not None and time.monotonic() >= deadline:
                return self.service_is_ready()
            if not self.node.context.ok:
                return False
            self.node.context.wait_graph_change(0.05)
        return True

    # ------------------------------------------------------------------ calls
    def call_async(self, request: ReqT, *, timeout_sec: float | None = None) -> Future[RespT]:
        """Send a request; the returned future completes with the response.

        Args:
            request: a ``Request`` of the client's service type.
            timeout_sec: a visnav addition: fail the future with
                :class:`ServiceTimeoutError` when no response came within this time
                (None: only when the server goes away).

        Raises:
            ServiceError: ``request`` is not of the service's request type, or it
                cannot be serialized.
        """
        self._check_request(request)
        future: Future[RespT] = Future(self._dispatch)
        ctx = self.node.context
        local = ctx.local_service(self.srv_name, self.srv_type.name)
        if local is not None:
            ctx.deliver_request(local, _Request(request, future))
            self._watch(future, timeout_sec)
            return future
        if self._session is None or self._key is None:
            future.set_exception(self._no_server())
            return future
        try:
            payload = self._encode_request(request)
        except MessageError as exc:
            raise ServiceError(f"{self.describe()}: {exc}") from exc
        self._send(future, payload, timeout_sec)
        return future

    def _check_request(self, request: Any) -> None:
        if type(request) is not self._request_cls:
            got = getattr(request, "__msgtype__", type(request).__name__)
            msg = (
                f"{self.describe()}: the request is a {got}, expected "
                f"{self.srv_type.request_type_name}; build it with {self.srv_type.name}.Request"
            )
            raise ServiceError(msg)

    def _outcome(self, reply: Any, timeout_sec: float | None) -> Any:
        """The response in a Zenoh reply, or the exception it stands for (returned)."""
        ok = reply.ok
        if ok is None:
            err = reply.err
            text = _text(err.payload) if err is not None else "an error"
            if "Timeout" in text:
                return self._timeout(timeout_sec)
            return ServiceError(f"{self.describe()}: {text}")
        try:
            return self._decode_response(ok.payload.to_bytes())
        except MessageError as exc:
            return ServiceError(f"{self.describe()}: the server's response is unreadable: {exc}")

    def _get(self, payload: bytes | bytearray, handler: Any, timeout_sec: float | None) -> Any:
        """Send one request as a Zenoh ``get`` with rmw_zenoh's attachment."""
        # encode_service_attachment(seq, now, gid), with the GID part made once
        att = _ATTACH.pack(next(self._seq), time.time_ns()) + self._gid_tail
        session, key = self._session, self._key
        if session is None or key is None:  # pragma: no cover - checked by the callers
            raise self._no_server()
        return session.get(
            key,
            handler,
            payload=payload,
            attachment=att,
            target=_BEST_MATCHING,
            consolidation=_NO_CONSOLIDATION,
            express=True,  # sent at once, not held back for batching
            timeout=timeout_sec if timeout_sec is not None else _FOREVER_S,
        )

    def _send(
        self, future: Future[RespT], payload: bytes | bytearray, timeout_sec: float | None
    ) -> None:
        got = [False]

        def on_reply(reply: Any) -> None:
            if got[0]:
                return
            got[0] = True
            outcome = self._outcome(reply, timeout_sec)
            if isinstance(outcome, BaseException):
                future.set_exception(outcome)
            else:
                future.set_result(outcome)

        def on_done() -> None:
            if not got[0]:
                if timeout_sec is not None and time.monotonic() >= deadline - 0.01:
                    future.set_exception(self._timeout(timeout_sec))
                else:
                    future.set_exception(self._no_server(mid_call=True))

        deadline = time.monotonic() + (timeout_sec if timeout_sec is not None else _FOREVER_S)
        # direct: the handlers only decode and complete the future (indirect costs a Python
        # thread per call)
        self._get(payload, _Callback(on_reply, on_done, indirect=False), timeout_sec)

    def _watch(self, future: Future[RespT], timeout_sec: float | None) -> None:
        """Fail an in-process call's future at its timeout."""
        if timeout_sec is None:
            return
        timer = threading.Timer(
            timeout_sec, lambda: future.set_exception(self._timeout(timeout_sec))
        )
        timer.daemon = True
        future.on_complete(timer.cancel)
        timer.start()

    def _timeout(self, timeout_sec: float | None) -> ServiceTimeoutError:
        return ServiceTimeoutError(
            f"{self.describe()}: no response within {timeout_sec:g} s; is the server busy "
            "or stuck? (raise timeout_sec, or check the server's node)"
        )

    def _no_server(self, *, mid_call: bool = False) -> ServiceError:
        if mid_call:
            return ServiceError(
                f"{self.describe()}: no response: the server went away before answering "
                "(or none was running; call wait_for_service first)"
            )
        return ServiceError(
            f"{self.describe()}: no server is running in this process and the context is "
            "local-only; start the server, or use the Zenoh transport"
        )

    def call(self, request: ReqT, timeout_sec: float | None = None) -> RespT:
        """Send a request and block until its response (rclpy's ``Client.call``).

        Call it from another thread than the one spinning the client's context: from
        inside a callback of that context the in-process server could never run.

        Raises:
            GraphError: called from inside a callback of the client's own executor.
            ServiceTimeoutError: no response within ``timeout_sec`` (a TimeoutError).
            ServiceError: the server raised (its text), went away, or replied garbage.
        """
        if self.node.context.in_callback():
            msg = (
                f"{self.describe()}: call() from inside a callback of the same executor "
                "would wait for itself; use call_async() with add_done_callback(), or call "
                "from another thread"
            )
            raise GraphError(msg)
        ctx = self.node.context
        if (
            self._session is not None
            and ctx.local_service(self.srv_name, self.srv_type.name) is None
        ):
            return self._call_remote(request, timeout_sec)  # type: ignore[no-any-return]
        future = self.call_async(request, timeout_sec=timeout_sec)
        if not future.wait(timeout_sec):
            future.cancel()
            raise self._timeout(timeout_sec)
        exc = future.exception()
        if exc is not None:
            raise exc
        return future.result()  # type: ignore[return-value]  # done without exception

    def _call_remote(self, request: Any, timeout_sec: float | None) -> Any:
        """``call()`` to another process: the reply waits in a Zenoh channel for this thread.

        No Python runs on Zenoh's thread (a channel rather than a callback completing a
        future): the caller takes the reply and decodes it itself.
        """
        self._check_request(request)
        try:
            payload = self._encode_request(request)
        except MessageError as exc:
            raise ServiceError(f"{self.describe()}: {exc}") from exc
        deadline = time.monotonic() + (timeout_sec if timeout_sec is not None else _FOREVER_S)
        replies = self._get(payload, None, timeout_sec)  # None: Zenoh's default FIFO channel
        try:
            reply = replies.recv()  # a Ctrl-C interrupts it
        except zenoh.ZError:  # closed without a reply: no server, or it went away
            if timeout_sec is not None and time.monotonic() >= deadline - 0.01:
                raise self._timeout(timeout_sec) from None
            raise self._no_server(mid_call=True) from None
        outcome = self._outcome(reply, timeout_sec)
        if isinstance(outcome, BaseException):
            raise outcome
        return outcome

    # ------------------------------------------------------------------ executor entity
    def _dispatch(self, future: Future[Any]) -> None:
        """Run ``future``'s done callbacks in the executor."""
        ctx = self.node.context
        with ctx.lock:
            self._callbacks.append(future)
        ctx.notify_ready(self)

    def pending(self) -> bool:
        """Whether done callbacks wait."""
        return bool(self._callbacks)

    def take_call(self) -> Callable[[], None] | None:
        """The next completed future's done callbacks, or None."""
        if not self._callbacks:
            return None
        return self._callbacks.popleft().run_callbacks

    def remove_pending_request(self, future: Future[Any]) -> None:
        """Stop waiting for ``future`` (rclpy's name): it is cancelled."""
        future.cancel()

    def destroy(self) -> None:
        """Remove the client."""
        self.node.destroy_client(self)


def _text(payload: Any) -> str:
    try:
        data = payload.to_bytes() if hasattr(payload, "to_bytes") else bytes(payload)
        return data.decode("utf-8", errors="replace") or "an empty error"
    except Exception:  # noqa: BLE001 - a foreign error payload
        return "an unreadable error"
