"""Client of the ROS 1 master's XML-RPC API and the environment that locates it.

``ROS_MASTER_URI`` names the master; ``ROS_HOSTNAME``, else ``ROS_IP``, is the address this
process advertises to its peers, else the host name (rospy's order, from ``rosgraph.network``).
"""

from __future__ import annotations

import http.client
import os
import socket
import xmlrpc.client
from collections.abc import Mapping
from typing import Any
from urllib.parse import urlsplit

from visnav.bridge.errors import BridgeError, MasterError, MasterUnreachableError

__all__ = [
    "DEFAULT_MASTER_URI",
    "MasterClient",
    "advertised_host",
    "bind_address",
    "master_uri_from_env",
    "xmlrpc_proxy",
]

DEFAULT_MASTER_URI = "http://localhost:11311/"


def master_uri_from_env(env: Mapping[str, str] | None = None) -> str:
    """Return ``ROS_MASTER_URI`` (rospy's default ``http://localhost:11311/`` when unset).

    Raises:
        BridgeError: the value is not an ``http://host:port`` URI.
    """
    env = os.environ if env is None else env
    uri = env.get("ROS_MASTER_URI", "") or DEFAULT_MASTER_URI
    parts = urlsplit(uri)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "http" or not parts.hostname or port is None:
        msg = (
            f"ROS_MASTER_URI is {uri!r}: expected http://HOST:PORT/, "
            "e.g. export ROS_MASTER_URI=http://localhost:11311/"
        )
        raise BridgeError(msg)
    return uri


def advertised_host(env: Mapping[str, str] | None = None) -> str:
    """The address peers use to reach this process: ROS_HOSTNAME, ROS_IP, else the host name.

    As rospy: a host name of ``localhost`` or ``127.*`` is replaced by this machine's address
    only when it comes from ``socket.gethostname()``, not when the user set it.
    """
    env = os.environ if env is None else env
    for key in ("ROS_HOSTNAME", "ROS_IP"):
        value = env.get(key, "").strip()
        if value:
            return value
    name = socket.gethostname()
    if not name or name == "localhost" or name.startswith("127."):
        try:
            return socket.gethostbyname(socket.getfqdn())
        except OSError:
            return "127.0.0.1"
    return name


def bind_address(host: str) -> str:
    """The address to listen on for an advertised host: loopback stays loopback (as rospy)."""
    if host in ("localhost", "::1") or host.startswith("127."):
        return "127.0.0.1"
    return "0.0.0.0"  # noqa: S104 - peers on other machines must reach the node, as rospy


class _TimeoutTransport(xmlrpc.client.Transport):
    def __init__(self, timeout_s: float) -> None:
        super().__init__()
        self._timeout_s = timeout_s

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        conn = super().make_connection(host)
        conn.timeout = self._timeout_s
        return conn


def xmlrpc_proxy(uri: str, *, timeout_s: float = 5.0) -> xmlrpc.client.ServerProxy:
    """An XML-RPC proxy with a socket timeout (a new one per thread: proxies are not shared)."""
    return xmlrpc.client.ServerProxy(uri, transport=_TimeoutTransport(timeout_s), allow_none=True)


class MasterClient:
    """Calls the ROS 1 master's API as one caller id.

    Args:
        uri: the master's URI.
        caller_id: this node's name, e.g. ``/visnav_bridge``.
        timeout_s: socket timeout of each call.
    """

    def __init__(self, uri: str, caller_id: str, *, timeout_s: float = 5.0) -> None:
        self.uri = uri
        self.caller_id = caller_id
        self.timeout_s = timeout_s

    def call(self, method: str, *args: Any) -> Any:
        """Call ``method(caller_id, *args)``; return the value of a ``[code, msg, value]`` reply.

        Raises:
            MasterUnreachableError: nothing answers at the URI (says how to start a master).
            MasterError: the master answered with an error code or a fault.
        """
        proxy = xmlrpc_proxy(self.uri, timeout_s=self.timeout_s)
        try:
            reply = getattr(proxy, method)(self.caller_id, *args)
        except (OSError, http.client.HTTPException) as exc:
            msg = (
                f"no ROS 1 master at ROS_MASTER_URI={self.uri} ({exc}); start one with "
                "`roscore` or let the bridge serve one: visnav bridge ros1 --serve-master"
            )
            raise MasterUnreachableError(msg) from exc
        except xmlrpc.client.Fault as exc:
            msg = f"ROS 1 master at {self.uri} failed {method}: {exc.faultString}"
            raise MasterError(msg) from exc
        if not isinstance(reply, list) or len(reply) != 3:
            msg = (
                f"ROS 1 master at {self.uri} answered {method} with {reply!r}: "
                "expected [code, message, value]"
            )
            raise MasterError(msg)
        code, text, value = reply
        if code != 1:
            msg = f"ROS 1 master at {self.uri} refused {method}{args!r}: {text} (code {code})"
            raise MasterError(msg)
        return value

    def ping(self) -> int:
        """Return the master's process id (checks that it is there)."""
        return int(self.call("getPid"))

    def register_publisher(self, topic: str, type_name: str, api: str) -> list[str]:
        """Register a publication; return the subscribers' slave URIs."""
        return list(self.call("registerPublisher", topic, type_name, api))

    def unregister_publisher(self, topic: str, api: str) -> None:
        """Unregister a publication."""
        self.call("unregisterPublisher", topic, api)

    def register_subscriber(self, topic: str, type_name: str, api: str) -> list[str]:
        """Register a subscription; return the publishers' slave URIs."""
        return list(self.call("registerSubscriber", topic, type_name, api))

    def unregister_subscriber(self, topic: str, api: str) -> None:
        """Unregister a subscription."""
        self.call("unregisterSubscriber", topic, api)

    def system_state(self) -> tuple[list[Any], list[Any], list[Any]]:
        """Return ``(publishers, subscribers, services)``, each ``[[name, [node, ...]], ...]``."""
        pubs, subs, srvs = self.call("getSystemState")
        return list(pubs), list(subs), list(srvs)

    def topic_types(self) -> dict[str, str]:
        """Return ``{topic: ROS 1 type}`` of every topic the master knows."""
        return {str(t): str(ty) for t, ty in self.call("getTopicTypes")}

    def set_param(self, key: str, value: Any) -> None:
        """Set a parameter on the master's parameter server."""
        self.call("setParam", key, value)

    def get_param(self, key: str) -> Any:
        """Return a parameter's value.

        Raises:
            MasterError: the parameter is not set.
        """
        return self.call("getParam", key)
