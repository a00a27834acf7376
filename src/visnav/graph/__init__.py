"""The graph: names, QoS, nodes, topics, timers, parameters, clocks and the executor.

rclpy-shaped API; one :class:`Context` per graph participant, Zenoh between
processes (see :mod:`visnav.graph.transport`).
"""

from __future__ import annotations

from visnav.graph.action_client import ActionClient, ClientGoalHandle
from visnav.graph.action_server import ActionServer, ServerGoalHandle
from visnav.graph.action_types import ActionError, CancelResponse, GoalResponse, GoalStatus
from visnav.graph.clock import Clock, ClockType, TimePoint
from visnav.graph.context import Context
from visnav.graph.errors import (
    GraphError,
    ParameterAlreadyDeclaredError,
    ParameterError,
    ParameterNotDeclaredError,
    ServiceError,
    ServiceTimeoutError,
    TopicTypeConflictError,
    TransportError,
)
from visnav.graph.future import Future
from visnav.graph.graph_cache import EndpointInfo, GraphCache, NodeInfo
from visnav.graph.message_info import MessageInfo
from visnav.graph.names import (
    InvalidNameError,
    Remapping,
    RemapRule,
    expand_topic_name,
    parse_remap_rule,
    resolve_topic_name,
    validate_full_topic_name,
    validate_namespace,
    validate_node_name,
    validate_topic_name,
)
from visnav.graph.node import (
    Client,
    Node,
    NodeLogger,
    NodeOptions,
    Publisher,
    Service,
    Subscription,
    Timer,
)
from visnav.graph.param_dataclass import (
    ParamBinding,
    ParameterDescriptor,
    declare_params,
    param,
)
from visnav.graph.parameters import Parameter, ParameterType, SetParametersResult
from visnav.graph.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    check_qos_compatibility,
    qos_profile_latched,
    qos_profile_parameters,
    qos_profile_sensor_data,
    qos_profile_services_default,
    qos_profile_system_default,
    qos_profile_tf_static,
)
from visnav.graph.subscription import SerializedMessage

__all__ = [
    "ActionClient",
    "ActionError",
    "ActionServer",
    "CancelResponse",
    "Client",
    "ClientGoalHandle",
    "Clock",
    "ClockType",
    "Context",
    "DurabilityPolicy",
    "EndpointInfo",
    "Future",
    "GoalResponse",
    "GoalStatus",
    "GraphCache",
    "GraphError",
    "HistoryPolicy",
    "InvalidNameError",
    "MessageInfo",
    "RemapRule",
    "Remapping",
    "expand_topic_name",
    "parse_remap_rule",
    "resolve_topic_name",
    "validate_full_topic_name",
    "validate_namespace",
    "validate_node_name",
    "validate_topic_name",
    "Node",
    "NodeInfo",
    "NodeLogger",
    "NodeOptions",
    "ParamBinding",
    "Parameter",
    "ParameterAlreadyDeclaredError",
    "ParameterDescriptor",
    "ParameterError",
    "ParameterNotDeclaredError",
    "ParameterType",
    "Publisher",
    "QoSProfile",
    "ReliabilityPolicy",
    "SerializedMessage",
    "ServerGoalHandle",
    "Service",
    "ServiceError",
    "ServiceTimeoutError",
    "SetParametersResult",
    "Subscription",
    "TimePoint",
    "Timer",
    "TopicTypeConflictError",
    "TransportError",
    "check_qos_compatibility",
    "declare_params",
    "param",
    "qos_profile_latched",
    "qos_profile_parameters",
    "qos_profile_sensor_data",
    "qos_profile_services_default",
    "qos_profile_system_default",
    "qos_profile_tf_static",
]
