"""rclpy-shaped nodes: publishers, subscriptions, timers, parameters, clock and logger.

Example::

    from visnav.graph import Context, Node
    from visnav.msgs import String

    with Context() as ctx:
        node = Node("talker", namespace="/demo", context=ctx)
        pub = node.create_publisher(String, "chatter", 10)
        node.create_timer(0.5, lambda: pub.publish(String(data="hi")))
        ctx.spin(duration_s=2.0)

Where visnav differs from rclpy: ``Node(..., context=None)`` makes a private
context owned by the node (rclpy uses a process-global default context; visnav
keeps no global state). Nodes that should share zero-copy in-process delivery and
one executor must be given the same :class:`~visnav.graph.Context`.
"""

from __future__ import annotations

import contextlib
import functools
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Generic, TypedDict, TypeVar

from visnav.graph.clock import Clock, ClockType
from visnav.graph.context import Context
from visnav.graph.errors import GraphError, TopicTypeConflictError
from visnav.graph.graph_cache import EndpointInfo
from visnav.graph.keys import EntityKind, topic_key
from visnav.graph.logger import NodeLogger
from visnav.graph.message_info import MessageInfo, encode_attachment
from visnav.graph.names import (
    RemapRule,
    parse_remap_rule,
    resolve_node_name_and_namespace,
    resolve_topic_name,
)
from visnav.graph.param_dataclass import ParameterDescriptor
from visnav.graph.param_services import ParameterServices
from visnav.graph.parameters import Parameter, ParameterStore, SetParametersResult
from visnav.graph.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    check_qos_compatibility,
    qos_profile_services_default,
    to_qos,
)
from visnav.graph.service import Client, Service
from visnav.graph.subscription import RemotePayload, Subscription
from visnav.graph.timer import Timer
from visnav.graph.token_keys import trusted_token
from visnav.msgs.serde import CdrSerializer, msg_type_name, typestore
from visnav.msgs.srv import ServiceType, get_service_type
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import Clock as ClockMsg

__all__ = [
    "Client",
    "Node",
    "NodeLogger",
    "NodeOptions",
    "Publisher",
    "RemotePayload",
    "Service",
    "Subscription",
    "Timer",
]

MsgT = TypeVar("MsgT")

_CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


@functools.cache
def _type_hash(type_name: str) -> str:
    return str(typestore().hash_rihs01(type_name))


@functools.lru_cache(maxsize=4096)
def _service_key(domain: int, name: str, type_name: str) -> str:
    return topic_key(domain, name, type_name, _type_hash(type_name))


class NodeOptions(TypedDict, total=False):
    """The keyword arguments of :class:`Node` other than its name, for subclasses to pass on.

    A node class written ``def __init__(self, name: str = "x", **node_kwargs:
    Unpack[NodeOptions])`` lets type checkers check ``SomeNode(namespace=..., context=...,
    parameter_overrides=...)`` against :class:`Node`'s own parameters.
    """

    context: Context | None
    namespace: str | None
    parameter_overrides: Mapping[str, Any] | Sequence[Parameter] | None
    remappings: Mapping[str, str] | Sequence[str] | None
    use_sim_time: bool | None
    start_parameter_services: bool


