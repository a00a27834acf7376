"""Which service of a context answers a Zenoh query from another process.

A context's services declare their queryables with the context's inbox as callback
(see :meth:`~visnav.graph.Context.route_queries`): Zenoh's thread only queues each
query, and the executor asks :class:`QueryRoutes` which service it is for, by the
query's key expression.
"""

from __future__ import annotations

import contextlib
from collections import deque
from typing import TYPE_CHECKING, Any

import zenoh

if TYPE_CHECKING:
    from visnav.graph.service import Service

__all__ = ["QueryRoutes"]


class QueryRoutes:
    """Service keys of one context and the services behind them (callers hold its lock)."""

    def __init__(self) -> None:
        self._routes: dict[str, Service[Any, Any]] = {}
        self._wild: dict[str, deque[Service[Any, Any]]] = {}

    def add(self, key: str, service: Service[Any, Any]) -> None:
        """Send queries on ``key`` to ``service``."""
        self._routes[key] = service
        self._wild.clear()

    def remove(self, key: str) -> None:
        """Stop routing queries on ``key``."""
        self._routes.pop(key, None)
        self._wild.clear()

    def find(self, query: Any) -> Service[Any, Any] | None:
        """The service for ``query``; None after answering one no service takes with an error."""
        try:
            key = str(query.key_expr)
        except Exception:  # noqa: BLE001 - a query already dropped: nothing to answer
            return None
        service = self._routes.get(key)
        if service is None:
            service = self._wildcard(key)
        if service is None:
            with contextlib.suppress(Exception):  # the caller went away
                query.reply_err(f"no service of this process answers {key}".encode())
            query.drop()
        return service

    def _wildcard(self, key: str) -> Service[Any, Any] | None:
        """The service for a query whose key is not a service's own (a wildcard).

        Each service whose key the query's intersects received its own copy of the
        query (all alike in the inbox): the copies go to those services in turn.
        """
        pending = self._wild.get(key)
        if not pending:
            try:
                expr = zenoh.KeyExpr(key)
                matches = [s for k, s in self._routes.items() if expr.intersects(zenoh.KeyExpr(k))]
            except Exception:  # noqa: BLE001 - not a valid key expression
                return None
            if not matches:
                return None
            pending = self._wild[key] = deque(matches)
        service = pending.popleft()
        if not pending:
            del self._wild[key]
        return service
