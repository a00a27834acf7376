"""Errors of :mod:`visnav.graph`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = [
    "GraphError",
    "LoggerError",
    "ParameterAlreadyDeclaredError",
    "ParameterError",
    "ParameterNotDeclaredError",
    "ServiceError",
    "ServiceTimeoutError",
    "TopicTypeConflictError",
    "TransportError",
]


class GraphError(VisnavError):
    """A node, topic or executor operation failed."""


class LoggerError(GraphError, ValueError):
    """A logger call has a bad filter parameter, or changed its filters at one call site."""


class TopicTypeConflictError(GraphError, TypeError):
    """A topic is used with a second message type."""


class TransportError(GraphError):
    """The inter-process transport (Zenoh) could not be configured or opened."""


class ParameterError(GraphError, ValueError):
    """A parameter value or declaration is invalid."""


class ParameterNotDeclaredError(ParameterError, LookupError):
    """A parameter was read or set before being declared."""


class ParameterAlreadyDeclaredError(ParameterError):
    """A parameter was declared twice."""


class ServiceError(GraphError):
    """A service call failed: the server raised, went away or sent a bad reply."""


class ServiceTimeoutError(ServiceError, TimeoutError):
    """A service call got no response within its timeout."""
