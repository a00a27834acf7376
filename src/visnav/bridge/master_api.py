"""Client of the ROS 1 master's XML-RPC API and the environment that locates it.

``ROS_MASTER_URI`` names the master; ``ROS_HOSTNAME``, else ``ROS_IP``, is the address this
process advertises to its peers (rospy's order, from ``rosgraph.network``) and the only address
it listens on (:func:`node_addresses`).
"""

from __future__ import annotations

import http.client
import ipaddress
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
    "node_addresses",
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


def _is_loopback(address: str) -> bool:
    return address == "::1" or address.startswith("127.")


def bind_address(host: str) -> str:
    """The address to listen on for an advertised host: that host's own address only.

    ``localhost`` (and ``::1``) give ``127.0.0.1``; an IP address is used as it is; a host
    name is resolved (IPv4: Debian's ``/etc/hosts`` maps the host name to ``127.0.1.1``,
    which is then the address). Never all interfaces: a peer reaches the node only at the
    address it is told, so listening elsewhere only lets others in.

    Raises:
        BridgeError: the host name does not resolve.
    """
    host = host.strip()
    if host in ("localhost", "::1"):
        return "127.0.0.1"
    try:
        ipaddress.ip_address(host)
    except ValueError:
        pass
    else:
        return host
    try:
        infos = socket.getaddrinfo(host, None, socket.AF_INET, socket.SOCK_STREAM)
    except OSError as exc:
        msg = (
            f"ROS_HOSTNAME={host!r} does not resolve ({exc}): set it to a name of this machine, "
            "or set ROS_IP to one of its addresses"
        )
        raise BridgeError(msg) from exc
    return str(infos[0][4][0])


def _route_source(host: str, port: int) -> str:
    """This machine's address on the route to ``host`` (a UDP connect: nothing is sent)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.connect((host, port))
        return str(probe.getsockname()[0])


def node_addresses(master_uri: str, env: Mapping[str, str] | None = None) -> tuple[str, str]:
    """``(advertised host, bind address)`` of a ROS 1 node of this process.

    * ``ROS_HOSTNAME``, else ``ROS_IP``, set: peers are told that, and the node listens on
      its address only (:func:`bind_address`).
    * Neither set and the master on loopback (``localhost``, ``127.*``): ``127.0.0.1`` for
      both; nothing outside this machine can reach the node.
    * Neither set and the master elsewhere: this machine's address on the route to the
      master, for both (rospy would tell the host name and listen on all interfaces).

    Raises:
        BridgeError: ``ROS_HOSTNAME`` does not resolve, or the master's host cannot be
            resolved or routed to.
    """
    env = os.environ if env is None else env
    for key in ("ROS_HOSTNAME", "ROS_IP"):
        value = env.get(key, "").strip()
        if value:
            return value, bind_address(value)
    parts = urlsplit(master_uri)
    master_host = parts.hostname or "localhost"
    try:
        infos = socket.getaddrinfo(master_host, None, socket.AF_INET, socket.SOCK_STREAM)
        master_ip = str(infos[0][4][0])
        if master_host == "localhost" or _is_loopback(master_ip):
            return "127.0.0.1", "127.0.0.1"
        own = _route_source(master_ip, parts.port or 11311)
    except OSError as exc:
        msg = (
            f"cannot find this machine's address towards the ROS 1 master {master_uri} "
            f"({exc}); set ROS_IP to the address other ROS 1 nodes reach this machine at"
        )
        raise BridgeError(msg) from exc
    return own, own


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

    def register_service(self, service: str, service_api: str, api: str) -> None:
        """Register as the provider of a service (``rosrpc://host:port``)."""
        self.call("registerService", service, service_api, api)

    def unregister_service(self, service: str, service_api: str) -> None:
        """Unregister a service."""
        self.call("unregisterService", service, service_api)

    def lookup_service(self, service: str) -> str:
        """The ``rosrpc://`` URI of a service's provider.

        Raises:
            MasterError: no node provides it.
        """
        return str(self.call("lookupService", service))

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