class Publisher(Generic[MsgT]):
    """Publishes one message type on one topic; made by :meth:`Node.create_publisher`.

    :meth:`publish` is thread-safe (as rclpy's): threads publishing on one publisher
    take turns, since the CDR serialization buffer is reused between messages.
    """

    def __init__(self, node: Node, msg_type: type[MsgT], topic_name: str, qos: QoSProfile) -> None:
        self.node = node
        self.msg_type = msg_type
        self.type_name = msg_type_name(msg_type)
        self.topic_name = topic_name
        self.qos = qos
        self.entity_id = node.context.next_id()
        self.targets: list[Subscription[Any]] = []
        transient = qos.durability is DurabilityPolicy.TRANSIENT_LOCAL
        self.history: deque[Any] | None = deque(maxlen=qos.queue_limit) if transient else None
        self._zpub: Any = None
        self._cdr = CdrSerializer(self.type_name)
        self._zid = node.context.zid
        self._lock = threading.Lock()
        self.sequence = 0

    def link(self, targets: list[Subscription[Any]]) -> None:
        """Set the in-process subscriptions this publisher delivers to (context's job)."""
        self.targets = targets

    def compatible_with(self, sub: Subscription[Any]) -> bool:
        """Whether this publisher's QoS can feed ``sub``."""
        return check_qos_compatibility(self.qos, sub.qos)[0]

    def publish(self, msg: MsgT) -> None:
        """Publish a message: in-process subscriptions get the same object (zero copy).

        Raises:
            TopicTypeConflictError: ``msg`` is not of the publisher's type.
        """
        if type(msg) is not self.msg_type:
            got = getattr(msg, "__msgtype__", type(msg).__name__)
            text = (
                f"publisher on '{self.topic_name}' carries {self.type_name} but was given {got}; "
                f"publish a {self.type_name} or create another publisher"
            )
            raise TopicTypeConflictError(text)
        # one message at a time: the serializer's buffer is reused until Zenoh has copied
        # it, and the sequence number in the attachment must be this message's own
        with self._lock:
            self.sequence += 1
            self.node.context.deliver_local(self, msg)
            zpub = self._zpub
            if zpub is not None and zpub.wants_sample():
                att = encode_attachment(self.sequence, time.time_ns(), self.entity_id, self._zid)
                zpub.put(self._cdr.serialize(msg), att)

    def local_info(self) -> MessageInfo:
        """The :class:`MessageInfo` of the message being delivered in-process."""
        now = time.time_ns()
        return MessageInfo(
            now, now, self.sequence, self.node.context.zid, self.entity_id, from_this_process=True
        )

    def has_listeners(self) -> bool:
        """Whether a message published now would reach anyone (in process or remote)."""
        zpub = self._zpub
        return bool(self.targets) or (zpub is not None and zpub.wants_sample())

    def get_subscription_count(self) -> int:
        """Number of matched subscriptions in the graph (all processes)."""
        return self.node.count_subscribers(self.topic_name)

    def destroy(self) -> None:
        """Remove the publisher."""
        self.node.destroy_publisher(self)


def _rules(remappings: Mapping[str, str] | Sequence[str] | None) -> list[RemapRule]:
    if remappings is None:
        return []
    if isinstance(remappings, Mapping):
        return [parse_remap_rule(f"{k}:={v}") for k, v in remappings.items()]
    return [parse_remap_rule(r) for r in remappings]


