"""Services across the bridge, both ways.

* **visnav -> ROS 1:** every visnav service server whose type crosses
  (:func:`~visnav.bridge.srvmap.ros1_service_type`) is registered with the ROS 1 master
  (``registerService``); a ROS 1 call (``rosservice call``, ``rospy.ServiceProxy``) is
  decoded on its TCPROS thread, made with a visnav client, and answered with the response
  or with the visnav error's text (ok byte 0).
* **ROS 1 -> visnav:** a service that a visnav *client* calls, that no visnav server
  provides and that the ROS 1 master lists gets a visnav server on the bridge node; its
  callback calls the ROS 1 provider (``lookupService`` then TCPROS) and returns its
  response, or fails with the ROS 1 error text. The ROS 1 call runs on a worker thread
  (at most :data:`MAX_CONCURRENT_CALLS` at once, :data:`MAX_PENDING_CALLS` waiting or
  running; more are refused with an error at once): the callback returns a deferred
  response (a :class:`~visnav.graph.future.Future`), so a ROS 1 service that takes
  seconds holds neither the bridge's executor (its topics, other services and scans go
  on) nor other calls.

The bridge never re-exports what it serves itself, so a service does not loop.
"""

from __future__ import annotations

import concurrent.futures
import functools
import logging
import threading
from collections.abc import Callable
from typing import Any

from visnav.bridge.errors import BridgeError, UnconvertibleTypeError
from visnav.bridge.ros1_node import Ros1Node
from visnav.bridge.srvmap import ROS2_ONLY_PACKAGES, Ros1ServiceType, decode_part, encode_part
from visnav.bridge.srvmap import ros1_service_type as _service_type
from visnav.bridge.tcpros_service import call_service
from visnav.graph import Node
from visnav.graph.future import Future
from visnav.graph.service import Client, Service

__all__ = ["MAX_CONCURRENT_CALLS", "MAX_PENDING_CALLS", "CallPool", "ServiceBridge"]

_log = logging.getLogger("visnav.bridge")

MAX_CONCURRENT_CALLS = 8
"""ROS 1 service calls the bridge makes at once (each on a worker thread)."""
MAX_PENDING_CALLS = 64
"""ROS 1 service calls running or waiting for a worker; further ones fail at once."""


class CallPool:
    """Runs blocking calls on a few worker threads and completes visnav futures with them.

    Args:
        workers: calls run at once.
        max_pending: calls running or waiting; :meth:`submit` fails the future of any
            further one at once (:class:`BridgeError`) rather than queueing without bound.
    """

    def __init__(
        self, *, workers: int = MAX_CONCURRENT_CALLS, max_pending: int = MAX_PENDING_CALLS
    ) -> None:
        self.workers = workers
        self.max_pending = max_pending
        self._pool = concurrent.futures.ThreadPoolExecutor(
            max_workers=workers, thread_name_prefix="bridge-service"
        )
        self._lock = threading.Lock()
        self._pending: set[Future[Any]] = set()
        self._closed = False

    @property
    def pending(self) -> int:
        """Calls running or waiting for a worker."""
        with self._lock:
            return len(self._pending)

    def submit(self, call: Callable[[], Any], *, what: str) -> Future[Any]:
        """Run ``call()`` on a worker; the returned future completes with its outcome."""
        future: Future[Any] = Future()
        with self._lock:
            if self._closed:
                refused = f"{what}: the bridge is shutting down"
            elif len(self._pending) >= self.max_pending:
                refused = (
                    f"{what}: the bridge already has {len(self._pending)} calls to ROS 1 "
                    f"services in flight (at most {self.max_pending}); retry later"
                )
            else:
                refused = ""
                self._pending.add(future)
        if refused:
            future.set_exception(BridgeError(refused))
            return future
        try:
            self._pool.submit(self._run, future, call)
        except RuntimeError:  # closed between the check and here
            with self._lock:
                self._pending.discard(future)
            future.set_exception(BridgeError(f"{what}: the bridge is shutting down"))
        return future

    def _run(self, future: Future[Any], call: Callable[[], Any]) -> None:
        try:
            result = call()
        except Exception as exc:  # noqa: BLE001 - handed to the caller
            future.set_exception(exc)
        else:
            future.set_result(result)
        finally:
            with self._lock:
                self._pending.discard(future)

    def close(self) -> None:
        """Fail the calls still waiting or running; stop the workers (without waiting)."""
        with self._lock:
            self._closed = True
            pending, self._pending = list(self._pending), set()
        for future in pending:
            future.set_exception(
                BridgeError("the bridge stopped before the ROS 1 service answered")
            )
        self._pool.shutdown(wait=False, cancel_futures=True)


