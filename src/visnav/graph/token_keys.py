"""Liveliness token keys of entities whose names are already valid (the fast path of nodes).

:func:`trusted_token` builds the same key as :func:`visnav.graph.keys.liveliness_token`
without re-validating the names a :class:`~visnav.graph.Node` has resolved and checked:
creating many entities (e.g. the six parameter services of every node) spent most of its
time validating and then parsing its own tokens.
"""

from __future__ import annotations

import functools

from visnav.graph.keys import (
    ADMIN_SPACE,
    EntityKind,
    KeyExpressionError,
    LivelinessToken,
    TokenQoS,
    dds_type_to_ros,
    keyexpr_to_qos,
    qos_to_keyexpr,
    ros_type_to_dds,
)
from visnav.graph.names import mangle_name

__all__ = ["trusted_token"]


@functools.lru_cache(maxsize=4096)
def _endpoint_tail(type_name: str, type_hash: str, qos: object) -> tuple[str, str, TokenQoS]:
    """``<dds type>/<hash>/<qos>`` chunks, the ROS type name and the QoS fields (cached)."""
    qos_chunk = qos_to_keyexpr(qos)  # checks the policies
    q: TokenQoS = keyexpr_to_qos(qos_chunk)
    dds = ros_type_to_dds(type_name)
    LivelinessToken(  # checks the hash (and the rest) once per combination
        0,
        "0",
        0,
        1,
        EntityKind.PUBLISHER,
        "/",
        "n",
        topic="/t",
        type_name=dds,
        type_hash=type_hash,
        reliability=q.reliability,
        durability=q.durability,
        history=q.history,
        depth=q.depth,
    )
    return f"{dds}/{type_hash}/{qos_chunk}", dds_type_to_ros(dds), q


def trusted_token(
    domain: int,
    zid: str,
    node_id: int,
    entity_id: int,
    kind: EntityKind,
    namespace: str,
    node_name: str,
    topic: str | None = None,
    type_name: str | None = None,
    type_hash: str | None = None,
    qos: object = None,
) -> tuple[str, LivelinessToken]:
    """The key and parts of a token whose names are already valid (fast path for nodes).

    The same key as :func:`liveliness_token` (default enclave), built without
    re-validating names that :class:`~visnav.graph.Node` has resolved and checked
    (creating many entities, e.g. the six parameter services of every node, spent most
    of its time validating and parsing its own tokens). Type name, hash and QoS are
    still checked, once per distinct combination.

    Raises:
        KeyExpressionError: an invalid type name, hash or QoS.
    """
    head = (
        f"{ADMIN_SPACE}/{domain}/{zid}/{node_id}/{entity_id}/{kind.value}/%/"
        f"{mangle_name(namespace)}/{node_name}"
    )
    token = object.__new__(LivelinessToken)
    parts: dict[str, object] = {
        "domain": domain,
        "zid": zid,
        "node_id": node_id,
        "entity_id": entity_id,
        "kind": kind,
        "namespace": namespace,
        "node_name": node_name,
        "enclave": "/",
        "topic": None,
        "type_name": None,
        "type_hash": None,
        "reliability": None,
        "durability": None,
        "history": None,
        "depth": None,
        "extra": (),
    }
    key = head
    if kind is not EntityKind.NODE:
        if topic is None or type_name is None or type_hash is None or qos is None:
            msg = f"a {kind.name.lower()} token needs topic, type_name, type_hash and qos"
            raise KeyExpressionError(msg)
        tail, ros_type, q = _endpoint_tail(type_name, type_hash, qos)
        key = f"{head}/{mangle_name(topic)}/{tail}"
        parts.update(
            topic=topic,
            type_name=ros_type,
            type_hash=type_hash,
            reliability=q.reliability,
            durability=q.durability,
            history=q.history,
            depth=q.depth,
        )
    for name, value in parts.items():
        object.__setattr__(token, name, value)
    return key, token
