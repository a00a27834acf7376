"""The graph context: in-process topics, the fair executor and the transport.

A :class:`Context` is the unit of "one graph participant": every node created
with it shares in-process (zero-copy) delivery and one Zenoh session that
connects it to the other processes of the same domain. Nothing is global: make
a context explicitly, or let a :class:`~visnav.graph.Node` make a private one.

Executor policy (fair, deterministic). Callbacks run in the thread that calls
:meth:`Context.spin_once`, one callback per call.

* Pending work lives with its entity: each subscription has its QoS queue
  (keep-last(N) keeps the newest N messages, dropping and counting the oldest
  when a message arrives; keep-all keeps all), each timer its deadline. There
  is no executor-wide backlog of messages. (Requests from other processes pass
  through the context's inbox, which the executor empties into their services'
  queues, in arrival order, before each step.)
* Entities with work wait in one *ready ring* (first in, first out), each at
  most once. A subscription joins the back when a message arrives and it is
  neither in the ring nor running; a timer joins when it is found due (timers
  are checked before each step and right after each callback; several due at
  once join in deadline order, ties in creation order). So entities join in the
  order their oldest pending work arrived.
* Each step takes the entity at the front and runs one callback: the oldest
  message of a subscription's queue, or the timer (its deadline advances,
  skipping missed periods). After the callback, a subscription that still has
  messages joins the back again.
* Hence with R entities ready, pending work waits for at most R - 1 callbacks
  of other entities: a topic that becomes ready while another topic's slow
  callback runs is served right after that one callback, however many messages
  the busy topic has queued.
* The price of that bound: a turn is one callback, so a topic that shares the
  executor with an always-ready slow callback gets one message per slow
  callback (its keep-last queue drops the rest, counted). Work that must not
  be throttled so belongs in another process (``process: own`` in a launch).
  rclcpp's and rclpy's executors take one message per ready entity per wait
  too.
* The same inputs in one process give the same callback order (in-process
  deliveries happen in publication order; remote samples in arrival order).

Fault boundary: an exception from a callback is logged (rate limited, naming
node, topic and type; see :mod:`visnav.graph.faults`) and spinning goes on;
:meth:`Context.set_error_policy` makes a node's errors raise
:class:`~visnav.graph.faults.CallbackError` instead. ``KeyboardInterrupt`` and
``SystemExit`` always propagate.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from visnav.graph.errors import GraphError, TopicTypeConflictError
from visnav.graph.faults import FaultBoundary
from visnav.graph.graph_cache import GraphCache
from visnav.graph.keys import (
    KeyExpressionError,
    LivelinessToken,
    liveliness_key_pattern,
    parse_topic_key,
)
from visnav.graph.message_info import MessageInfo
from visnav.graph.query_routes import QueryRoutes
from visnav.graph.timer_poll import TimerPoll
from visnav.graph.token_declarer import DeferredToken, TokenDeclarer
from visnav.graph.transport import TransportConfig, ZenohTransport, resolve_domain

if TYPE_CHECKING:
    from visnav.graph.node import Node, Publisher
    from visnav.graph.service import Client, Service, _Request
    from visnav.graph.subscription import Subscription
    from visnav.graph.timer import Timer

    _Entity = Subscription[Any] | Timer | Service[Any, Any] | Client[Any, Any]

__all__ = ["ENV_TRANSPORT", "Context"]

ENV_TRANSPORT = "VISNAV_TRANSPORT"
_TRANSPORTS = ("zenoh", "local")


class _LocalTopic:
    __slots__ = ("msg_type", "name", "publishers", "subscriptions")

    def __init__(self, name: str, msg_type: type[Any]) -> None:
        self.name = name
        self.msg_type = msg_type
        self.publishers: list[Publisher[Any]] = []
        self.subscriptions: list[Subscription[Any]] = []


class Context:
    """One participant in a visnav graph.

    Args:
        domain: graph domain id; default ``VISNAV_DOMAIN`` or 0.
        transport: ``"zenoh"`` (default; talks to other processes) or ``"local"``
            (this process only); default ``VISNAV_TRANSPORT`` or ``"zenoh"``.
        env: environment to read (default ``os.environ``); for tests.
    """

    def __init__(
        self,
        domain: str | int | None = None,
        *,
        transport: str | None = None,
        env: Mapping[str, str] | None = None,
    ) -> None:
        env = os.environ if env is None else env
        self.domain = resolve_domain(domain, env)
        kind = transport or env.get(ENV_TRANSPORT, "zenoh")
        if kind not in _TRANSPORTS:
            msg = f"transport is {kind!r}: expected one of {', '.join(_TRANSPORTS)}"
            raise GraphError(msg)
        self.transport_kind = kind
        self._config = TransportConfig.from_env(self.domain, env)
        self._zenoh: ZenohTransport | None = None
        self._zenoh_lock = threading.Lock()
        self._lock = threading.RLock()
        # The executor sleeps on this queue (see _signal / _sleep): wake-up tokens (None)
        # and requests from other processes (Zenoh queries, put by Zenoh's threads).
        self._inbox: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._sleeping = False
        self._query_routes = QueryRoutes()
        self._topics: dict[str, _LocalTopic] = {}
        self._ready: deque[_Entity] = deque()
        self._queued: set[_Entity] = set()
        self._running: _Entity | None = None
        self._callback_thread: int | None = None
        self._services: dict[str, tuple[Service[Any, Any], ...]] = {}
        self._graph_cond = threading.Condition()
        self._declarer: TokenDeclarer | None = None
        self._timer_poll = TimerPoll()  # which timers are due, cheaply (timer_poll.py)
        self._timers: list[Timer] = self._timer_poll.timers
        self.faults = FaultBoundary()
        """Callback errors so far (per callback) and the nodes' error policies."""
        self._nodes: list[Node] = []
        self._ids = itertools.count(1)
        self._spinning = False
        self._shutdown = False
        self._watch: Any = None
        self.graph = GraphCache()
        self._remote_subs: dict[str, tuple[int, frozenset[tuple[str, int]]]] = {}
        self.graph.add_listener(self._on_graph_change)
        self.graph.add_token_listener(self._on_token)

    # ------------------------------------------------------------------ lifecycle
    def __enter__(self) -> Context:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()

    @property
    def ok(self) -> bool:
        """False after :meth:`shutdown`."""
        return not self._shutdown

    def shutdown(self) -> None:
        """Destroy all nodes and close the transport (idempotent)."""
        if self._shutdown:
            return
        for node in list(self._nodes):
            node.destroy_node()
        self._shutdown = True
        with self._lock:
            self._signal()
        if self._declarer is not None:
            self._declarer.close()
        if self._watch is not None:
            with contextlib.suppress(Exception):
                self._watch.undeclare()
        if self._zenoh is not None:
            self._zenoh.close()

    def next_id(self) -> int:
        """Return a new entity id, unique in this context."""
        return next(self._ids)

    @property
    def zenoh(self) -> ZenohTransport | None:
        """The Zenoh transport (opened on first use), or None for a local-only context."""
        if self.transport_kind != "zenoh" or self._shutdown:
            return None
        with self._zenoh_lock:
            if self._zenoh is None:
                self._zenoh = ZenohTransport(
                    self._config, remote_subscriptions=self.remote_subscriptions
                )
                self._watch = self._zenoh.watch_liveliness(
                    liveliness_key_pattern(self.domain), self.graph.put, self.graph.delete
                )
            return self._zenoh

    @property
    def zid(self) -> str:
        """The Zenoh id of this context (``"0"`` for a local-only context)."""
        z = self.zenoh
        return z.zid if z is not None else "0"

    def remote_subscriptions(self, key: str) -> frozenset[tuple[str, int]]:
        """``(zid, entity id)`` of the subscriptions of a data key in other sessions.

        From the graph (liveliness tokens), cached until it changes; publishers use it to
        tell whether every remote subscription is a paused paced one.
        """
        version = self.graph.version
        cached = self._remote_subs.get(key)
        if cached is not None and cached[0] == version:
            return cached[1]
        try:
            parsed = parse_topic_key(key)
        except KeyExpressionError:
            return frozenset()  # not a topic's data key: nothing to pace
        own = self._zenoh.zid if self._zenoh is not None else ""
        subs = frozenset(
            (e.zid, e.entity_id)
            for e in self.graph.endpoints(parsed.topic)
            if e.kind == "subscription" and e.zid != own and e.type_name == parsed.type_name
        )
        self._remote_subs[key] = (version, subs)
        return subs

    # ------------------------------------------------------------------ registry
    def register_node(self, node: Node) -> None:
        """Called by :class:`Node`: add a node."""
        self._check_ok()
        self._nodes.append(node)

    def unregister_node(self, node: Node) -> None:
        """Called by :class:`Node`: remove a node."""
        with contextlib.suppress(ValueError):
            self._nodes.remove(node)

    @property
    def nodes(self) -> list[Node]:
        """The nodes of this context."""
        return list(self._nodes)

    def _check_ok(self) -> None:
        if self._shutdown:
            msg = "the context is shut down; create a new Context"
            raise GraphError(msg)

    def _topic(self, name: str, msg_type: type[Any], what: str) -> _LocalTopic:
        topic = self._topics.get(name)
        if topic is None:
            topic = _LocalTopic(name, msg_type)
            self._topics[name] = topic
        elif topic.msg_type is not msg_type:
            existing = getattr(topic.msg_type, "__msgtype__", topic.msg_type.__name__)
            new = getattr(msg_type, "__msgtype__", msg_type.__name__)
            msg = (
                f"topic '{name}' already carries {existing} in this process; cannot create a "
                f"{what} of {new} on it: use another topic name or the same type"
            )
            raise TopicTypeConflictError(msg)
        return topic

    def check_remote_type(self, name: str, type_name: str) -> None:
        """Refuse ``type_name`` on a topic whose known remote publishers use another type."""
        for e in self.graph.endpoints(name):
            if e.kind == "publisher" and e.type_name and e.type_name != type_name:
                msg = (
                    f"topic '{name}' is already published as {e.type_name} by {e.node_fqn}; "
                    f"cannot publish {type_name} on it: use another topic name or the same type"
                )
                raise TopicTypeConflictError(msg)

    def add_publisher(self, pub: Publisher[Any]) -> None:
        """Called by :class:`Node`: attach a publisher to its in-process topic."""
        with self._lock:
            self._check_ok()
            topic = self._topic(pub.topic_name, pub.msg_type, "publisher")
            topic.publishers.append(pub)
            self._relink(topic)

    def add_subscription(self, sub: Subscription[Any]) -> None:
        """Called by :class:`Node`: attach a subscription; deliver transient-local history."""
        with self._lock:
            self._check_ok()
            topic = self._topic(sub.topic_name, sub.msg_type, "subscription")
            topic.subscriptions.append(sub)
            self._relink(topic)
            for pub in topic.publishers:
                if sub in pub.targets and pub.history is not None and sub.wants_history:
                    for msg in pub.history:
                        sub.enqueue(msg, pub.local_info() if sub.wants_info else None)
                    self._schedule(sub)
            self._signal()

    def remove_publisher(self, pub: Publisher[Any]) -> None:
        """Called by :class:`Node`: detach a publisher."""
        with self._lock:
            topic = self._topics.get(pub.topic_name)
            if topic is not None and pub in topic.publishers:
                topic.publishers.remove(pub)
                self._gc(topic)

    def remove_subscription(self, sub: Subscription[Any]) -> None:
        """Called by :class:`Node`: detach a subscription and drop its pending messages.

        Dropping them also releases remote samples' buffers (a sender's shared memory).
        """
        sub.stop()
        with self._lock:
            sub.queue.clear()
            topic = self._topics.get(sub.topic_name)
            if topic is not None and sub in topic.subscriptions:
                topic.subscriptions.remove(sub)
                self._relink(topic)
                self._gc(topic)

    def _gc(self, topic: _LocalTopic) -> None:
        if not topic.publishers and not topic.subscriptions:
            del self._topics[topic.name]

    @staticmethod
    def _relink(topic: _LocalTopic) -> None:
        for pub in topic.publishers:
            pub.link([s for s in topic.subscriptions if pub.compatible_with(s)])

    def add_timer(self, timer: Timer) -> None:
        """Called by :class:`Node`: schedule a timer."""
        with self._lock:
            self._timer_poll.add(timer)
            self._signal()

    def remove_timer(self, timer: Timer) -> None:
        """Called by :class:`Node`: unschedule a timer."""
        with self._lock:
            self._timer_poll.remove(timer)

    # ------------------------------------------------------------------ delivery
    def deliver_local(self, pub: Publisher[Any], msg: Any) -> None:
        """Hand ``msg`` (same object, no copy) to the in-process subscriptions of ``pub``."""
        with self._lock:
            for sub in pub.targets:
                sub.enqueue(msg, pub.local_info() if sub.wants_info else None)
                if sub is not self._running and sub not in self._queued:
                    self._queued.add(sub)
                    self._ready.append(sub)
            if pub.history is not None:
                pub.history.append(msg)
            wake, self._sleeping = self._sleeping, False
        if wake:
            self._inbox.put(None)

    def deliver_remote(
        self, sub: Subscription[Any], payload: Any, info: MessageInfo | None
    ) -> None:
        """Hand a sample (CDR payload) that arrived from another process to ``sub`` (any thread)."""
        with self._lock:
            sub.enqueue_remote(payload, info)
            if sub is not self._running and sub not in self._queued:
                self._queued.add(sub)
                self._ready.append(sub)
            wake, self._sleeping = self._sleeping, False
        if wake:
            self._inbox.put(None)

    def wake(self, *, timers: bool = False) -> None:
        """Wake a waiting :meth:`spin_once` (e.g. after a clock change; ``timers``: a reset)."""
        with self._lock:
            if timers:  # a timer's deadline moved: the cheap due check starts afresh
                self._timer_poll.invalidate()
            self._signal()

    def _on_graph_change(self) -> None:
        self.wake()
        with self._graph_cond:
            self._graph_cond.notify_all()

    def declare_token_deferred(self, key: str) -> DeferredToken | None:
        """Declare a liveliness token off this thread (None for a local-only context)."""
        z = self.zenoh
        if z is None:
            return None
        with self._zenoh_lock:
            if self._declarer is None:
                self._declarer = TokenDeclarer(z.token)
            declarer = self._declarer
        return declarer.submit(key)

    def flush_tokens(self, timeout_s: float = 5.0) -> bool:
        """Wait until deferred tokens are declared (other processes can then see them)."""
        declarer = self._declarer
        return True if declarer is None else declarer.flush(timeout_s)

    def wait_graph_change(self, timeout_s: float) -> None:
        """Block until the graph changes or ``timeout_s`` passes (for waits on discovery)."""
        with self._graph_cond:
            self._graph_cond.wait(timeout_s)

    # ------------------------------------------------------------------ services
    @property
    def lock(self) -> threading.RLock:
        """The executor's lock (entities that queue work from other threads hold it)."""
        return self._lock

    def add_service(self, service: Service[Any, Any]) -> None:
        """Called by :class:`Node`: make a server reachable by in-process clients."""
        with self._lock:
            self._check_ok()
            # copied on write: local_service reads without the lock
            servers = self._services.get(service.srv_name, ())
            self._services[service.srv_name] = (*servers, service)

    def remove_service(self, service: Service[Any, Any]) -> None:
        """Called by :class:`Node`: detach a server and fail its queued requests."""
        with self._lock:
            self._drain_inbox(keep_token=True)
            servers = tuple(s for s in self._services.get(service.srv_name, ()) if s is not service)
            if servers:
                self._services[service.srv_name] = servers
            else:
                self._services.pop(service.srv_name, None)
            waiting = list(service.queue)
            service.queue.clear()
        # answered outside the lock: replies go through Zenoh, whose threads take this lock
        for request in waiting:
            request.fail(f"{service.describe()} was destroyed before answering")

    def local_service(self, name: str, type_name: str) -> Service[Any, Any] | None:
        """The first in-process server of ``name`` with type ``type_name``, or None."""
        for service in self._services.get(name, ()):  # a tuple, replaced on change
            if service.srv_type.name == type_name:
                return service
        return None

    def service_is_ready(self, name: str, type_name: str) -> bool:
        """Whether a server of ``name`` and ``type_name`` is in this process or the graph."""
        if self.local_service(name, type_name) is not None:
            return True
        return self.graph.has_service_server(name, type_name)

    def deliver_request(self, service: Service[Any, Any], request: _Request) -> None:
        """Queue a request for ``service`` (any thread) and wake the executor."""
        with self._lock:
            service.enqueue(request)
            if service is not self._running and service not in self._queued:
                self._queued.add(service)
                self._ready.append(service)
            wake, self._sleeping = self._sleeping, False
        if wake:  # after unlocking: the executor wakes to a free lock
            self._inbox.put(None)

    def notify_ready(self, entity: _Entity) -> None:
        """Put ``entity`` (which has work now) in the ready ring (any thread)."""
        with self._lock:
            self._schedule(entity)
            wake, self._sleeping = self._sleeping, False
        if wake:
            self._inbox.put(None)

    def in_callback(self) -> bool:
        """Whether the calling thread is running a callback of this context."""
        return self._callback_thread == threading.get_ident()

    def _on_token(self, token: LivelinessToken) -> None:
        """A latched publisher appeared in another session: its subscribers here fetch its cache."""
        if token.kind != "MP" or token.durability != "transient_local" or token.topic is None:
            return
        if self._zenoh is None or token.zid == self._zenoh.zid:
            return
        with self._lock:
            topic = self._topics.get(token.topic)
            subs = [s for s in topic.subscriptions if s.wants_history] if topic else []
        for sub in subs:
            sub.on_remote_publisher(token.zid)

    # ------------------------------------------------------------------ executor
    def set_error_policy(self, node_name: str, policy: str) -> None:
        """Choose what follows an exception in a callback of a node.

        Args:
            node_name: the node's fully qualified name.
            policy: ``"log"`` (default: log, rate limited, and keep spinning) or ``"raise"``
                (log, then :meth:`spin_once` raises
                :class:`~visnav.graph.faults.CallbackError`).

        Raises:
            GraphError: an unknown policy.
        """
        self.faults.set_policy(node_name, policy)

    def _signal(self) -> None:
        """With the lock held: wake the executor if it sleeps in :meth:`_sleep`.

        The sleeping executor sets ``_sleeping`` (lock held) and blocks on ``_inbox``, a
        ``queue.SimpleQueue``; a producer that finds it set clears it and puts one
        ``None`` token (the hot paths after unlocking, so the woken executor does not
        wake only to wait for their lock). Leftover tokens are skipped. Zenoh's thread
        puts each remote query in the inbox directly (:meth:`route_queries`): no Python
        runs there for them.
        """
        if self._sleeping:
            self._sleeping = False
            self._inbox.put(None)

    def _sleep(self, timeout_s: float | None) -> None:
        """With the lock held once: release it and sleep until woken or the timeout.

        Only the spinning thread sleeps (one at a time, see :meth:`spin_once`). Returns
        with the lock held again; the caller looks for work again either way.
        """
        self._sleeping = True
        lock = self._lock
        item = None
        lock.release()
        try:
            item = self._inbox.get(timeout=timeout_s)
        except queue.Empty:
            pass
        finally:
            lock.acquire()
            self._sleeping = False
        if item is not None:
            self._route_query(item)

    # ------------------------------------------------------------------ remote requests
    def route_queries(self, service: Service[Any, Any], key: str) -> Callable[[Any], None]:
        """Send Zenoh queries on ``key`` to ``service``; return the queryable's callback.

        The callback (the inbox's ``put``) runs on Zenoh's thread and only queues the
        query; the executor routes it to ``service``'s queue by its key before taking
        the next callback (in arrival order, so fairness is as for in-process requests).
        """
        with self._lock:
            self._query_routes.add(key, service)
        return self._inbox.put

    def forget_queries(self, key: str) -> None:
        """Stop routing queries on ``key``; the ones already queued go to the service first."""
        with self._lock:
            self._drain_inbox(keep_token=True)
            self._query_routes.remove(key)

    def _drain_inbox(self, *, keep_token: bool = False) -> None:
        """With the lock held: route every queued query (wake-up tokens are dropped).

        ``keep_token``: for a caller that may not be the executor, which may be about
        to take a token from the inbox: one is put back if any was taken.
        """
        inbox = self._inbox
        took_token = False
        while True:
            try:
                item = inbox.get_nowait()
            except queue.Empty:
                break
            if item is None:
                took_token = True
            else:
                self._route_query(item)
        if took_token and keep_token:
            inbox.put(None)

    def _route_query(self, query: Any) -> None:
        """With the lock held: queue a Zenoh query for the service its key names."""
        service = self._query_routes.find(query)
        if service is not None:
            service.accept_query(query)
            if service is not self._running and service not in self._queued:
                self._queued.add(service)
                self._ready.append(service)

    def _schedule(self, entity: _Entity) -> None:
        """Put ``entity`` at the back of the ready ring unless it is there or running."""
        if entity is not self._running and entity not in self._queued:
            self._queued.add(entity)
            self._ready.append(entity)

    def _take(self, poll: bool = True) -> tuple[_Entity, Callable[[], None]] | None:
        """With the lock held: the next callback from the ready ring (due timers joined first)."""
        if self._shutdown:
            return None
        if not self._inbox.empty():
            self._drain_inbox()
        if poll and self._timers:  # the due ones join the ring's back in deadline order
            for timer in self._timer_poll.due(self._queued):
                self._schedule(timer)
        ready = self._ready
        while ready:
            entity = ready.popleft()
            self._queued.discard(entity)
            self._timer_poll.taken(entity)
            call = entity.take_call()
            if call is not None:
                self._running = entity
                return entity, call
        return None

    def _take_or_wait(self, timeout_s: float | None) -> tuple[_Entity, Callable[[], None]] | None:
        """With the lock held: the next callback, waiting up to ``timeout_s`` for one."""
        if self._shutdown:
            return None
        taken = self._take()
        if taken is not None or timeout_s == 0:
            return taken
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                return None
            wait = self._timer_poll.wall_wait_s()
            if wait is not None and (remaining is None or wait < remaining):
                remaining = wait
            self._sleep(remaining)
            if self._shutdown:
                return None
            taken = self._take()
            if taken is not None:
                return taken

    def spin_once(self, timeout_s: float | None = None) -> bool:
        """Run at most one ready callback, waiting up to ``timeout_s`` for one.

        An exception from the callback is logged and counted in :attr:`faults` (see the
        module docstring); ``spin_once`` still returns True.

        Args:
            timeout_s: ``None`` waits forever, ``0`` does not wait.

        Returns:
            True if a callback ran.

        Raises:
            CallbackError: the callback raised and its node's error policy is ``"raise"``.
        """
        return self._spin_one(timeout_s, True)

    def _spin_one(self, timeout_s: float | None, poll: bool) -> bool:
        """:meth:`spin_once`; ``poll=False`` (no waiting): the timers were polled just now."""
        lock = self._lock
        with lock:
            if self._spinning:
                msg = "spin_once called while this context is already spinning (from a callback?)"
                raise GraphError(msg)
            self._spinning = True
            try:
                taken = self._take_or_wait(timeout_s) if poll else self._take(False)
            finally:
                if self._running is None:
                    self._spinning = False
            if taken is None:
                return False
        entity, call = taken
        self._callback_thread = threading.get_ident()
        try:
            call()
        except Exception as exc:  # noqa: BLE001 - the fault boundary: log and go on
            self.faults.report(entity.node, entity.entity_id, entity.describe(), exc)
        finally:
            self._callback_thread = None
            with lock:
                self._spinning = False
                self._running = None
                # timers that fell due during the callback go before the busy entity
                for timer in self._timer_poll.due(self._queued) if self._timers else ():
                    self._schedule(timer)
                if entity.pending():
                    self._schedule(entity)
        return True

    def spin_some(self, max_callbacks: int | None = None) -> int:
        """Run the ready callbacks, without waiting (timers polled once between two); count them."""
        count = 0
        while (max_callbacks is None or count < max_callbacks) and self._spin_one(0.0, count == 0):
            count += 1
        return count

    def spin_until(self, predicate: Callable[[], bool], timeout_s: float | None = None) -> bool:
        """Spin until ``predicate()`` is true or ``timeout_s`` passes; return the predicate."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while not predicate():
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                return predicate()
            self.spin_once(min(remaining, 0.05) if remaining is not None else 0.05)
            if self._shutdown:
                return predicate()
        return True

    def spin(self, duration_s: float | None = None) -> None:
        """Spin until shutdown (or for ``duration_s`` seconds)."""
        end = None if duration_s is None else time.monotonic() + duration_s
        while not self._shutdown:
            remaining = None if end is None else end - time.monotonic()
            if remaining is not None and remaining <= 0:
                return
            self.spin_once(min(remaining, 0.1) if remaining is not None else 0.1)
