"""The Foxglove server's graph side: channels from topics, client publishing, services, parameters.

:class:`FoxgloveServer` keeps a :class:`~visnav.bridge.foxglove.websocket.WebSocketServer`
in step with a visnav graph, the way foxglove_bridge does with ROS 2:

* every topic with a publisher (whose type visnav knows) is a channel, advertised to each
  client as it appears, with encoding ``cdr``, schema encoding ``ros2msg`` and the full
  ``.msg`` text with dependencies (what rosbag2 MCAP files store); a topic whose last
  publisher leaves is unadvertised;
* a client's ``subscribe`` makes one raw graph subscription for that client
  (``raw=True``: the CDR bytes as the publisher sent them, never deserialized; a transient
  local topic such as ``/map`` delivers its last message to each new client);
* ``clientPublish``: a client channel (``cdr`` or ``json``) becomes a graph publisher;
* ``services``: graph services are advertised with their request/response schemas and
  called with the client's CDR (or JSON) request;
* ``parameters`` / ``parametersSubscribe``: through every node's parameter services and
  ``/parameter_events`` (:mod:`~visnav.bridge.foxglove.params`);
* ``time``: with ``use_sim_time`` the ``/clock`` time is sent to clients;
* ``connectionGraph``: the nodes publishing, subscribing and serving, whole on
  ``subscribeConnectionGraph`` then as it changes
  (:mod:`~visnav.bridge.foxglove.connection_graph`);
* ``assets``: ``fetchAsset`` of ``package://`` (and allowed ``file://``) files, such as the
  meshes of ``robot_description`` (:mod:`~visnav.bridge.foxglove.assets`).

Graph changes asked for by clients (subscriptions, publishers) run in order on one worker
thread; service and parameter calls on a small pool, so a slow service never blocks data.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from visnav.bridge.foxglove.assets import AssetError, AssetResolver
from visnav.bridge.foxglove.connection_graph import (
    GraphSnapshot,
    full_update,
    graph_snapshot,
    graph_update,
)
from visnav.bridge.foxglove.entities import (
    Channel,
    ClientPub,
    ClientState,
    ServiceEntry,
    json_object,
)
from visnav.bridge.foxglove.errors import FoxgloveError
from visnav.bridge.foxglove.options import FoxgloveOptions, compile_patterns, matches
from visnav.bridge.foxglove.params import ParameterGateway, to_json_parameter
from visnav.bridge.foxglove.protocol import (
    Advertise,
    CallService,
    ClientMessage,
    FetchAsset,
    GetParameters,
    PublishData,
    SetParameters,
    Subscribe,
    SubscribeGraph,
    SubscribeParameterUpdates,
    Unadvertise,
    Unsubscribe,
    UnsubscribeParameterUpdates,
    encode_fetch_asset_response,
    encode_message_data,
    encode_service_response,
    encode_time,
)
from visnav.bridge.foxglove.websocket import ClientConnection, WebSocketServer
from visnav.errors import VisnavError
from visnav.graph import MessageInfo, Node, QoSProfile, SerializedMessage
from visnav.graph.clock import Clock, ClockType
from visnav.graph.introspect import subscription_qos_for
from visnav.graph.names import is_hidden_name
from visnav.graph.param_services import msg_to_value
from visnav.graph.qos import HistoryPolicy
from visnav.graph.service import Client
from visnav.msgs.construct import message_from_dict, message_to_dict
from visnav.msgs.serde import deserialize, get_message_class, message_definition, serialize
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import time_to_ns

__all__ = ["FoxgloveOptions", "FoxgloveServer"]  # FoxgloveOptions re-exported for callers

_log = logging.getLogger("visnav.foxglove")
_WARNING, _ERROR = 1, 2
_ENCODINGS = ("cdr", "json")
_MATCH_WAIT_S = 1.0


class FoxgloveServer:
    """Serve a visnav graph to Foxglove / Lichtblick clients over the Foxglove WebSocket protocol.

    Args:
        node: the node whose context is served (its executor must spin: the discovery
            timer and the data callbacks run there).
        options: what to serve, where.

    Raises:
        FoxgloveError: bad options, or (from :meth:`start`) the port cannot be bound.

    Example::

        with Context() as ctx:
            server = FoxgloveServer(Node("foxglove_bridge", context=ctx), FoxgloveOptions())
            server.start()
            ctx.spin()
    """

    def __init__(self, node: Node, options: FoxgloveOptions | None = None) -> None:
        self.node = node
        self.options = options = options or FoxgloveOptions()
        self._topic_ok = compile_patterns("topic_whitelist", options.topic_whitelist)
        self._service_ok = compile_patterns("service_whitelist", options.service_whitelist)
        self._client_topic_ok = compile_patterns(
            "client_topic_whitelist", options.client_topic_whitelist
        )
        caps = list(options.capabilities)
        self.sim_time = bool(node.get_parameter("use_sim_time").value)
        if "time" in caps and not self.sim_time:
            caps.remove("time")
        self.capabilities = tuple(caps)
        self._lock = threading.RLock()
        self._channels: dict[str, Channel] = {}
        self._services: dict[str, ServiceEntry] = {}
        self._skipped: set[str] = set()
        self._next_id = 1
        self._graph_version = -1
        self._clients: dict[int, ClientConnection] = {}
        self._graph_worker = ThreadPoolExecutor(1, thread_name_prefix="foxglove-graph")
        self._call_pool = ThreadPoolExecutor(4, thread_name_prefix="foxglove-call")
        self._srv_clients: dict[str, Client[Any, Any]] = {}
        self._assets = AssetResolver(options.asset_uri_allowlist, packages=options.packages)
        self._graph_view: GraphSnapshot | None = None  # what graph subscribers were last sent
        self._graph_lock = threading.Lock()
        self._params = ParameterGateway(
            node, whitelist=options.param_whitelist, timeout_s=min(2.0, options.service_timeout_s)
        )
        info = {
            "op": "serverInfo",
            "name": options.name,
            "capabilities": list(self.capabilities),
            "supportedEncodings": list(_ENCODINGS),
            "metadata": {"ROS_DISTRO": "humble", "fg-library": "visnav"},
            "sessionId": str(time.time_ns()),
        }
        self.ws = WebSocketServer(
            self,
            info,
            address=options.address,
            port=options.port,
            send_buffer_limit=options.send_buffer_limit,
            compression=options.use_compression,
        )
        self._started = False

    # ------------------------------------------------------------------ lifecycle
    @property
    def url(self) -> str:
        """``ws://address:port`` clients connect to."""
        return self.ws.url

    @property
    def port(self) -> int:
        """The bound port (the chosen one when ``port`` was 0)."""
        return self.ws.port

    def start(self) -> None:
        """Bind the port, discover the graph and start serving.

        Raises:
            FoxgloveError: the port cannot be bound.
        """
        if self._started:
            return
        self.ws.start()
        self._started = True
        steady = Clock(ClockType.STEADY_TIME)
        self._timer = self.node.create_timer(0.2, self.poll, clock=steady)
        if "time" in self.capabilities:
            clock_cls = get_message_class("rosgraph_msgs/msg/Clock")
            self.node.create_subscription(clock_cls, "/clock", self._on_clock, 10)
        if "parametersSubscribe" in self.capabilities:
            event_cls = get_message_class("rcl_interfaces/msg/ParameterEvent")
            self.node.create_subscription(event_cls, "/parameter_events", self._on_params, 100)
        self.poll()
        _log.debug("Foxglove server at %s", self.url)

    def close(self) -> None:
        """Disconnect the clients, stop the server and remove its graph entities (idempotent)."""
        if not self._started:
            return
        self._started = False
        self.ws.stop()
        self._call_pool.shutdown(wait=False, cancel_futures=True)
        self._graph_worker.shutdown(wait=True, cancel_futures=True)
        with self._lock:
            states = [c.state.get("fg") for c in self._clients.values()]
            self._clients.clear()
        for state in states:
            if isinstance(state, ClientState):
                self._drop_client_entities(state)
        self._params.close()
        for client in self._srv_clients.values():
            self.node.destroy_client(client)
        self._srv_clients.clear()
        timer = getattr(self, "_timer", None)
        if timer is not None:
            self.node.destroy_timer(timer)

    # ------------------------------------------------------------------ discovery
    def _new_id(self) -> int:
        n = self._next_id
        self._next_id += 1
        return n

    def poll(self) -> None:
        """Advertise new topics and services, unadvertise gone ones (every 0.2 s)."""
        graph = self.node.context.graph
        version = graph.version
        if version == self._graph_version:
            return
        self._graph_version = version
        added, removed = self._scan_topics()
        s_added, s_removed = self._scan_services() if "services" in self.capabilities else ([], [])
        self._send_graph_update()
        if not (added or removed or s_added or s_removed):
            return
        gone = {c.id for c in removed}
        for client in self.ws.clients:
            if removed:
                client.send_json({"op": "unadvertise", "channelIds": sorted(gone)})
                state = _state(client)
                for sid in [sid for sid, cid in state.subs.items() if cid in gone]:
                    del state.subs[sid]
                    self._submit(self._graph_worker, client, self._unsubscriber(state, sid))
            if added:
                client.send_json({"op": "advertise", "channels": [c.to_json() for c in added]})
            if s_removed:
                ids = [s.id for s in s_removed]
                client.send_json({"op": "unadvertiseServices", "serviceIds": ids})
            if s_added:
                services = [s.to_json() for s in s_added]
                client.send_json({"op": "advertiseServices", "services": services})

    def _scan_topics(self) -> tuple[list[Channel], list[Channel]]:
        graph = self.node.context.graph
        present: dict[str, str] = {}
        for topic, _types in graph.topic_names_and_types():
            types = {e.type_name for e in graph.endpoints(topic) if e.kind == "publisher"}
            if len(types) == 1:
                present[topic] = types.pop()
        added, removed = [], []
        with self._lock:
            for topic, ch in list(self._channels.items()):
                if present.get(topic) != ch.type_name:
                    removed.append(self._channels.pop(topic))
            for topic, type_name in present.items():
                key = f"{topic} {type_name}"
                if topic in self._channels or key in self._skipped:
                    continue
                if not self.options.include_hidden and is_hidden_name(topic):
                    continue
                if not matches(self._topic_ok, topic):
                    continue
                try:
                    schema = message_definition(type_name)
                except VisnavError as exc:
                    _log.warning("Foxglove: not advertising '%s': %s", topic, exc)
                    self._skipped.add(key)
                    continue
                ch = Channel(self._new_id(), topic, type_name, schema)
                self._channels[topic] = ch
                added.append(ch)
        return added, removed

    def _scan_services(self) -> tuple[list[ServiceEntry], list[ServiceEntry]]:
        graph = self.node.context.graph
        present = {
            name: types[0]
            for name, types in graph.service_names_and_types()
            if len(types) == 1
            and (self.options.include_hidden or not is_hidden_name(name))
            and matches(self._service_ok, name)
        }
        added, removed = [], []
        with self._lock:
            for name, svc in list(self._services.items()):
                if present.get(name) != svc.srv.name:
                    removed.append(self._services.pop(name))
            for name, type_name in present.items():
                key = f"{name} {type_name}"
                if name in self._services or key in self._skipped:
                    continue
                try:
                    srv = get_service_type(type_name)
                    req = message_definition(srv.request_type_name)
                    resp = message_definition(srv.response_type_name)
                except VisnavError as exc:
                    _log.warning("Foxglove: not advertising service '%s': %s", name, exc)
                    self._skipped.add(key)
                    continue
                svc = ServiceEntry(self._new_id(), name, srv, req, resp)
                self._services[name] = svc
                added.append(svc)
        return added, removed

    # ------------------------------------------------------------------ clients
    def on_connect(self, client: ClientConnection) -> None:
        """Send the current channels and services to a new client (WebSocket thread)."""
        state = ClientState()
        client.state["fg"] = state
        with self._lock:
            self._clients[client.id] = client
            channels = [c.to_json() for c in self._channels.values()]
            services = [s.to_json() for s in self._services.values()]
        if channels:
            client.send_json({"op": "advertise", "channels": channels})
        if services and "services" in self.capabilities:
            client.send_json({"op": "advertiseServices", "services": services})

    def on_disconnect(self, client: ClientConnection) -> None:
        """Remove the client's subscriptions and publishers (WebSocket thread)."""
        with self._lock:
            self._clients.pop(client.id, None)
        state = _state(client)
        state.gone = True
        self._submit(self._graph_worker, client, lambda: self._drop_client_entities(state))

    def _drop_client_entities(self, state: ClientState) -> None:
        for sub in list(state.graph_subs.values()):
            self.node.destroy_subscription(sub)
        state.graph_subs.clear()
        for pub in list(state.pubs.values()):
            if pub.publisher is not None:
                self.node.destroy_publisher(pub.publisher)
        state.pubs.clear()

    def on_message(self, client: ClientConnection, message: ClientMessage) -> None:
        """Act on one parsed client message (WebSocket thread).

        Raises:
            FoxgloveError: the message asks for what this server does not offer or know
                (sent to the client as a warning status by the WebSocket server).
        """
        state = _state(client)
        if isinstance(message, Subscribe):
            self._subscribe(client, state, message)
        elif isinstance(message, Unsubscribe):
            for sid in message.subscription_ids:
                if state.subs.pop(sid, None) is not None:
                    self._submit(self._graph_worker, client, self._unsubscriber(state, sid))
        elif isinstance(message, Advertise):
            self._require(client, "clientPublish", "advertise")
            for ch in message.channels:
                self._advertise_client(client, state, ch.id, ch.topic, ch.encoding, ch.schema_name)
        elif isinstance(message, Unadvertise):
            for cid in message.channel_ids:
                pub = state.pubs.pop(cid, None)
                if pub is not None:
                    self._submit(self._graph_worker, client, self._unpublisher(pub))
        elif isinstance(message, PublishData):
            self._publish(client, state, message)
        elif isinstance(message, CallService):
            self._call_service(client, message)
        elif isinstance(message, GetParameters):
            self._require(client, "parameters", "getParameters")
            self._submit(self._call_pool, client, lambda: self._get_params(client, message))
        elif isinstance(message, SetParameters):
            self._require(client, "parameters", "setParameters")
            self._submit(self._call_pool, client, lambda: self._set_params(client, message))
        elif isinstance(message, SubscribeParameterUpdates):
            self._require(client, "parametersSubscribe", "subscribeParameterUpdates")
            state.param_names.update(message.names)
        elif isinstance(message, UnsubscribeParameterUpdates):
            state.param_names.difference_update(message.names)
        elif isinstance(message, SubscribeGraph):
            op = "subscribeConnectionGraph" if message.subscribe else "unsubscribeConnectionGraph"
            self._require(client, "connectionGraph", op)
            self._subscribe_graph(client, state, subscribe=message.subscribe)
        elif isinstance(message, FetchAsset):
            self._require(client, "assets", "fetchAsset")
            self._submit(self._call_pool, client, lambda: self._fetch_asset(client, message))

    def _require(self, client: ClientConnection, capability: str, op: str) -> None:
        if capability not in self.capabilities:
            msg = (
                f"{op!r} needs the {capability!r} capability, which this server does not offer "
                f"(capabilities: {', '.join(self.capabilities)})"
            )
            raise FoxgloveError(msg)

    def _submit(
        self, pool: ThreadPoolExecutor, client: ClientConnection, fn: Callable[[], None]
    ) -> None:
        try:
            future = pool.submit(fn)
        except RuntimeError:  # the server is closing
            return

        def done(f: Future[None]) -> None:
            exc = f.exception() if not f.cancelled() else None
            if exc is None:
                return
            if isinstance(exc, VisnavError):
                client.status(_WARNING, str(exc))
                return
            self.ws.internal_errors += 1
            _log.error("Foxglove server: a request of %s failed: %r", client.address, exc)
            client.status(_ERROR, f"internal error: {type(exc).__name__}: {exc}")

        future.add_done_callback(done)

    # ------------------------------------------------------------------ subscribe
    def _subscribe(self, client: ClientConnection, state: ClientState, message: Subscribe) -> None:
        problems = []
        for sid, cid in message.subscriptions:
            with self._lock:
                ch = next((c for c in self._channels.values() if c.id == cid), None)
            if ch is None:
                problems.append(f"channel {cid} is not advertised")
                continue
            if sid in state.subs:
                problems.append(f"subscription id {sid} is in use (unsubscribe it first)")
                continue
            state.subs[sid] = cid
            self._submit(self._graph_worker, client, self._subscriber(client, state, sid, ch))
        if problems:
            raise FoxgloveError("subscribe: " + "; ".join(problems))

    def _subscriber(
        self, client: ClientConnection, state: ClientState, sid: int, ch: Channel
    ) -> Callable[[], None]:
        def make() -> None:
            if state.gone or state.subs.get(sid) != ch.id:
                return
            cls = get_message_class(ch.type_name)
            qos = self._qos(ch.topic)
            clock = self.node.get_clock()

            def on_message(msg: SerializedMessage, _info: MessageInfo | None) -> None:
                client.send(encode_message_data(sid, clock.now_ns(), msg.to_bytes()))

            sub = self.node.create_subscription(cls, ch.topic, on_message, qos, raw=True)
            state.graph_subs[sid] = sub

        return make

    def _qos(self, topic: str) -> QoSProfile:
        qos = subscription_qos_for(self.node.context, topic)
        pubs = [e for e in self.node.context.graph.endpoints(topic) if e.kind == "publisher"]
        depth = sum(max(1, e.depth) for e in pubs) or 1
        depth = min(max(depth, self.options.min_qos_depth), self.options.max_qos_depth)
        return QoSProfile(
            depth=depth,
            history=HistoryPolicy.KEEP_LAST,
            reliability=qos.reliability,
            durability=qos.durability,
        )

    def _unsubscriber(self, state: ClientState, sid: int) -> Callable[[], None]:
        def drop() -> None:
            sub = state.graph_subs.pop(sid, None)
            if sub is not None:
                self.node.destroy_subscription(sub)

        return drop

    # ------------------------------------------------------------------ client publish
    def _advertise_client(
        self,
        client: ClientConnection,
        state: ClientState,
        cid: int,
        topic: str,
        encoding: str,
        schema_name: str,
    ) -> None:
        if encoding not in _ENCODINGS:
            msg = f"advertise {topic!r}: encoding {encoding!r} is not supported (cdr or json)"
            raise FoxgloveError(msg)
        if not matches(self._client_topic_ok, topic):
            msg = f"advertise {topic!r}: not in the server's client_topic_whitelist"
            raise FoxgloveError(msg)
        if cid in state.pubs:
            msg = f"advertise {topic!r}: client channel id {cid} is in use (unadvertise it first)"
            raise FoxgloveError(msg)
        cls = get_message_class(schema_name)  # raises UnknownMessageTypeError (a VisnavError)
        pub = ClientPub(topic, getattr(cls, "__msgtype__", schema_name), encoding)
        state.pubs[cid] = pub

        def make() -> None:
            if state.gone or state.pubs.get(cid) is not pub:
                return
            publisher = self.node.create_publisher(cls, topic, 10)
            # a sample published before the graph's subscribers are matched is lost (no
            # history on a volatile topic): wait briefly, as a click must reach move_base
            deadline = time.monotonic() + _MATCH_WAIT_S
            while (
                self.node.count_subscribers(topic) > 0
                and not publisher.has_listeners()
                and time.monotonic() < deadline
            ):
                time.sleep(0.01)
            pub.publisher = publisher

        self._submit(self._graph_worker, client, make)

    def _unpublisher(self, pub: ClientPub) -> Callable[[], None]:
        def drop() -> None:
            if pub.publisher is not None:
                self.node.destroy_publisher(pub.publisher)
                pub.publisher = None

        return drop

    def _publish(self, client: ClientConnection, state: ClientState, message: PublishData) -> None:
        pub = state.pubs.get(message.channel_id)
        if pub is None:
            msg = f"message data on client channel {message.channel_id}, which is not advertised"
            raise FoxgloveError(msg)
        data = message.data

        def send() -> None:
            if pub.publisher is None:
                return
            if pub.encoding == "cdr":
                msg = deserialize(data, pub.type_name)
            else:
                msg = message_from_dict(pub.type_name, json_object(data, pub.topic))
            pub.publisher.publish(msg)

        self._submit(self._graph_worker, client, send)

    # ------------------------------------------------------------------ services
    def _call_service(self, client: ClientConnection, message: CallService) -> None:
        self._require(client, "services", "service call")
        with self._lock:
            svc = next((s for s in self._services.values() if s.id == message.service_id), None)
        if svc is None:
            self._service_failure(client, message, "the service is not advertised")
            return
        if message.encoding not in _ENCODINGS:
            self._service_failure(client, message, f"encoding {message.encoding!r}: expected cdr")
            return

        def call() -> None:
            try:
                caller = self._service_client(svc)
                if message.encoding == "cdr":
                    request = deserialize(message.data, svc.srv.request_type_name)
                else:
                    request = message_from_dict(
                        svc.srv.request_type_name, json_object(message.data, svc.name)
                    )
                response = caller.call(request, timeout_sec=self.options.service_timeout_s)
                payload = (
                    serialize(response)
                    if message.encoding == "cdr"
                    else json.dumps(message_to_dict(response)).encode()
                )
            except VisnavError as exc:
                self._service_failure(client, message, str(exc))
                return
            frame = encode_service_response(svc.id, message.call_id, message.encoding, payload)
            client.send(frame, droppable=False)

        self._submit(self._call_pool, client, call)

    def _service_client(self, svc: ServiceEntry) -> Client[Any, Any]:
        with self._lock:
            caller = self._srv_clients.get(svc.name)
            if caller is None:
                caller = self.node.create_client(svc.srv, svc.name)
                self._srv_clients[svc.name] = caller
            return caller

    @staticmethod
    def _service_failure(client: ClientConnection, message: CallService, text: str) -> None:
        client.send_json(
            {
                "op": "serviceCallFailure",
                "serviceId": message.service_id,
                "callId": message.call_id,
                "message": text,
            }
        )

    # ------------------------------------------------------------------ graph, assets
    def _snapshot(self) -> GraphSnapshot:
        return graph_snapshot(
            self.node.context.graph,
            topic_whitelist=self._topic_ok,
            service_whitelist=self._service_ok,
            include_hidden=self.options.include_hidden,
        )

    def _graph_clients(self) -> list[ClientConnection]:
        with self._lock:
            clients = list(self._clients.values())
        return [c for c in clients if _state(c).graph_subscribed]

    def _subscribe_graph(
        self, client: ClientConnection, state: ClientState, *, subscribe: bool
    ) -> None:
        if not subscribe:
            if not state.graph_subscribed:
                msg = "unsubscribeConnectionGraph: this client is not subscribed to the graph"
                raise FoxgloveError(msg)
            state.graph_subscribed = False
            return
        with self._graph_lock:  # one snapshot at a time: updates go out in graph order
            others = [c for c in self._graph_clients() if c is not client]
            snapshot = self._snapshot()
            old, self._graph_view = self._graph_view, snapshot
            state.graph_subscribed = True
            update = graph_update(old, snapshot) if old is not None else None
            for other in others if update is not None else []:
                other.send_json(update or {})
            client.send_json(full_update(snapshot))

    def _send_graph_update(self) -> None:
        with self._graph_lock:
            clients = self._graph_clients()
            if not clients:
                self._graph_view = None
                return
            snapshot = self._snapshot()
            old, self._graph_view = self._graph_view, snapshot
            update = graph_update(old, snapshot) if old is not None else full_update(snapshot)
            for client in clients if update is not None else []:
                client.send_json(update or {})

    def _fetch_asset(self, client: ClientConnection, message: FetchAsset) -> None:
        try:
            data = self._assets.read(message.uri)
        except AssetError as exc:
            _log.warning("Foxglove: %s", exc)
            frame = encode_fetch_asset_response(message.request_id, error=str(exc))
        else:
            frame = encode_fetch_asset_response(message.request_id, data=data)
        client.send(frame, droppable=False)

    # ------------------------------------------------------------------ parameters, time
    def _get_params(self, client: ClientConnection, message: GetParameters) -> None:
        values = self._params.get(message.names)
        out: dict[str, Any] = {"op": "parameterValues", "parameters": values}
        if message.request_id is not None:
            out["id"] = message.request_id
        client.send_json(out)

    def _set_params(self, client: ClientConnection, message: SetParameters) -> None:
        problems = self._params.set(message.parameters)
        if problems:
            client.status(_WARNING, "setParameters refused: " + "; ".join(problems))
        names = tuple(name for name, _v, _h in message.parameters)
        self._get_params(client, GetParameters(names, message.request_id))

    def _on_params(self, event: Any) -> None:
        node = str(event.node)
        changed = [*event.new_parameters, *event.changed_parameters]
        with self._lock:
            clients = list(self._clients.values())
        for client in clients:
            names = _state(client).param_names
            if not names:
                continue
            params = [
                to_json_parameter(f"{node}.{p.name}", msg_to_value(p.value))
                for p in changed
                if f"{node}.{p.name}" in names
            ]
            if params:
                client.send_json({"op": "parameterValues", "parameters": params})

    def _on_clock(self, msg: Any) -> None:
        frame = encode_time(time_to_ns(msg.clock))
        for client in self.ws.clients:
            client.send(frame)


def _state(client: ClientConnection) -> ClientState:
    state = client.state.get("fg")
    if not isinstance(state, ClientState):
        state = ClientState()
        client.state["fg"] = state
    return state
