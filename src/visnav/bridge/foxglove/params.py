"""The ``parameters`` capability: Foxglove parameter names and values <-> visnav parameter services.

A Foxglove parameter is named ``<node>.<parameter>`` with the node's fully qualified name
(``/move_base.controller_frequency``), as foxglove_bridge names ROS 2 parameters; node names
cannot contain a dot, parameter names can (``/amcl.initial_pose.x``), so the name splits at
the first dot. Values are JSON: numbers, booleans, strings and arrays of them; a double is
sent with the type hint ``float64`` (``float64_array`` for arrays) so that ``2.0`` stays a
double in a client that writes it back, and a byte array is base64 text with the hint
``byte_array``. Each request is one service call per node (:class:`ParameterClient`), made
on a worker thread, never on the executor or the WebSocket loop.
"""

from __future__ import annotations

import base64
import binascii
import logging
import math
import re
import threading
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

from visnav.bridge.foxglove.errors import FoxgloveError
from visnav.graph.param_client import ParameterClient
from visnav.graph.parameters import Parameter

if TYPE_CHECKING:
    from visnav.graph.node import Node

__all__ = ["ParameterGateway", "from_json_value", "split_name", "to_json_parameter"]

_log = logging.getLogger("visnav.foxglove")
_GET_TYPE = "rcl_interfaces/srv/GetParameters"


def split_name(name: str) -> tuple[str, str]:
    """Split ``/node.param`` into the node's name and the parameter's.

    Raises:
        FoxgloveError: no dot, or an empty node or parameter part.
    """
    node, dot, param = name.partition(".")
    if not dot or not node or not param:
        msg = (
            f"parameter name {name!r}: expected '<node>.<parameter>' with the node's full "
            "name, e.g. '/move_base.controller_frequency'"
        )
        raise FoxgloveError(msg)
    return (node if node.startswith("/") else "/" + node), param


def to_json_parameter(name: str, value: Any) -> dict[str, Any]:
    """A Foxglove ``Parameter`` object for a visnav parameter value."""
    out: dict[str, Any] = {"name": name}
    if isinstance(value, (bytes, bytearray)):
        out["value"] = base64.b64encode(bytes(value)).decode()
        out["type"] = "byte_array"
    elif isinstance(value, float):
        out["value"] = value if math.isfinite(value) else None
        out["type"] = "float64"
    elif isinstance(value, (list, tuple)) and value and all(isinstance(v, float) for v in value):
        out["value"] = [v if math.isfinite(v) else None for v in value]
        out["type"] = "float64_array"
    else:
        out["value"] = list(value) if isinstance(value, tuple) else value
    return out


def from_json_value(name: str, value: Any, hint: str | None) -> Any:
    """The visnav value of a Foxglove parameter value (with its optional type hint).

    Raises:
        FoxgloveError: the value does not match its hint, or has no parameter type.
    """
    try:
        if hint == "byte_array":
            if not isinstance(value, str):
                raise TypeError(type(value).__name__)
            return base64.b64decode(value, validate=True)
        if hint == "float64":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(type(value).__name__)
            return float(value)
        if hint == "float64_array":
            if not isinstance(value, list) or any(
                isinstance(v, bool) or not isinstance(v, (int, float)) for v in value
            ):
                raise TypeError(type(value).__name__)
            return [float(v) for v in value]
    except (TypeError, ValueError, binascii.Error) as exc:
        msg = f"parameter {name!r}: value {value!r} does not match its type {hint!r} ({exc})"
        raise FoxgloveError(msg) from exc
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list) and _uniform(value):
        return value
    msg = (
        f"parameter {name!r}: value {value!r} is not a parameter value; expected a number, "
        "boolean, string or an array of one of them"
    )
    raise FoxgloveError(msg)


def _uniform(values: list[Any]) -> bool:
    kinds = {bool if isinstance(v, bool) else type(v) for v in values}
    return kinds <= {str} or kinds <= {bool} or kinds <= {int} or kinds <= {int, float}


class ParameterGateway:
    """Get and set parameters of every visnav node through its parameter services.

    Args:
        node: the bridge's node (its clients make the calls).
        whitelist: regular expressions (full match) of ``<node>.<param>`` names served.
        timeout_s: timeout of each service call.
    """

    def __init__(
        self, node: Node, *, whitelist: Sequence[str] = (".*",), timeout_s: float = 2.0
    ) -> None:
        self._node = node
        self._patterns = [re.compile(p) for p in whitelist]
        self._timeout = timeout_s
        self._clients: dict[str, ParameterClient] = {}
        self._lock = threading.Lock()

    def allowed(self, name: str) -> bool:
        """Whether ``name`` matches the parameter whitelist."""
        return any(p.fullmatch(name) for p in self._patterns)

    def _client(self, node_name: str) -> ParameterClient:
        with self._lock:
            client = self._clients.get(node_name)
            if client is None:
                client = ParameterClient(self._node, node_name, timeout_sec=self._timeout)
                self._clients[node_name] = client
            return client

    def _serving_nodes(self) -> list[str]:
        graph = self._node.context.graph
        out = []
        for info in graph.nodes():
            fqn = info.fully_qualified_name
            if info.name.startswith("_"):
                continue
            if graph.has_service_server(f"{fqn.rstrip('/')}/get_parameters", _GET_TYPE):
                out.append(fqn)
        return sorted(set(out))

    def get(self, names: Sequence[str]) -> list[dict[str, Any]]:
        """Foxglove ``Parameter`` objects of ``names`` (empty: every node's parameters).

        Nodes that do not answer are skipped (their parameters are left out), as
        foxglove_bridge does.
        """
        wanted: dict[str, list[str]] = {}
        if names:
            for name in names:
                node, param = split_name(name)
                wanted.setdefault(node, []).append(param)
        else:
            for node in self._serving_nodes():
                try:
                    wanted[node] = self._client(node).list_parameters()
                except Exception as exc:  # noqa: BLE001 - a node that does not answer is left out
                    _log.debug("Foxglove: %s does not list its parameters: %s", node, exc)
                    continue
        out: list[dict[str, Any]] = []
        for node, params in wanted.items():
            try:
                values = self._client(node).get_parameters(params)
            except Exception as exc:  # noqa: BLE001 - as above
                _log.debug("Foxglove: %s does not give its parameters: %s", node, exc)
                continue
            for param, value in zip(params, values, strict=False):
                full = f"{node}.{param}"
                if value is not None and self.allowed(full):
                    out.append(to_json_parameter(full, value))
        return out

    def set(self, parameters: Iterable[tuple[str, Any, str | None]]) -> list[str]:
        """Set parameters (each on its own); returns the refusals' reasons.

        Raises:
            FoxgloveError: a name is malformed or not whitelisted, or a value is invalid.
        """
        by_node: dict[str, list[Parameter]] = {}
        for name, value, hint in parameters:
            node, param = split_name(name)
            if not self.allowed(name):
                msg = f"parameter {name!r} is not in the bridge's param_whitelist"
                raise FoxgloveError(msg)
            by_node.setdefault(node, []).append(
                Parameter(param, from_json_value(name, value, hint))
            )
        problems = []
        for node, todo in by_node.items():
            results = self._client(node).set_parameters(todo)
            for item, result in zip(todo, results, strict=False):
                if not result.successful:
                    problems.append(f"{node}.{item.name}: {result.reason}")
        return problems

    def close(self) -> None:
        """Destroy the service clients."""
        with self._lock:
            for client in self._clients.values():
                client.close()
            self._clients.clear()
