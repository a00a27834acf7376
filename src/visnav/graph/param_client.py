"""Reach another node's parameters through its parameter services (rclpy's ParameterClient).

The library behind ``visnav param``: every call is one service call to
``<node>/<service>`` with a timeout, and fails with a
:class:`~visnav.graph.errors.ServiceError` naming the node and the service when the
node does not serve its parameters (``start_parameter_services=False``) or is gone.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from visnav.graph.errors import ServiceError
from visnav.graph.param_services import msg_to_value, value_to_msg
from visnav.graph.parameters import Parameter, SetParametersResult
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type

if TYPE_CHECKING:
    from visnav.graph.node import Client, Node

__all__ = ["ParameterClient"]


class ParameterClient:
    """Calls the parameter services of one remote node.

    Args:
        node: the node that makes the calls (its executor need not spin: responses
            complete on the transport's thread).
        remote_node: the target's fully qualified name, e.g. ``/camera/driver``.
        timeout_sec: each call's timeout.
    """

    def __init__(self, node: Node, remote_node: str, *, timeout_sec: float = 5.0) -> None:
        self._node = node
        self.remote_node = remote_node if remote_node.startswith("/") else "/" + remote_node
        self.timeout_sec = timeout_sec
        self._clients: dict[str, Client[Any, Any]] = {}

    def _client(self, suffix: str, type_name: str) -> Client[Any, Any]:
        client = self._clients.get(suffix)
        if client is None:
            name = f"{self.remote_node.rstrip('/')}/{suffix}"
            client = self._node.create_client(get_service_type(type_name), name)
            self._clients[suffix] = client
        return client

    def _call(self, suffix: str, type_name: str, **fields: Any) -> Any:
        client = self._client(suffix, type_name)
        if not client.wait_for_service(self.timeout_sec):
            msg = (
                f"node {self.remote_node} does not serve {client.srv_name} "
                f"(not running, or started with start_parameter_services=False); "
                "check `visnav node list`"
            )
            raise ServiceError(msg)
        request = client.srv_type.Request(**fields) if fields else client.srv_type.Request()
        return client.call(request, timeout_sec=self.timeout_sec)

    def wait_for_services(self, timeout_sec: float | None = None) -> bool:
        """Whether the node's ``get_parameters`` service appears within ``timeout_sec``."""
        client = self._client("get_parameters", "rcl_interfaces/srv/GetParameters")
        return client.wait_for_service(self.timeout_sec if timeout_sec is None else timeout_sec)

    def list_parameters(self, prefixes: Sequence[str] = (), depth: int = 0) -> list[str]:
        """Names of the node's parameters (optionally under ``prefixes``), sorted."""
        response = self._call(
            "list_parameters",
            "rcl_interfaces/srv/ListParameters",
            prefixes=list(prefixes),
            depth=depth,
        )
        return sorted(response.result.names)

    def get_parameters(self, names: Sequence[str]) -> list[Any]:
        """Values of ``names`` (None for an undeclared one)."""
        response = self._call(
            "get_parameters", "rcl_interfaces/srv/GetParameters", names=list(names)
        )
        return [msg_to_value(v) for v in response.values]

    def get_parameter_types(self, names: Sequence[str]) -> list[int]:
        """rcl_interfaces ParameterType codes of ``names`` (0 when undeclared)."""
        response = self._call(
            "get_parameter_types", "rcl_interfaces/srv/GetParameterTypes", names=list(names)
        )
        return [int(t) for t in response.types]

    def describe_parameters(self, names: Sequence[str]) -> list[Any]:
        """``rcl_interfaces/msg/ParameterDescriptor`` of the declared ones of ``names``."""
        response = self._call(
            "describe_parameters", "rcl_interfaces/srv/DescribeParameters", names=list(names)
        )
        return list(response.descriptors)

    def _messages(self, parameters: Sequence[Parameter]) -> list[Any]:
        cls = get_message_class("rcl_interfaces/msg/Parameter")
        return [cls(name=p.name, value=value_to_msg(p.value)) for p in parameters]

    def set_parameters(self, parameters: Sequence[Parameter]) -> list[SetParametersResult]:
        """Set each parameter on its own; one result (with the refusal's reason) each."""
        response = self._call(
            "set_parameters",
            "rcl_interfaces/srv/SetParameters",
            parameters=self._messages(parameters),
        )
        return [SetParametersResult(bool(r.successful), str(r.reason)) for r in response.results]

    def set_parameters_atomically(self, parameters: Sequence[Parameter]) -> SetParametersResult:
        """Set all parameters or none."""
        response = self._call(
            "set_parameters_atomically",
            "rcl_interfaces/srv/SetParametersAtomically",
            parameters=self._messages(parameters),
        )
        return SetParametersResult(bool(response.result.successful), str(response.result.reason))

    def close(self) -> None:
        """Destroy the clients."""
        for client in self._clients.values():
            self._node.destroy_client(client)
        self._clients.clear()