class Node:
    """A ROS-style node.

    Args:
        node_name: the node's name (no slashes).
        context: the graph context; None makes a private one owned by this node.
        namespace: the node's namespace (default ``/``).
        parameter_overrides: initial parameter values (a mapping or rclpy-style list of
            :class:`Parameter`).
        remappings: rules ``{"from": "to"}`` or ``["from:=to", "__ns:=/x"]``.
        use_sim_time: shortcut for the ``use_sim_time`` parameter override.
        start_parameter_services: serve the parameter services (``~/get_parameters``,
            ...) and publish ``/parameter_events`` (rclpy's option; default True).
    """

    def __init__(
        self,
        node_name: str,
        *,
        context: Context | None = None,
        namespace: str | None = None,
        parameter_overrides: Mapping[str, Any] | Sequence[Parameter] | None = None,
        remappings: Mapping[str, str] | Sequence[str] | None = None,
        use_sim_time: bool | None = None,
        start_parameter_services: bool = True,
    ) -> None:
        self._owns_context = context is None
        self.context = context if context is not None else Context()
        self._rules = _rules(remappings)
        name, ns = resolve_node_name_and_namespace(node_name, namespace or "/", self._rules)
        self._name = name
        self._namespace = ns
        self.node_id = self.context.next_id()
        self._publishers: list[Publisher[Any]] = []
        self._subscriptions: list[Subscription[Any]] = []
        self._timers: list[Timer] = []
        self._services: list[Service[Any, Any]] = []
        self._clients: list[Client[Any, Any]] = []
        self._descriptors: dict[str, ParameterDescriptor] = {}
        self._param_services: ParameterServices | None = None
        self._tokens: dict[int, tuple[str, Any]] = {}
        self._destroyed = False
        self._logger = NodeLogger(self.get_fully_qualified_name())
        self._clock = Clock(ClockType.ROS_TIME)
        overrides: dict[str, Any]
        if parameter_overrides is None:
            overrides = {}
        elif isinstance(parameter_overrides, Mapping):
            overrides = dict(parameter_overrides)
        else:
            overrides = {p.name: p.value for p in parameter_overrides}
        if use_sim_time is not None:
            overrides["use_sim_time"] = use_sim_time
        self._params = ParameterStore(self.get_fully_qualified_name(), overrides)
        self.context.register_node(self)
        self._announce(self.node_id, "NN")
        self._clock_sub: Subscription[Any] | None = None
        self._params.declare("use_sim_time", value=False)
        self._params.add_on_set_callback(self._on_params)
        self._apply_sim_time(bool(self._params.get("use_sim_time").value))
        if start_parameter_services:
            self._param_services = ParameterServices(self)

    # ------------------------------------------------------------------ identity
    def get_name(self) -> str:
        """The node's name."""
        return self._name

    def get_namespace(self) -> str:
        """The node's namespace."""
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        """``/namespace/name``."""
        return f"{self._namespace.rstrip('/')}/{self._name}"

    def get_logger(self) -> NodeLogger:
        """The node's logger."""
        return self._logger

    def get_clock(self) -> Clock:
        """The node's ROS clock (follows ``/clock`` when ``use_sim_time`` is true)."""
        return self._clock

    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str:
        """Expand (and, unless ``only_expand``, remap) a topic name for this node."""
        rules = [] if only_expand else self._rules
        return resolve_topic_name(topic, self._name, self._namespace, rules)

    # ------------------------------------------------------------------ graph tokens
    def _announce(
        self,
        entity_id: int,
        kind: str,
        topic: str | None = None,
        type_name: str | None = None,
        qos: QoSProfile | None = None,
        *,
        deferred: bool = False,
    ) -> None:
        key, token = trusted_token(
            self.context.domain,
            self.context.zid,
            self.node_id,
            entity_id,
            EntityKind(kind),
            self._namespace,
            self._name,
            topic=topic,
            type_name=type_name,
            type_hash=_type_hash(type_name) if type_name else None,
            qos=qos,
        )
        z = self.context.zenoh
        if deferred:
            handle: Any = self.context.declare_token_deferred(key)
        else:
            handle = z.token(key) if z is not None else None
        self._tokens[entity_id] = (key, handle)
        self.context.graph.put(key, token)

    def _retract(self, entity_id: int) -> None:
        key, handle = self._tokens.pop(entity_id, ("", None))
        if handle is not None:
            with contextlib.suppress(Exception):
                handle.undeclare()
        if key:
            self.context.graph.delete(key)

    # ------------------------------------------------------------------ entities
    def create_publisher(
        self, msg_type: type[MsgT], topic: str, qos_profile: QoSProfile | int
    ) -> Publisher[MsgT]:
        """Create a publisher (rclpy signature).

        Raises:
            TopicTypeConflictError: the topic already carries another type.
            InvalidNameError: the topic name is invalid.
        """
        self._check_alive()
        qos = to_qos(qos_profile)
        name = self.resolve_topic_name(topic)
        pub = Publisher(self, msg_type, name, qos)
        self.context.check_remote_type(name, pub.type_name)
        self.context.add_publisher(pub)
        self._publishers.append(pub)
        z = self.context.zenoh
        if z is not None:
            key = topic_key(self.context.domain, name, pub.type_name, _type_hash(pub.type_name))
            cache = qos.depth if qos.durability is DurabilityPolicy.TRANSIENT_LOCAL else None
            block = (
                qos.history is HistoryPolicy.KEEP_ALL
                and qos.reliability is ReliabilityPolicy.RELIABLE
            )
            pub._zpub = z.publisher(key, cache_depth=cache, block=block, publisher_id=pub.entity_id)
        self._announce(pub.entity_id, "MP", name, pub.type_name, qos)
        return pub

    def create_subscription(
        self,
        msg_type: type[MsgT],
        topic: str,
        callback: Callable[[MsgT], Any] | Callable[[MsgT, MessageInfo], Any],
        qos_profile: QoSProfile | int,
        *,
        raw: bool = False,
        paced: bool = False,
    ) -> Subscription[MsgT]:
        """Create a subscription (rclpy signature); ``callback(msg)`` runs in the executor.

        A callback taking two arguments gets ``(msg, MessageInfo)``. With ``raw=True`` it
        gets a :class:`~visnav.graph.subscription.SerializedMessage` (CDR bytes copied out
        of the transport only when read) instead of ``msg``. With ``paced=True`` (keep-last,
        volatile) remote samples wait in the transport until the executor takes them, and
        :meth:`Subscription.pause`/``resume`` hold them back (see
        :mod:`visnav.graph.subscription`).

        Raises:
            TopicTypeConflictError: the topic carries another type in this process.
            InvalidNameError: the topic name is invalid.
        """
        self._check_alive()
        qos = to_qos(qos_profile)
        name = self.resolve_topic_name(topic)
        sub = Subscription(self, msg_type, name, callback, qos, raw=raw, paced=paced)
        self.context.add_subscription(sub)
        self._subscriptions.append(sub)
        z = self.context.zenoh
        if z is not None:
            key = topic_key(self.context.domain, name, sub.type_name, _type_hash(sub.type_name))
            sub.attach_transport(z, key)
        self._announce(sub.entity_id, "MS", name, sub.type_name, qos)
        return sub

    def create_timer(
        self,
        timer_period_sec: float,
        callback: Callable[[], Any],
        *,
        clock: Clock | None = None,
    ) -> Timer:
        """Create a timer firing every ``timer_period_sec`` of the node's clock (or ``clock``)."""
        self._check_alive()
        timer = Timer(self, round(timer_period_sec * 1e9), callback, clock or self._clock)
        self.context.add_timer(timer)
        self._timers.append(timer)
        return timer

    def destroy_publisher(self, pub: Publisher[Any]) -> None:
        """Remove a publisher."""
        if pub in self._publishers:
            self._publishers.remove(pub)
            self.context.remove_publisher(pub)
            with pub._lock:  # a publish from another thread finishes first or sends nothing
                zpub, pub._zpub = pub._zpub, None
            if zpub is not None:
                zpub.close()
            self._retract(pub.entity_id)

    def destroy_subscription(self, sub: Subscription[Any]) -> None:
        """Remove a subscription."""
        if sub in self._subscriptions:
            self._subscriptions.remove(sub)
            self.context.remove_subscription(sub)
            if sub._zsub is not None:
                with contextlib.suppress(Exception):
                    sub._zsub.undeclare()
            self._retract(sub.entity_id)

    def destroy_timer(self, timer: Timer) -> None:
        """Remove a timer."""
        if timer in self._timers:
            timer.cancel()
            self._timers.remove(timer)
            self.context.remove_timer(timer)

    # ------------------------------------------------------------------ services
    def create_service(
        self,
        srv_type: ServiceType | str,
        srv_name: str,
        callback: Callable[[Any, Any], Any],
        *,
        qos_profile: QoSProfile | int = qos_profile_services_default,
    ) -> Service[Any, Any]:
        """Create a service server (rclpy signature): ``callback(request, response) -> response``.

        Args:
            srv_type: a :class:`~visnav.msgs.srv.ServiceType` or its name
                (``"std_srvs/srv/Trigger"``).
            srv_name: the service name (expanded and remapped as topics are).
            callback: runs in the executor; fills in and returns ``response``.
            qos_profile: its depth bounds the queue of waiting requests.

        Raises:
            UnknownMessageTypeError: an unknown service type.
            InvalidNameError: the name is invalid.
        """
        self._check_alive()
        stype = get_service_type(srv_type)
        name = self.resolve_topic_name(srv_name)
        return self._add_service(stype, name, callback, to_qos(qos_profile))

    def _add_service(
        self,
        stype: ServiceType,
        name: str,
        callback: Callable[[Any, Any], Any],
        qos: QoSProfile,
        *,
        deferred_token: bool = False,
        queryable: bool = True,
        service_cls: type[Service[Any, Any]] = Service,
    ) -> Service[Any, Any]:
        """Create a server of a resolved name (the parameter services' and actions' path)."""
        service: Service[Any, Any] = service_cls(self, stype, name, callback, qos)
        self.context.add_service(service)
        self._services.append(service)
        z = self.context.zenoh
        if z is not None and queryable:
            service.attach_transport(z.session, self._service_key(name, stype))
        self._announce(service.entity_id, "SS", name, stype.name, qos, deferred=deferred_token)
        return service

    def create_client(
        self,
        srv_type: ServiceType | str,
        srv_name: str,
        *,
        qos_profile: QoSProfile | int = qos_profile_services_default,
    ) -> Client[Any, Any]:
        """Create a service client (rclpy signature).

        Raises:
            UnknownMessageTypeError: an unknown service type.
            InvalidNameError: the name is invalid.
        """
        self._check_alive()
        stype = get_service_type(srv_type)
        name = self.resolve_topic_name(srv_name)
        qos = to_qos(qos_profile)
        client: Client[Any, Any] = Client(self, stype, name, qos)
        self._clients.append(client)
        z = self.context.zenoh
        if z is not None:
            client.attach_transport(z.session, self._service_key(name, stype))
        self._announce(client.entity_id, "SC", name, stype.name, qos)
        return client

    def _service_key(self, name: str, stype: ServiceType) -> str:
        return _service_key(self.context.domain, name, stype.name)

    def destroy_service(self, service: Service[Any, Any]) -> None:
        """Remove a service server (its queued requests are answered with an error)."""
        if service in self._services:
            self._services.remove(service)
            service.close_transport()
            self.context.remove_service(service)
            self._retract(service.entity_id)

    def destroy_client(self, client: Client[Any, Any]) -> None:
        """Remove a service client."""
        if client in self._clients:
            self._clients.remove(client)
            self._retract(client.entity_id)

    @property
    def remapping_rules(self) -> list[RemapRule]:
        """The node's remapping rules (empty when it has none)."""
        return list(self._rules)

    @property
    def services(self) -> list[Service[Any, Any]]:
        """This node's service servers."""
        return list(self._services)

    @property
    def clients(self) -> list[Client[Any, Any]]:
        """This node's service clients."""
        return list(self._clients)

    def get_service_names_and_types(self) -> list[tuple[str, list[str]]]:
        """``(service, [types])`` of every service with a server in the graph."""
        return self.context.graph.service_names_and_types()

    def destroy_node(self) -> None:
        """Remove the node and all its entities (closes a private context)."""
        if self._destroyed:
            return
        self._destroyed = True
        if self._param_services is not None:
            self._param_services.close()
        for srv in list(self._services):
            self.destroy_service(srv)
        for cli in list(self._clients):
            self.destroy_client(cli)
        for p in list(self._publishers):
            self.destroy_publisher(p)
        for s in list(self._subscriptions):
            self.destroy_subscription(s)
        for t in list(self._timers):
            self.destroy_timer(t)
        self._retract(self.node_id)
        self.context.unregister_node(self)
        if self._owns_context:
            self.context.shutdown()

    def _check_alive(self) -> None:
        if self._destroyed:
            msg = f"node {self.get_fully_qualified_name()} was destroyed"
            raise GraphError(msg)

    @property
    def publishers(self) -> list[Publisher[Any]]:
        """This node's publishers."""
        return list(self._publishers)

    @property
    def subscriptions(self) -> list[Subscription[Any]]:
        """This node's subscriptions."""
        return list(self._subscriptions)

    # ------------------------------------------------------------------ parameters
    def declare_parameter(
        self,
        name: str,
        value: Any = None,
        *,
        description: str = "",
        ignore_override: bool = False,
    ) -> Parameter:
        """Declare a parameter; overrides replace ``value``."""
        param = self._params.declare(
            name, value, description=description, ignore_override=ignore_override
        )
        if self._param_services is not None:
            self._param_services.publish_event(new=[param])
        return param

    def declare_parameters(
        self, namespace: str, parameters: Sequence[tuple[str, Any]]
    ) -> list[Parameter]:
        """Declare several parameters ``namespace.name``."""
        return self._params.declare_many(namespace, parameters)

    def get_parameter(self, name: str) -> Parameter:
        """Return a declared parameter."""
        return self._params.get(name)

    def get_parameter_or(self, name: str, alternative_value: Any = None) -> Parameter:
        """Return a parameter, or ``alternative_value`` when undeclared."""
        return self._params.get_or(name, alternative_value)

    def has_parameter(self, name: str) -> bool:
        """Whether a parameter is declared."""
        return self._params.has(name)

    def set_parameters(self, parameters: Sequence[Parameter]) -> list[SetParametersResult]:
        """Set declared parameters (all or none); accepted ones go to ``/parameter_events``.

        Raises:
            ParameterNotDeclaredError: a name is not declared.
            ParameterError: a value has the wrong type.
        """
        results = self._params.set(parameters)
        if self._param_services is not None and all(r.successful for r in results):
            changed = [self._params.get(p.name) for p in parameters]
            self._param_services.publish_event(changed=changed)
        return results

    def parameter_names(self) -> list[str]:
        """The declared parameter names, sorted."""
        return self._params.names()

    def set_parameter_descriptor(self, descriptor: ParameterDescriptor) -> None:
        """Record what a declared parameter is (range, read-only; ``describe_parameters``)."""
        self._descriptors[descriptor.name] = descriptor

    def describe_parameter(self, name: str) -> ParameterDescriptor:
        """The descriptor of a declared parameter (type and description at least).

        Raises:
            ParameterNotDeclaredError: not declared.
        """
        kind, description = self._params.info(name)
        known = self._descriptors.get(name)
        if known is not None:
            return known
        return ParameterDescriptor(name=name, type=kind, description=description)

    def add_on_set_parameters_callback(
        self, callback: Callable[[list[Parameter]], SetParametersResult]
    ) -> None:
        """Register a parameter validator."""
        self._params.add_on_set_callback(callback)

    @property
    def parameters(self) -> dict[str, Any]:
        """All parameter values."""
        return self._params.items()

    def _on_params(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name == "use_sim_time":
                self._apply_sim_time(bool(p.value))
        return SetParametersResult(successful=True)

    def _apply_sim_time(self, enabled: bool) -> None:
        self._clock.enable_sim_time(enabled=enabled)
        if enabled and self._clock_sub is None:
            self._clock_sub = self.create_subscription(
                ClockMsg, "/clock", self._on_clock, _CLOCK_QOS
            )
        elif not enabled and self._clock_sub is not None:
            self.destroy_subscription(self._clock_sub)
            self._clock_sub = None

    def _on_clock(self, msg: Any) -> None:
        self._clock.set_sim_time_ns(time_to_ns(msg.clock))
        self.context.wake()

    # ------------------------------------------------------------------ graph queries
    def get_node_names(self) -> list[str]:
        """Names of all nodes in the graph."""
        return [n.name for n in self.context.graph.nodes()]

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        """``(name, namespace)`` of all nodes in the graph."""
        return [(n.name, n.namespace) for n in self.context.graph.nodes()]

    def get_topic_names_and_types(self) -> list[tuple[str, list[str]]]:
        """``(topic, [types])`` of all topics in the graph."""
        return self.context.graph.topic_names_and_types()

    def get_publishers_info_by_topic(self, topic: str) -> list[EndpointInfo]:
        """Publishers of a topic (name expanded for this node)."""
        name = self.resolve_topic_name(topic, only_expand=True)
        return [e for e in self.context.graph.endpoints(name) if e.kind == "publisher"]

    def get_subscriptions_info_by_topic(self, topic: str) -> list[EndpointInfo]:
        """Subscriptions of a topic (name expanded for this node)."""
        name = self.resolve_topic_name(topic, only_expand=True)
        return [e for e in self.context.graph.endpoints(name) if e.kind == "subscription"]

    def count_publishers(self, topic: str) -> int:
        """Number of publishers of a topic in the graph."""
        return len(self.get_publishers_info_by_topic(topic))

    def count_subscribers(self, topic: str) -> int:
        """Number of subscriptions of a topic in the graph."""
        return len(self.get_subscriptions_info_by_topic(topic))