class ServiceBridge:
    """Keeps the services of one visnav node and one ROS 1 node in step (see the module).

    Args:
        node: the bridge's visnav node.
        ros1: the bridge's ROS 1 node.
        selected: ``selected(name) -> bool``, the ``--services`` / ``--exclude`` choice.
        timeout_s: the longest a call through the bridge may take, each way.
    """

    def __init__(
        self, node: Node, ros1: Ros1Node, *, selected: Any, timeout_s: float = 10.0
    ) -> None:
        self.node = node
        self.ros1 = ros1
        self.selected = selected
        self.timeout_s = timeout_s
        self._fqn = node.get_fully_qualified_name()
        self._out: dict[str, Client[Any, Any]] = {}
        self._in: dict[str, Service[Any, Any]] = {}
        self._refused: set[tuple[str, str]] = set()
        self.calls = CallPool()
        """Where calls to ROS 1 services run (off the executor)."""

    def out_services(self) -> list[str]:
        """Services bridged visnav -> ROS 1."""
        return sorted(self._out)

    def in_services(self) -> list[str]:
        """Services bridged ROS 1 -> visnav."""
        return sorted(self._in)

    def _convertible(self, name: str, type_name: str) -> Ros1ServiceType | None:
        try:
            return _service_type(type_name)
        except UnconvertibleTypeError as exc:
            if (name, type_name) not in self._refused:
                self._refused.add((name, type_name))
                quiet = type_name.partition("/")[0] in ROS2_ONLY_PACKAGES or "/action/" in type_name
                text = f"not bridging service {name}: {exc}"
                if quiet:
                    self.node.get_logger().debug(text)
                else:
                    self.node.get_logger().warning(text)
            return None

    def scan(self) -> None:
        """Compare the graphs once (the bridge's scan timer calls this).

        Raises:
            BridgeError: the master failed (the caller logs it once and retries).
        """
        servers: dict[str, set[str]] = {}
        clients: dict[str, set[str]] = {}
        for e in self.node.context.graph.service_endpoints():
            if e.node_fqn == self._fqn or not self.selected(e.topic):
                continue
            side = servers if e.kind == "service_server" else clients
            side.setdefault(e.topic, set()).add(e.type_name)
        self._scan_out(servers)
        self._scan_in({n: t for n, t in clients.items() if n not in servers})

    # ------------------------------------------------------------------ visnav -> ROS 1
    def _scan_out(self, servers: dict[str, set[str]]) -> None:
        for name in list(self._out):
            if name not in servers:
                self._drop_out(name)
        for name, types in sorted(servers.items()):
            if name in self._out or name in self._in or len(types) != 1:
                continue
            stype = self._convertible(name, next(iter(types)))
            if stype is None:
                continue
            client = self.node.create_client(stype.ros2_name, name)
            try:
                self.ros1.advertise_service(name, stype, self._handler(name, stype, client))
            except BridgeError:
                self.node.destroy_client(client)
                raise
            self._out[name] = client
            self.node.get_logger().info(f"visnav -> ROS 1: service {name} [{stype.ros1_name}]")

    def _handler(self, name: str, stype: Ros1ServiceType, client: Client[Any, Any]) -> Any:
        def handle(data: bytes) -> bytes:
            """A ROS 1 call (on its TCPROS thread): decode, call visnav, encode."""
            request = decode_part(data, stype.request)
            response = client.call(request, timeout_sec=self.timeout_s)
            return encode_part(response, stype.response)

        return handle

    def _drop_out(self, name: str) -> None:
        client = self._out.pop(name)
        self.ros1.unadvertise_service(name)
        self.node.destroy_client(client)
        self.node.get_logger().info(f"visnav -> ROS 1: service {name} gone")

    # ------------------------------------------------------------------ ROS 1 -> visnav
    def _scan_in(self, wanted: dict[str, set[str]]) -> None:
        ros1_services: set[str] = set()
        if wanted or self._in:
            _pubs, _subs, srvs = self.ros1.master.system_state()
            ros1_services = {
                str(n) for n, providers in srvs if any(p != self.ros1.name for p in providers)
            }
        for name in list(self._in):
            if name not in wanted or name not in ros1_services:
                self._drop_in(name)
        for name, types in sorted(wanted.items()):
            if name in self._in or name in self._out or name not in ros1_services:
                continue
            if len(types) != 1:
                continue
            stype = self._convertible(name, next(iter(types)))
            if stype is None:
                continue
            self._in[name] = self.node.create_service(
                stype.ros2_name, name, self._proxy(name, stype)
            )
            self.node.get_logger().info(f"ROS 1 -> visnav: service {name} [{stype.ros1_name}]")

    def _proxy(self, name: str, stype: Ros1ServiceType) -> Any:
        def proxy(request: Any, _response: Any) -> Future[Any]:
            """A visnav call (in the executor): hand the ROS 1 call to a worker thread."""
            data = encode_part(request, stype.request)
            call = functools.partial(self._call_ros1, name, stype, data)
            return self.calls.submit(call, what=f"ROS 1 service {name}")

        return proxy

    def _call_ros1(self, name: str, stype: Ros1ServiceType, data: bytes) -> Any:
        """On a worker: find the ROS 1 provider, call it, decode its response."""
        uri = self.ros1.master.lookup_service(name)
        reply = call_service(
            uri, name, stype, data, caller_id=self.ros1.name, timeout_s=self.timeout_s
        )
        return decode_part(reply, stype.response)

    def _drop_in(self, name: str) -> None:
        service = self._in.pop(name)
        self.node.destroy_service(service)
        self.node.get_logger().info(f"ROS 1 -> visnav: service {name} gone")

    def close(self) -> None:
        """Drop every bridged service."""
        for name in list(self._out):
            self._drop_out(name)
        for name in list(self._in):
            self._drop_in(name)
        self.calls.close()
