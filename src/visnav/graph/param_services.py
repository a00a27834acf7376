"""A node's parameters over the graph: rcl_interfaces' six services and /parameter_events.

What rclpy's ``start_parameter_services`` sets up, served by every node unless it is
created with ``start_parameter_services=False``:

* ``~/list_parameters``, ``~/get_parameters``, ``~/set_parameters``,
  ``~/set_parameters_atomically``, ``~/describe_parameters``,
  ``~/get_parameter_types`` (rcl_interfaces/srv/*), answered in the executor like any
  service;
* ``/parameter_events`` (rcl_interfaces/msg/ParameterEvent): declared parameters as
  ``new_parameters``, accepted sets as ``changed_parameters``. An event is built, and
  the node's publisher created, only once a subscription of the topic is in the graph,
  so nodes that declare many parameters pay nothing for it.

A refused set answers ``SetParametersResult(successful=False, reason=...)`` with the
reason the parameter store or the node's params dataclass gave
(:mod:`visnav.graph.param_dataclass`).

Conversions between Python values and ``rcl_interfaces/msg/ParameterValue`` are
:func:`value_to_msg` and :func:`msg_to_value`.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import zenoh

from visnav.graph.errors import ParameterError
from visnav.graph.keys import ros_type_to_dds
from visnav.graph.parameters import Parameter, ParameterType
from visnav.graph.qos import QoSProfile, qos_profile_parameters
from visnav.msgs.construct import default_message
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time

if TYPE_CHECKING:
    from visnav.graph.node import Node, Publisher
    from visnav.graph.service import Service

__all__ = [
    "PARAMETER_EVENTS_TOPIC",
    "PARAMETER_SERVICES",
    "ParameterServices",
    "descriptor_to_msg",
    "msg_to_value",
    "value_to_msg",
]

PARAMETER_EVENTS_TOPIC = "/parameter_events"
PARAMETER_SERVICES: tuple[tuple[str, str], ...] = (
    ("describe_parameters", "rcl_interfaces/srv/DescribeParameters"),
    ("get_parameter_types", "rcl_interfaces/srv/GetParameterTypes"),
    ("get_parameters", "rcl_interfaces/srv/GetParameters"),
    ("list_parameters", "rcl_interfaces/srv/ListParameters"),
    ("set_parameters", "rcl_interfaces/srv/SetParameters"),
    ("set_parameters_atomically", "rcl_interfaces/srv/SetParametersAtomically"),
)
"""``(~/suffix, service type)`` of the parameter services, as rclpy names them."""

_EVENTS_QOS = QoSProfile(depth=1000)
_PV = "rcl_interfaces/msg/ParameterValue"
_ARRAYS = {
    ParameterType.BYTE_ARRAY: ("byte_array_value", np.uint8),
    ParameterType.BOOL_ARRAY: ("bool_array_value", np.bool_),
    ParameterType.INTEGER_ARRAY: ("integer_array_value", np.int64),
    ParameterType.DOUBLE_ARRAY: ("double_array_value", np.float64),
}
_SCALARS = {
    ParameterType.BOOL: "bool_value",
    ParameterType.INTEGER: "integer_value",
    ParameterType.DOUBLE: "double_value",
    ParameterType.STRING: "string_value",
}


_dds_name = functools.cache(ros_type_to_dds)


def value_to_msg(value: Any) -> Any:
    """A Python parameter value as ``rcl_interfaces/msg/ParameterValue``.

    Raises:
        ParameterError: the value has no parameter type.
    """
    msg = default_message(_PV)
    kind = ParameterType.from_value(value)
    if isinstance(value, list | tuple) and not value:
        kind = ParameterType.STRING_ARRAY
    msg.type = kind.value
    if kind in _SCALARS:
        setattr(msg, _SCALARS[kind], value)
    elif kind in _ARRAYS:
        field, dtype = _ARRAYS[kind]
        if dtype is np.uint8:
            array = np.frombuffer(bytes(value), dtype=np.uint8).copy()
        else:
            array = np.asarray(value, dtype=dtype)
        setattr(msg, field, array)
    elif kind is ParameterType.STRING_ARRAY:
        msg.string_array_value = [str(v) for v in value]
    return msg


def msg_to_value(msg: Any) -> Any:
    """The Python value of a ``ParameterValue`` (None for NOT_SET).

    Raises:
        ParameterError: the type code is not one of rcl_interfaces' ParameterType.
    """
    try:
        kind = ParameterType(int(msg.type))
    except ValueError:
        text = f"parameter value type {msg.type!r} is not a ParameterType code (0-9)"
        raise ParameterError(text) from None
    if kind is ParameterType.NOT_SET:
        return None
    if kind in _SCALARS:
        value = getattr(msg, _SCALARS[kind])
        return value.item() if isinstance(value, np.generic) else value
    if kind is ParameterType.BYTE_ARRAY:
        return bytes(np.asarray(msg.byte_array_value, dtype=np.uint8))
    if kind in _ARRAYS:
        return np.asarray(getattr(msg, _ARRAYS[kind][0])).tolist()
    return list(msg.string_array_value)


def descriptor_to_msg(node: Node, name: str) -> Any:
    """``rcl_interfaces/msg/ParameterDescriptor`` of a declared parameter of ``node``."""
    msg = default_message("rcl_interfaces/msg/ParameterDescriptor")
    msg.name = name
    info = node.describe_parameter(name)
    msg.type = info.type.value
    msg.description = info.description
    msg.read_only = info.read_only
    if info.integer_range is not None:
        rng = get_message_class("rcl_interfaces/msg/IntegerRange")
        r = info.integer_range
        msg.integer_range = [rng(from_value=r.from_value, to_value=r.to_value, step=r.step)]
    if info.floating_point_range is not None:
        rng = get_message_class("rcl_interfaces/msg/FloatingPointRange")
        f = info.floating_point_range
        msg.floating_point_range = [
            rng(from_value=float(f.from_value), to_value=float(f.to_value), step=float(f.step))
        ]
    return msg


class ParameterServices:
    """The parameter services and event publisher of one node (made by :class:`Node`)."""

    def __init__(self, node: Node) -> None:
        self._node = node
        handlers = {
            "describe_parameters": self._describe,
            "get_parameter_types": self._types,
            "get_parameters": self._get,
            "list_parameters": self._list,
            "set_parameters": self._set,
            "set_parameters_atomically": self._set_atomically,
        }
        fqn = node.get_fully_qualified_name()
        plain = not node.remapping_rules
        self._by_name: dict[str, Service[Any, Any]] = {}
        for suffix, type_name in PARAMETER_SERVICES:
            # without remapping rules '~/x' is '<fqn>/x' (both parts already valid)
            name = f"{fqn}/{suffix}" if plain else node.resolve_topic_name(f"~/{suffix}")
            self._by_name[name] = node._add_service(
                get_service_type(type_name),
                name,
                handlers[suffix],
                qos_profile_parameters,
                deferred_token=True,
                queryable=not plain,
            )
        self._queryable: Any = None
        z = node.context.zenoh
        if plain and z is not None:
            # one queryable for the six (a Zenoh queryable each costs ~0.1 ms per node),
            # matching each one's key: domain, node name, suffix, rcl_interfaces type, hash
            key = f"{node.context.domain}{fqn}/*/rcl_interfaces::srv::dds_::$*/*"
            self._queryable = z.session.declare_queryable(
                key,
                zenoh.handlers.Callback(self._on_query, indirect=False),
                allowed_origin=zenoh.Locality.REMOTE,
            )
        self._events: Publisher[Any] | None = None
        self._listened = (-1, False)  # (graph version, a subscription exists)
        self._parameter_cls = get_message_class("rcl_interfaces/msg/Parameter")

    def _on_query(self, query: Any) -> None:
        """Route a remote request to its service by the key's name and type chunks."""
        chunks = str(query.key_expr).split("/")
        service = self._by_name.get("/" + "/".join(chunks[1:-2])) if len(chunks) > 3 else None
        if service is None or chunks[-2] != _dds_name(service.srv_type.name):
            with contextlib.suppress(Exception):
                query.reply_err(f"no parameter service at {query.key_expr}".encode())
            query.drop()
            return
        service._on_query(query)

    def close(self) -> None:
        """Undeclare the shared queryable (the node is being destroyed)."""
        if self._queryable is not None:
            with contextlib.suppress(Exception):
                self._queryable.undeclare()
            self._queryable = None

    # ------------------------------------------------------------------ events
    def publish_event(
        self, *, new: Sequence[Parameter] = (), changed: Sequence[Parameter] = ()
    ) -> None:
        """Publish a ParameterEvent, if anyone listens (else nothing is built).

        The publisher is created for the first event that has a subscription to go to:
        a Zenoh publisher per node on one key costs more the more nodes a process has
        (each new one is matched against the others), and most nodes never have a
        ``/parameter_events`` subscriber.
        """
        if not self._has_subscription():
            return
        pub = self._events
        if pub is None:
            event_cls = get_message_class("rcl_interfaces/msg/ParameterEvent")
            pub = self._node.create_publisher(event_cls, PARAMETER_EVENTS_TOPIC, _EVENTS_QOS)
            self._events = pub
        event = default_message("rcl_interfaces/msg/ParameterEvent")
        event.stamp = ns_to_time(self._node.get_clock().now_ns())
        event.node = self._node.get_fully_qualified_name()
        event.new_parameters = [self._param_msg(p) for p in new]
        event.changed_parameters = [self._param_msg(p) for p in changed]
        pub.publish(event)

    def _has_subscription(self) -> bool:
        graph = self._node.context.graph
        version, listened = self._listened
        if version != graph.version:
            listened = any(
                e.kind == "subscription" for e in graph.endpoints(PARAMETER_EVENTS_TOPIC)
            )
            self._listened = (graph.version, listened)
        return listened

    def _param_msg(self, p: Parameter) -> Any:
        return self._parameter_cls(name=p.name, value=value_to_msg(p.value))

    # ------------------------------------------------------------------ handlers
    def _describe(self, request: Any, response: Any) -> Any:
        node = self._node
        response.descriptors = [
            descriptor_to_msg(node, n) for n in request.names if node.has_parameter(n)
        ]
        return response

    def _types(self, request: Any, response: Any) -> Any:
        node = self._node
        codes = [
            node.describe_parameter(n).type.value if node.has_parameter(n) else 0
            for n in request.names
        ]
        response.types = np.asarray(codes, dtype=np.uint8)
        return response

    def _get(self, request: Any, response: Any) -> Any:
        node = self._node
        response.values = [
            value_to_msg(node.get_parameter(n).value)
            if node.has_parameter(n)
            else default_message(_PV)
            for n in request.names
        ]
        return response

    def _list(self, request: Any, response: Any) -> Any:
        prefixes = list(request.prefixes)
        depth = int(request.depth)
        names = []
        for name in self._node.parameter_names():
            if prefixes and not any(name == p or name.startswith(p + ".") for p in prefixes):
                continue
            if depth and name.count(".") >= depth:
                continue
            names.append(name)
        response.result.names = names
        response.result.prefixes = sorted({n.rsplit(".", 1)[0] for n in names if "." in n})
        return response

    def _to_params(self, messages: Sequence[Any]) -> list[Parameter]:
        return [Parameter(m.name, msg_to_value(m.value)) for m in messages]

    def _set_one(self, params: list[Parameter]) -> Any:
        result = default_message("rcl_interfaces/msg/SetParametersResult")
        try:
            outcome = self._node.set_parameters(params)
        except ParameterError as exc:
            result.successful, result.reason = False, str(exc)
            return result
        refused = [r for r in outcome if not r.successful]
        result.successful = not refused
        result.reason = refused[0].reason if refused else ""
        return result

    def _set(self, request: Any, response: Any) -> Any:
        out = []
        for m in request.parameters:
            try:
                params = self._to_params([m])
            except ParameterError as exc:
                r = default_message("rcl_interfaces/msg/SetParametersResult")
                r.successful, r.reason = False, str(exc)
                out.append(r)
                continue
            out.append(self._set_one(params))
        response.results = out
        return response

    def _set_atomically(self, request: Any, response: Any) -> Any:
        try:
            params = self._to_params(request.parameters)
        except ParameterError as exc:
            response.result.successful, response.result.reason = False, str(exc)
            return response
        response.result = self._set_one(params)
        return response
