"""What the Foxglove server tracks: advertised channels and services, per-client state."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from visnav.bridge.foxglove.errors import FoxgloveError
from visnav.graph import Publisher, Subscription
from visnav.msgs.srv import ServiceType

__all__ = ["Channel", "ClientPub", "ClientState", "ServiceEntry", "json_object"]


@dataclass
class Channel:
    """An advertised topic: its channel id, type and ``ros2msg`` schema."""

    id: int
    topic: str
    type_name: str
    schema: str

    def to_json(self) -> dict[str, Any]:
        """The channel as the ``advertise`` message lists it."""
        return {
            "id": self.id,
            "topic": self.topic,
            "encoding": "cdr",
            "schemaName": self.type_name,
            "schema": self.schema,
            "schemaEncoding": "ros2msg",
        }


@dataclass
class ServiceEntry:
    """An advertised service: its id, type and request/response schemas."""

    id: int
    name: str
    srv: ServiceType
    request_schema: str
    response_schema: str

    def to_json(self) -> dict[str, Any]:
        """The service as ``advertiseServices`` lists it (with the older schema fields too)."""

        def part(type_name: str, schema: str) -> dict[str, str]:
            return {
                "encoding": "cdr",
                "schemaName": type_name,
                "schemaEncoding": "ros2msg",
                "schema": schema,
            }

        return {
            "id": self.id,
            "name": self.name,
            "type": self.srv.name,
            "request": part(self.srv.request_type_name, self.request_schema),
            "response": part(self.srv.response_type_name, self.response_schema),
            "requestSchema": self.request_schema,
            "responseSchema": self.response_schema,
        }


@dataclass
class ClientPub:
    """A client channel (``clientPublish``) and its graph publisher once made."""

    topic: str
    type_name: str
    encoding: str
    publisher: Publisher[Any] | None = None


@dataclass
class ClientState:
    """One client's subscriptions, client channels, watched parameters and graph subscription."""

    subs: dict[int, int] = field(default_factory=dict)  # subscription id -> channel id
    graph_subs: dict[int, Subscription[Any]] = field(default_factory=dict)
    pubs: dict[int, ClientPub] = field(default_factory=dict)
    param_names: set[str] = field(default_factory=set)
    graph_subscribed: bool = False  # connectionGraph updates wanted
    gone: bool = False


def json_object(data: bytes, where: str) -> dict[str, Any]:
    """Message data in the ``json`` encoding as an object.

    Raises:
        FoxgloveError: not JSON, or not an object.
    """
    try:
        value = json.loads(data)
    except (ValueError, RecursionError) as exc:
        msg = f"JSON message data for {where!r} is not JSON ({exc})"
        raise FoxgloveError(msg) from exc
    if not isinstance(value, dict):
        msg = f"JSON message data for {where!r} is {type(value).__name__}: expected an object"
        raise FoxgloveError(msg)
    return value
