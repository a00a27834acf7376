"""A minimal ROS 1 master and parameter server (``visnav bridge ros1 --serve-master``).

Implements the master API calls nodes and the ``ros*`` tools make: registration of publishers,
subscribers and services (with ``publisherUpdate`` to subscribers), ``lookupNode``,
``lookupService``, ``getPublishedTopics``, ``getTopicTypes``, ``getSystemState``, ``getUri``,
``getPid``, and the parameter server (``setParam``, ``getParam``, ``hasParam``, ``deleteParam``,
``searchParam``, ``getParamNames``, ``subscribeParam``, ``unsubscribeParam`` with
``paramUpdate``). It keeps everything in memory; binds 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from typing import Any

from visnav.bridge.errors import BridgeError
from visnav.bridge.master_api import xmlrpc_proxy
from visnav.bridge.ros1_node import ThreadingXmlRpcServer

__all__ = ["Ros1Master", "resolve_param_key"]

_log = logging.getLogger("visnav.bridge.master")
_MASTER_ID = "/master"


def _namespace(caller_id: str) -> str:
    return caller_id.rsplit("/", 1)[0] + "/" if "/" in caller_id.strip("/") else "/"


def resolve_param_key(caller_id: str, key: str) -> str:
    """Resolve a parameter key as rosmaster does: relative to the caller's namespace, ``~`` private.

    Returns:
        The absolute key without a trailing slash (``/`` for the root).
    """
    if key.startswith("~"):
        key = f"{caller_id.rstrip('/')}/{key[1:]}"
    elif not key.startswith("/"):
        key = _namespace(caller_id) + key
    return "/" + "/".join(p for p in key.split("/") if p)


class Ros1Master:
    """The master: serves the XML-RPC API on its own threads until :meth:`close`.

    Args:
        port: TCP port (0 picks a free one; roscore uses 11311).
        host: address to listen on.

    Raises:
        BridgeError: the port is taken (names it and what to do).
    """

    def __init__(self, port: int = 11311, *, host: str = "127.0.0.1") -> None:
        self._lock = threading.RLock()
        self._pubs: dict[str, dict[str, str]] = {}
        self._subs: dict[str, dict[str, str]] = {}
        self._srvs: dict[str, tuple[str, str]] = {}
        self._types: dict[str, str] = {}
        self._nodes: dict[str, str] = {}
        self._params: dict[str, Any] = {}
        self._param_subs: dict[str, dict[str, str]] = {}
        try:
            self._server = ThreadingXmlRpcServer((host, port))
        except OSError as exc:
            msg = (
                f"cannot serve a ROS 1 master on {host}:{port}: {exc.strerror or exc}; is "
                f"roscore (or another master) running there? Use it (drop --serve-master) or "
                f"pick a free port: --serve-master PORT"
            )
            raise BridgeError(msg) from exc
        for name in dir(self):
            if name.startswith("_api_"):
                self._server.register_function(getattr(self, name), name[5:])
        self.port = int(self._server.server_address[1])
        self.uri = f"http://{host}:{self.port}/"
        self._thread = threading.Thread(
            target=self._server.serve_forever, args=(0.1,), name="ros1-master", daemon=True
        )

    def start(self) -> None:
        """Start serving."""
        self._thread.start()

    def close(self) -> None:
        """Stop serving (idempotent)."""
        if self._thread.is_alive():
            self._server.shutdown()
        self._server.server_close()

    # ------------------------------------------------------------------ helpers
    def _notify(self, api: str, method: str, *args: Any) -> None:
        def call() -> None:
            with contextlib.suppress(Exception):
                getattr(xmlrpc_proxy(api, timeout_s=3.0), method)(_MASTER_ID, *args)

        threading.Thread(target=call, daemon=True).start()

    def _node(self, caller_id: str, api: str) -> None:
        self._nodes[caller_id] = api

    def _publisher_update(self, topic: str) -> None:
        pubs = list(self._pubs.get(topic, {}).values())
        for api in self._subs.get(topic, {}).values():
            self._notify(api, "publisherUpdate", topic, pubs)

    # ------------------------------------------------------------------ registration
    def _api_registerPublisher(  # noqa: N802 - ROS API name
        self, caller_id: str, topic: str, topic_type: str, caller_api: str
    ) -> list[Any]:
        with self._lock:
            self._node(caller_id, caller_api)
            self._pubs.setdefault(topic, {})[caller_id] = caller_api
            if topic_type != "*" or topic not in self._types:
                self._types[topic] = topic_type
            subs = list(self._subs.get(topic, {}).values())
            self._publisher_update(topic)
        return [1, f"Registered [{caller_id}] as publisher of [{topic}]", subs]

    def _api_unregisterPublisher(  # noqa: N802
        self, caller_id: str, topic: str, caller_api: str
    ) -> list[Any]:
        with self._lock:
            pubs = self._pubs.get(topic, {})
            if pubs.get(caller_id) != caller_api:
                return [1, f"[{caller_id}] is not a publisher of [{topic}]", 0]
            del pubs[caller_id]
            self._publisher_update(topic)
        return [1, f"Unregistered [{caller_id}] as publisher of [{topic}]", 1]

    def _api_registerSubscriber(  # noqa: N802
        self, caller_id: str, topic: str, topic_type: str, caller_api: str
    ) -> list[Any]:
        with self._lock:
            self._node(caller_id, caller_api)
            self._subs.setdefault(topic, {})[caller_id] = caller_api
            if topic_type != "*" and topic not in self._types:
                self._types[topic] = topic_type
            pubs = list(self._pubs.get(topic, {}).values())
        return [1, f"Subscribed to [{topic}]", pubs]

    def _api_unregisterSubscriber(  # noqa: N802
        self, caller_id: str, topic: str, caller_api: str
    ) -> list[Any]:
        with self._lock:
            subs = self._subs.get(topic, {})
            if subs.get(caller_id) != caller_api:
                return [1, f"[{caller_id}] is not a subscriber of [{topic}]", 0]
            del subs[caller_id]
        return [1, f"Unsubscribed [{caller_id}] from [{topic}]", 1]

    def _api_registerService(  # noqa: N802
        self, caller_id: str, service: str, service_api: str, caller_api: str
    ) -> list[Any]:
        with self._lock:
            self._node(caller_id, caller_api)
            self._srvs[service] = (caller_id, service_api)
        return [1, f"Registered [{caller_id}] as provider of [{service}]", 1]

    def _api_unregisterService(  # noqa: N802
        self, caller_id: str, service: str, service_api: str
    ) -> list[Any]:
        with self._lock:
            if self._srvs.get(service) == (caller_id, service_api):
                del self._srvs[service]
                return [1, f"Unregistered [{service}]", 1]
        return [1, f"[{caller_id}] is not the provider of [{service}]", 0]

    def _api_lookupService(self, caller_id: str, service: str) -> list[Any]:  # noqa: N802
        with self._lock:
            entry = self._srvs.get(service)
        if entry is None:
            return [-1, f"no provider for [{service}]", ""]
        return [1, f"rosrpc URI: [{entry[1]}]", entry[1]]

    def _api_lookupNode(self, caller_id: str, node_name: str) -> list[Any]:  # noqa: N802
        with self._lock:
            api = self._nodes.get(node_name)
        if api is None:
            return [-1, f"unknown node [{node_name}]", ""]
        return [1, f"node api for [{node_name}]", api]

    # ------------------------------------------------------------------ state
    def _api_getPid(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "", os.getpid()]

    def _api_getUri(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "", self.uri]

    def _api_getPublishedTopics(self, caller_id: str, subgraph: str = "") -> list[Any]:  # noqa: N802
        with self._lock:
            out = [
                [t, self._types.get(t, "*")]
                for t, pubs in sorted(self._pubs.items())
                if pubs and t.startswith(subgraph or "")
            ]
        return [1, "current topics", out]

    def _api_getTopicTypes(self, caller_id: str) -> list[Any]:  # noqa: N802
        with self._lock:
            return [1, "current system state", [[t, ty] for t, ty in sorted(self._types.items())]]

    def _api_getSystemState(self, caller_id: str) -> list[Any]:  # noqa: N802
        with self._lock:
            pubs = [[t, sorted(n)] for t, n in sorted(self._pubs.items()) if n]
            subs = [[t, sorted(n)] for t, n in sorted(self._subs.items()) if n]
            srvs = [[s, [c]] for s, (c, _) in sorted(self._srvs.items())]
        return [1, "current system state", [pubs, subs, srvs]]

    # ------------------------------------------------------------------ parameters
    def _lookup(self, key: str) -> tuple[bool, Any]:
        node: Any = self._params
        for part in [p for p in key.split("/") if p]:
            if not isinstance(node, dict) or part not in node:
                return False, None
            node = node[part]
        return True, node

    def _api_setParam(self, caller_id: str, key: str, value: Any) -> list[Any]:  # noqa: N802
        key = resolve_param_key(caller_id, key)
        parts = [p for p in key.split("/") if p]
        with self._lock:
            if not parts:
                if not isinstance(value, dict):
                    return [-1, "cannot set the root parameter to a non-dictionary", 0]
                self._params = dict(value)
            else:
                node = self._params
                for part in parts[:-1]:
                    child = node.get(part)
                    if not isinstance(child, dict):
                        child = node[part] = {}
                    node = child
                node[parts[-1]] = value
            for sub_key, subscribers in self._param_subs.items():
                if sub_key == key or sub_key.startswith(key + "/") or key.startswith(sub_key + "/"):
                    found, current = self._lookup(sub_key)
                    for api in subscribers.values():
                        self._notify(api, "paramUpdate", sub_key + "/", current if found else {})
        return [1, f"parameter [{key}] set", 0]

    def _api_getParam(self, caller_id: str, key: str) -> list[Any]:  # noqa: N802
        key = resolve_param_key(caller_id, key)
        with self._lock:
            found, value = self._lookup(key)
        if not found:
            return [-1, f"Parameter [{key}] is not set", 0]
        return [1, f"Parameter [{key}]", value]

    def _api_hasParam(self, caller_id: str, key: str) -> list[Any]:  # noqa: N802
        key = resolve_param_key(caller_id, key)
        with self._lock:
            found, _ = self._lookup(key)
        return [1, key, found]

    def _api_deleteParam(self, caller_id: str, key: str) -> list[Any]:  # noqa: N802
        key = resolve_param_key(caller_id, key)
        parent_key, _, leaf = key.rpartition("/")
        with self._lock:
            found, parent = self._lookup(parent_key)
            if not found or not isinstance(parent, dict) or leaf not in parent:
                return [-1, f"parameter [{key}] is not set", 0]
            del parent[leaf]
        return [1, f"parameter {key} deleted", 0]

    def _api_searchParam(self, caller_id: str, key: str) -> list[Any]:  # noqa: N802
        first = key.strip("/").split("/")[0]
        ns = _namespace(caller_id)
        with self._lock:
            while True:
                candidate = resolve_param_key("/", ns + first)
                if self._lookup(candidate)[0]:
                    rest = key.strip("/")[len(first) :]
                    return [1, "found", candidate + rest]
                if ns == "/":
                    return [-1, f"cannot find [{key}]", ""]
                ns = ns.rstrip("/").rsplit("/", 1)[0] + "/"

    def _api_getParamNames(self, caller_id: str) -> list[Any]:  # noqa: N802
        names: list[str] = []

        def walk(prefix: str, node: Any) -> None:
            for k, v in node.items():
                if isinstance(v, dict) and v:
                    walk(f"{prefix}/{k}", v)
                else:
                    names.append(f"{prefix}/{k}")

        with self._lock:
            walk("", self._params)
        return [1, "Parameter names", sorted(names)]

    def _api_subscribeParam(  # noqa: N802
        self, caller_id: str, caller_api: str, key: str
    ) -> list[Any]:
        key = resolve_param_key(caller_id, key)
        with self._lock:
            self._node(caller_id, caller_api)
            self._param_subs.setdefault(key, {})[caller_id] = caller_api
            found, value = self._lookup(key)
        return [1, f"Subscribed to parameter [{key}]", value if found else {}]

    def _api_unsubscribeParam(  # noqa: N802
        self, caller_id: str, caller_api: str, key: str
    ) -> list[Any]:
        key = resolve_param_key(caller_id, key)
        with self._lock:
            removed = self._param_subs.get(key, {}).pop(caller_id, None)
        return [1, f"Unsubscribed from [{key}]", int(removed is not None)]
