"""Zenoh key expressions laid out as rmw_zenoh lays them out (data keys and liveliness tokens).

Using rmw_zenoh's layout lets visnav processes and ROS 2 nodes running
``rmw_zenoh_cpp`` see each other's topics and graph through one Zenoh router.

Data keys
---------
A topic's samples (and a service's queries) travel on::

    <domain_id>/<fully qualified name without the leading '/'>/<DDS type name>/<type hash>

e.g. ``0/robot1/chatter/std_msgs::msg::dds_::String_/RIHS01_df66…1a18``. The
domain keeps ROS domains apart; type name and hash keep endpoints of
different types apart. A ROS type ``pkg/msg/Name`` is written
``pkg::msg::dds_::Name_`` (its DDS/CDR name). The hash is REP-2016's
``RIHS01_<64 hex>``; ROS 2 Humble, which has no type hashes, writes
``TypeHashNotSupported``.

Liveliness tokens
-----------------
Every node, publisher, subscription, service server and client declares a
liveliness token while it exists; the graph (``ros2 node list``, topic info) is
the set of live tokens. A node's token is::

    @ros2_lv/<domain_id>/<zid>/<node_id>/<node_id>/NN/<enclave>/<namespace>/<node_name>

and an endpoint's appends its topic::

    @ros2_lv/<domain_id>/<zid>/<node_id>/<entity_id>/<kind>/<enclave>/<namespace>/<node_name>
        /<topic>/<DDS type name>/<type hash>/<qos>

* ``@ros2_lv`` is a hermetic admin-space prefix (``*``/``**`` never match it).
* ``<zid>`` is the Zenoh session id (hex); ``<node_id>`` numbers the node in
  its context, ``<entity_id>`` the entity in the node.
* ``<kind>``: ``NN`` node, ``MP`` publisher, ``MS`` subscription, ``SS``
  service server, ``SC`` service client.
* ``<enclave>``, ``<namespace>`` and ``<topic>`` are *mangled*: every ``/``
  becomes ``%`` so that each is one key chunk (``/`` -> ``%``,
  ``/robot1`` -> ``%robot1``, ``/a/b`` -> ``%a%b``). The default enclave is
  ``/``.
* ``<qos>`` is ``<reliability>:<durability>:<history>,<depth>:<deadline>:<lifespan>:<liveliness>``
  where deadline and lifespan are ``<s>,<ns>`` and liveliness is ``<kind>,<lease s>,<lease ns>``,
  with rmw's numeric policy codes (reliability 1 reliable, 2 best effort;
  durability 1 transient local, 2 volatile; history 1 keep last, 2 keep all),
  and every field equal to rmw_zenoh's default left empty. The defaults are
  reliable, volatile, keep last, depth 42, infinite deadline/lifespan/lease,
  automatic liveliness, so a reliable, volatile depth-10 publisher writes
  ``::,10:,:,:,,``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from enum import Enum
from typing import NamedTuple

from visnav.graph.errors import GraphError
from visnav.graph.names import (
    InvalidNameError,
    demangle_name,
    mangle_name,
    validate_full_topic_name,
    validate_namespace,
    validate_node_name,
)

__all__ = [
    "ADMIN_SPACE",
    "TYPE_HASH_NOT_SUPPORTED",
    "EntityKind",
    "KeyExpressionError",
    "LivelinessToken",
    "TokenQoS",
    "TopicKey",
    "dds_type_to_ros",
    "keyexpr_to_qos",
    "liveliness_key_pattern",
    "liveliness_token",
    "parse_liveliness_token",
    "parse_topic_key",
    "qos_to_keyexpr",
    "ros_type_to_dds",
    "topic_key",
]

ADMIN_SPACE = "@ros2_lv"
"""First chunk of every liveliness token."""

TYPE_HASH_NOT_SUPPORTED = "TypeHashNotSupported"
"""The type hash rmw_zenoh writes on ROS 2 Humble, which has no type hashes."""

_ROS_TYPE_RE = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)/(msg|srv|action)/([A-Za-z][A-Za-z0-9_]*)")
_DDS_TYPE_RE = re.compile(
    r"([A-Za-z_][A-Za-z0-9_]*)::(msg|srv|action)::dds_::([A-Za-z][A-Za-z0-9_]*)_"
)
_TYPE_HASH_RE = re.compile(
    r"RIHS01_[0-9a-f]{64}|RIHS(?!01)[0-9]{2}_[0-9a-f]+|" + TYPE_HASH_NOT_SUPPORTED
)
_ZID_RE = re.compile(r"[0-9a-f]{1,32}")
_UINT_RE = re.compile(r"[0-9]+")

_RELIABILITY = {"system_default": 0, "reliable": 1, "best_effort": 2, "best_available": 4}
_DURABILITY = {"system_default": 0, "transient_local": 1, "volatile": 2, "best_available": 4}
_HISTORY = {"system_default": 0, "keep_last": 1, "keep_all": 2}
_DEFAULT_DEPTH = 42  # rmw_zenoh's depth for "system default" (depth 0)
_DEFAULT_QOS_CODES = (1, 2, 1, _DEFAULT_DEPTH)  # reliable, volatile, keep_last, 42


class KeyExpressionError(GraphError, ValueError):
    """A key expression or one of its parts is malformed (the text names the part and the fix)."""


class EntityKind(str, Enum):
    """The entity a liveliness token announces (compares equal to its two-letter code)."""

    NODE = "NN"
    PUBLISHER = "MP"
    SUBSCRIPTION = "MS"
    SERVICE_SERVER = "SS"
    SERVICE_CLIENT = "SC"


class TokenQoS(NamedTuple):
    """The QoS fields a liveliness token carries (policy names as lowercase strings)."""

    reliability: str = "reliable"
    durability: str = "volatile"
    depth: int = 10
    history: str = "keep_last"


# --------------------------------------------------------------------------- type names


def ros_type_to_dds(type_name: str) -> str:
    """DDS name of a ROS type: ``std_msgs/msg/String`` -> ``std_msgs::msg::dds_::String_``.

    Args:
        type_name: ``package/msg|srv|action/Name``; a DDS name is returned unchanged
            after checking it.

    Returns:
        The DDS type name used in rmw_zenoh keys.

    Raises:
        KeyExpressionError: the name has neither form.
    """
    if isinstance(type_name, str) and _DDS_TYPE_RE.fullmatch(type_name):
        return type_name
    m = _ROS_TYPE_RE.fullmatch(type_name) if isinstance(type_name, str) else None
    if m is None:
        msg = (
            f"type name {type_name!r} is not 'package/msg/Name' (or srv/action): "
            "write the full ROS 2 name, e.g. 'std_msgs/msg/String'"
        )
        raise KeyExpressionError(msg)
    return f"{m[1]}::{m[2]}::dds_::{m[3]}_"


def dds_type_to_ros(dds_name: str) -> str:
    """ROS name of a DDS type: ``std_msgs::msg::dds_::String_`` -> ``std_msgs/msg/String``.

    Args:
        dds_name: ``package::msg|srv|action::dds_::Name_``.

    Returns:
        The ROS 2 type name.

    Raises:
        KeyExpressionError: the name is not a DDS-mangled ROS type name.
    """
    m = _DDS_TYPE_RE.fullmatch(dds_name) if isinstance(dds_name, str) else None
    if m is None:
        msg = (
            f"DDS type name {dds_name!r} is not 'package::msg::dds_::Name_' (or srv/action), "
            "as rmw_zenoh writes ROS types"
        )
        raise KeyExpressionError(msg)
    return f"{m[1]}/{m[2]}/{m[3]}"


# --------------------------------------------------------------------------- chunks


def _check_domain(domain: object) -> int:
    if isinstance(domain, bool) or not isinstance(domain, int) or domain < 0:
        msg = f"domain id is {domain!r}: expected an int >= 0 (ROS_DOMAIN_ID)"
        raise KeyExpressionError(msg)
    return domain


def _check_uint(what: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        msg = f"{what} is {value!r}: expected an int >= 0"
        raise KeyExpressionError(msg)
    return value


def _check_type_hash(type_hash: object) -> str:
    if not isinstance(type_hash, str) or not _TYPE_HASH_RE.fullmatch(type_hash):
        msg = (
            f"type hash {type_hash!r} is not 'RIHS01_' + 64 lowercase hex digits (REP 2016) "
            f"or {TYPE_HASH_NOT_SUPPORTED!r} (ROS 2 Humble); compute it with the type store"
        )
        raise KeyExpressionError(msg)
    return type_hash


def _name_error(what: str, exc: InvalidNameError) -> KeyExpressionError:
    return KeyExpressionError(f"{what}: {exc}")


def _policy(what: str, table: dict[str, int], value: object) -> str:
    """Normalise a policy given as str, Enum (value or name) or rmw code to its lowercase name."""
    candidates: list[object] = [value]
    if isinstance(value, Enum):
        candidates = [value.value, value.name]
    for cand in candidates:
        if isinstance(cand, str) and cand.lower() in table:
            return cand.lower()
        if isinstance(cand, int) and not isinstance(cand, bool):
            for name, code in table.items():
                if code == cand:
                    return name
    msg = f"{what} is {value!r}: expected one of {', '.join(table)}"
    raise KeyExpressionError(msg)


def _as_token_qos(qos: object) -> TokenQoS:
    """Accept a TokenQoS, a (reliability, durability, depth[, history]) tuple or a QoS object."""
    if isinstance(qos, tuple) and len(qos) in (3, 4):
        fields = qos
    elif all(hasattr(qos, a) for a in ("reliability", "durability", "depth")):
        fields = (qos.reliability, qos.durability, qos.depth, getattr(qos, "history", "keep_last"))  # type: ignore[attr-defined]
    else:
        msg = f"qos is {qos!r}: expected (reliability, durability, depth) or a QoS profile"
        raise KeyExpressionError(msg)
    reliability = _policy("reliability", _RELIABILITY, fields[0])
    durability = _policy("durability", _DURABILITY, fields[1])
    depth = _check_uint("qos depth", fields[2])
    history = _policy("history", _HISTORY, fields[3] if len(fields) == 4 else "keep_last")
    return TokenQoS(reliability, durability, depth, history)


def qos_to_keyexpr(qos: TokenQoS | tuple[object, ...] | object) -> str:
    """Encode QoS as the ``<qos>`` chunk of a liveliness token, as rmw_zenoh does.

    Like rmw_zenoh (which resolves "system default" before announcing), system
    default policies become reliable / volatile / keep last and depth 0 becomes
    42; fields equal to those defaults are left empty. Deadline, lifespan and
    liveliness are not modelled and written as defaults (empty).

    Args:
        qos: a :class:`TokenQoS`, a ``(reliability, durability, depth[, history])``
            tuple, or an object with those attributes. Policies are strings
            (``"reliable"``, ``"best_effort"``, ``"transient_local"``,
            ``"volatile"``, ``"keep_last"``, ``"keep_all"``, ...), enums whose
            value or name is such a string, or rmw's integer codes.

    Returns:
        e.g. ``"::,10:,:,:,,"`` for reliable, volatile, keep last 10.

    Raises:
        KeyExpressionError: a policy or the depth is invalid.
    """
    q = _as_token_qos(qos)
    codes = (
        _RELIABILITY[q.reliability] or _DEFAULT_QOS_CODES[0],
        _DURABILITY[q.durability] or _DEFAULT_QOS_CODES[1],
        _HISTORY[q.history] or _DEFAULT_QOS_CODES[2],
        q.depth or _DEFAULT_DEPTH,
    )
    rel, dur, hist, depth = (
        "" if code == default else str(code)
        for code, default in zip(codes, _DEFAULT_QOS_CODES, strict=True)
    )
    return f"{rel}:{dur}:{hist},{depth}:,:,:,,"


def keyexpr_to_qos(text: str) -> TokenQoS:
    """Decode the ``<qos>`` chunk of a liveliness token (inverse of :func:`qos_to_keyexpr`).

    Empty fields take rmw_zenoh's defaults (reliable, volatile, keep last, 42).
    Deadline, lifespan and liveliness fields are checked but not returned.

    Args:
        text: e.g. ``"::,10:,:,:,,"`` or ``"1:2:1,10:,:,:,,"``.

    Returns:
        The QoS fields.

    Raises:
        KeyExpressionError: the text does not have rmw_zenoh's QoS layout.
    """
    parts = text.split(":") if isinstance(text, str) else []
    groups = [p.split(",") for p in parts]
    if len(parts) != 6 or [len(g) for g in groups] != [1, 1, 2, 2, 2, 3]:
        msg = (
            f"QoS chunk {text!r} is not rmw_zenoh's "
            "'rel:dur:hist,depth:dl_s,dl_ns:ls_s,ls_ns:liv,lease_s,lease_ns' (e.g. '::,10:,:,:,,')"
        )
        raise KeyExpressionError(msg)
    numbers = [v for g in groups for v in g]
    for v in numbers:
        if v and not _UINT_RE.fullmatch(v):
            msg = f"QoS chunk {text!r}: field {v!r} is not a non-negative integer"
            raise KeyExpressionError(msg)
    rel, dur, hist, depth = (
        int(v) if v else d for v, d in zip(numbers[:4], _DEFAULT_QOS_CODES, strict=True)
    )
    return TokenQoS(
        reliability=_policy("QoS reliability code", _RELIABILITY, rel),
        durability=_policy("QoS durability code", _DURABILITY, dur),
        depth=depth,
        history=_policy("QoS history code", _HISTORY, hist),
    )


# --------------------------------------------------------------------------- data keys


@dataclass(frozen=True)
class TopicKey:
    """The parts of a topic's data key.

    Attributes:
        domain: the ROS domain id.
        topic: the fully qualified topic name (with its leading ``/``).
        type_name: the ROS type name, e.g. ``std_msgs/msg/String``.
        type_hash: the type hash (``RIHS01_...`` or ``TypeHashNotSupported``).
    """

    domain: int
    topic: str
    type_name: str
    type_hash: str

    def to_key(self) -> str:
        """Return the key expression (see :func:`topic_key`)."""
        return topic_key(self.domain, self.topic, self.type_name, self.type_hash)


def topic_key(domain: int, topic: str, type_name: str, type_hash: str) -> str:
    """Return the data key expression of a topic or service, as rmw_zenoh builds it.

    Args:
        domain: the ROS domain id (``ROS_DOMAIN_ID``).
        topic: the fully qualified topic name, e.g. ``/robot1/chatter``.
        type_name: the ROS type (``std_msgs/msg/String``) or its DDS name.
        type_hash: ``RIHS01_<64 hex>``, or ``TypeHashNotSupported`` as on Humble.

    Returns:
        e.g. ``0/robot1/chatter/std_msgs::msg::dds_::String_/RIHS01_...``.

    Raises:
        KeyExpressionError: a part is invalid (the message says which).
    """
    _check_domain(domain)
    try:
        validate_full_topic_name(topic)
    except InvalidNameError as exc:
        raise _name_error("topic of a data key", exc) from exc
    return f"{domain}/{topic[1:]}/{ros_type_to_dds(type_name)}/{_check_type_hash(type_hash)}"


def parse_topic_key(key: str) -> TopicKey:
    """Split a data key expression into its parts (inverse of :func:`topic_key`).

    Args:
        key: e.g. ``0/robot1/chatter/std_msgs::msg::dds_::String_/RIHS01_...``.

    Returns:
        The parts, with the topic's leading ``/`` restored and the ROS type name.

    Raises:
        KeyExpressionError: the key does not have the data-key layout.
    """
    chunks = key.split("/") if isinstance(key, str) else []
    if len(chunks) < 4 or not _UINT_RE.fullmatch(chunks[0]):
        msg = f"data key {key!r} is not '<domain>/<topic>/<DDS type>/<type hash>'"
        raise KeyExpressionError(msg)
    topic = "/" + "/".join(chunks[1:-2])
    try:
        validate_full_topic_name(topic)
    except InvalidNameError as exc:
        raise _name_error(f"data key {key!r}", exc) from exc
    return TopicKey(
        int(chunks[0]), topic, dds_type_to_ros(chunks[-2]), _check_type_hash(chunks[-1])
    )


# --------------------------------------------------------------------------- liveliness


def liveliness_key_pattern(domain: int) -> str:
    """Key expression matching every liveliness token of a domain: ``@ros2_lv/<domain>/**``."""
    return f"{ADMIN_SPACE}/{_check_domain(domain)}/**"


@dataclass(frozen=True)
class LivelinessToken:
    """The parts of a liveliness token; fields are validated on construction.

    Attributes:
        domain: the ROS domain id.
        zid: the Zenoh session id, lowercase hex.
        node_id: the node's id within its context.
        entity_id: the entity's id (equal to ``node_id`` for a node).
        kind: what the token announces.
        namespace: the node's namespace (demangled, e.g. ``/robot1``).
        node_name: the node's name.
        enclave: the SROS enclave (``/`` when unused).
        topic: the fully qualified topic or service name (``None`` for nodes).
        type_name: the ROS type name, e.g. ``std_msgs/msg/String`` (``None`` for nodes).
        type_hash: the type hash (``None`` for nodes).
        reliability: ``reliable``, ``best_effort`` or ``best_available`` (``None`` for nodes).
        durability: ``volatile``, ``transient_local`` or ``best_available`` (``None`` for nodes).
        history: ``keep_last`` or ``keep_all`` (``None`` for nodes).
        depth: the history depth (``None`` for nodes).
        extra: key chunks after the QoS chunk that newer rmw_zenoh versions may
            append; kept so that :meth:`to_key` reproduces the key.
    """

    domain: int
    zid: str
    node_id: int
    entity_id: int
    kind: EntityKind
    namespace: str
    node_name: str
    enclave: str = "/"
    topic: str | None = None
    type_name: str | None = None
    type_hash: str | None = None
    reliability: str | None = None
    durability: str | None = None
    history: str | None = None
    depth: int | None = None
    extra: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        _check_domain(self.domain)
        if not isinstance(self.zid, str) or not _ZID_RE.fullmatch(self.zid):
            msg = f"zenoh session id {self.zid!r} is not 1-32 lowercase hex digits (session.zid())"
            raise KeyExpressionError(msg)
        _check_uint("node id", self.node_id)
        _check_uint("entity id", self.entity_id)
        try:
            object.__setattr__(self, "kind", EntityKind(self.kind))
        except ValueError:
            kinds = ", ".join(k.value for k in EntityKind)
            msg = f"entity kind {self.kind!r} is not one of {kinds}"
            raise KeyExpressionError(msg) from None
        for what, check, value in (
            ("namespace", validate_namespace, self.namespace),
            ("node name", validate_node_name, self.node_name),
            ("enclave", validate_namespace, self.enclave),
        ):
            try:
                check(value)
            except InvalidNameError as exc:
                raise _name_error(f"liveliness token {what}", exc) from exc
        self._check_endpoint_fields()
        if any(not isinstance(c, str) or not c or "/" in c for c in self.extra):
            msg = f"extra chunks {self.extra!r} must be non-empty strings without '/'"
            raise KeyExpressionError(msg)

    def _check_endpoint_fields(self) -> None:
        endpoint = (self.topic, self.type_name, self.type_hash, self.reliability)
        qos_tail = (self.durability, self.history, self.depth)
        if self.kind is EntityKind.NODE:
            if self.entity_id != self.node_id:
                msg = (
                    f"a node's token uses its node id as entity id: "
                    f"got entity id {self.entity_id}, node id {self.node_id}"
                )
                raise KeyExpressionError(msg)
            if any(v is not None for v in (*endpoint, *qos_tail)) or self.extra:
                msg = "a node's liveliness token has no topic, type, hash or QoS: pass them as None"
                raise KeyExpressionError(msg)
            return
        missing = [
            n
            for n, v in zip(("topic", "type_name", "type_hash", "qos"), endpoint, strict=True)
            if v is None
        ]
        if missing or any(v is None for v in qos_tail):
            msg = (
                f"a {self.kind.name.lower()} token needs topic, type_name, type_hash and qos; "
                f"missing {missing or ['qos']}"
            )
            raise KeyExpressionError(msg)
        try:
            validate_full_topic_name(self.topic)  # type: ignore[arg-type]
        except InvalidNameError as exc:
            raise _name_error("liveliness token topic", exc) from exc
        object.__setattr__(self, "type_name", dds_type_to_ros(ros_type_to_dds(self.type_name)))  # type: ignore[arg-type]
        _check_type_hash(self.type_hash)
        q = _as_token_qos((self.reliability, self.durability, self.depth, self.history))
        object.__setattr__(self, "reliability", q.reliability)
        object.__setattr__(self, "durability", q.durability)
        object.__setattr__(self, "history", q.history)

    @property
    def qos(self) -> TokenQoS | None:
        """The QoS fields as a :class:`TokenQoS` (``None`` for nodes)."""
        if self.kind is EntityKind.NODE:
            return None
        return TokenQoS(self.reliability, self.durability, self.depth, self.history)  # type: ignore[arg-type]

    @property
    def node_fully_qualified_name(self) -> str:
        """``/namespace/node_name``."""
        return f"{self.namespace.rstrip('/')}/{self.node_name}"

    def to_key(self) -> str:
        """Return the key expression (see the module docstring for the layout)."""
        chunks = [
            ADMIN_SPACE,
            str(self.domain),
            self.zid,
            str(self.node_id),
            str(self.entity_id),
            self.kind.value,
            mangle_name(self.enclave),
            mangle_name(self.namespace),
            mangle_name(self.node_name),
        ]
        qos = self.qos
        if qos is not None:
            chunks += [
                mangle_name(self.topic),  # type: ignore[arg-type]
                ros_type_to_dds(self.type_name),  # type: ignore[arg-type]
                self.type_hash,  # type: ignore[list-item]
                qos_to_keyexpr(qos),
                *self.extra,
            ]
        return "/".join(chunks)


def liveliness_token(
    domain: int,
    zid: str,
    node_id: int,
    entity_id: int,
    kind: EntityKind | str,
    namespace: str,
    node_name: str,
    topic: str | None = None,
    type_name: str | None = None,
    type_hash: str | None = None,
    qos: TokenQoS | tuple[object, ...] | object | None = None,
    *,
    enclave: str = "/",
) -> str:
    """Return the liveliness token key of a node or endpoint, as rmw_zenoh builds it.

    Args:
        domain: the ROS domain id.
        zid: the Zenoh session id (``str(session.zid())``).
        node_id: the node's id within its context.
        entity_id: the entity's id; a node uses its ``node_id``.
        kind: ``NN``, ``MP``, ``MS``, ``SS`` or ``SC`` (or an :class:`EntityKind`).
        namespace: the node's absolute namespace.
        node_name: the node's name.
        topic: the fully qualified topic or service name (endpoints only).
        type_name: the ROS type name (or its DDS name; endpoints only).
        type_hash: ``RIHS01_...`` or ``TypeHashNotSupported`` (endpoints only).
        qos: ``(reliability, durability, depth[, history])``, a :class:`TokenQoS`
            or a QoS profile object (endpoints only; see :func:`qos_to_keyexpr`).
        enclave: the SROS enclave, ``/`` when unused.

    Returns:
        The key, e.g. for a publisher
        ``@ros2_lv/0/<zid>/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/<hash>/::,7:,:,:,,``.

    Raises:
        KeyExpressionError: a part is invalid, a node token got endpoint fields,
            or an endpoint token lacks them.
    """
    q = None if qos is None else _as_token_qos(qos)
    return LivelinessToken(
        domain=domain,
        zid=zid,
        node_id=node_id,
        entity_id=entity_id,
        kind=kind,  # type: ignore[arg-type]  # coerced and checked in __post_init__
        namespace=namespace,
        node_name=node_name,
        enclave=enclave,
        topic=topic,
        type_name=type_name,
        type_hash=type_hash,
        reliability=None if q is None else q.reliability,
        durability=None if q is None else q.durability,
        history=None if q is None else q.history,
        depth=None if q is None else q.depth,
    ).to_key()


def parse_liveliness_token(key: str) -> LivelinessToken:
    """Split a liveliness token key into its parts (inverse of :func:`liveliness_token`).

    Args:
        key: a key received on :func:`liveliness_key_pattern`.

    Returns:
        The parts, names demangled and the type as a ROS type name.

    Raises:
        KeyExpressionError: the key is not an rmw_zenoh liveliness token.
    """
    chunks = key.split("/") if isinstance(key, str) else []
    if len(chunks) < 9 or chunks[0] != ADMIN_SPACE or not all(chunks):
        msg = (
            f"liveliness token {key!r} is not '{ADMIN_SPACE}/<domain>/<zid>/<node id>/<entity id>/"
            "<kind>/<enclave>/<namespace>/<node name>[/<topic>/<type>/<hash>/<qos>]' "
            "(at least 9 non-empty chunks)"
        )
        raise KeyExpressionError(msg)
    for i, what in ((1, "domain"), (3, "node id"), (4, "entity id")):
        if not _UINT_RE.fullmatch(chunks[i]):
            msg = f"liveliness token {key!r}: {what} {chunks[i]!r} is not a non-negative integer"
            raise KeyExpressionError(msg)
    common = {
        "domain": int(chunks[1]),
        "zid": chunks[2],
        "node_id": int(chunks[3]),
        "entity_id": int(chunks[4]),
        "kind": chunks[5],
        "enclave": demangle_name(chunks[6]),
        "namespace": demangle_name(chunks[7]),
        "node_name": demangle_name(chunks[8]),
    }
    if chunks[5] == EntityKind.NODE.value:
        if len(chunks) != 9:
            msg = f"liveliness token {key!r}: a node token has 9 chunks, got {len(chunks)}"
            raise KeyExpressionError(msg)
        return LivelinessToken(**common)  # type: ignore[arg-type]
    if len(chunks) < 13:
        msg = (
            f"liveliness token {key!r}: an endpoint token has 13 chunks "
            f"(topic, type, hash, qos after the node name), got {len(chunks)}"
        )
        raise KeyExpressionError(msg)
    qos = keyexpr_to_qos(chunks[12])
    return LivelinessToken(
        **common,  # type: ignore[arg-type]
        topic=demangle_name(chunks[9]),
        type_name=dds_type_to_ros(chunks[10]),
        type_hash=chunks[11],
        reliability=qos.reliability,
        durability=qos.durability,
        history=qos.history,
        depth=qos.depth,
        extra=tuple(chunks[13:]),
    )
