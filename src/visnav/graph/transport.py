"""The inter-process transport: a Zenoh session per :class:`~visnav.graph.Context`.

How processes find each other with no configuration on one machine:

* Every session listens on an ephemeral loopback port and, if it is free, on the
  domain's *rendezvous port* ``20000 + crc32(str(domain)) % 10000`` on 127.0.0.1.
* Every session also connects to the rendezvous port (retrying in the
  background), so the first process of a domain becomes the meeting point and
  Zenoh's gossip scouting then meshes all peers directly. When the meeting point
  exits, the next process to start takes the port over and the others reconnect.
* Multicast scouting is off: nothing leaves the machine unless
  ``VISNAV_CONNECT=tcp/HOST:PORT[,..]`` (connect to another machine) or
  ``VISNAV_LISTEN=tcp/0.0.0.0:PORT`` (accept other machines) is set.

Domains are separated twice: by the rendezvous port and, since two domains may
share a port, by the domain as the first chunk of every key expression.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import re
import threading
import zlib
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

import zenoh
from zenoh import shm as zshm

from visnav.graph.errors import TransportError
from visnav.graph.transport_pace import (
    PaceRefresher,
    PaceReporter,
    PaceTracker,
    RemoteSubscriptions,
)

__all__ = [
    "ENV_CONNECT",
    "SHM_POOL_BYTES",
    "SHM_THRESHOLD",
    "ENV_DOMAIN",
    "ENV_LISTEN",
    "LATCHED_CHUNK",
    "TransportConfig",
    "detach_small",
    "ZenohPublisher",
    "ZenohTransport",
    "rendezvous_port",
    "latched_key",
    "resolve_domain",
]

SHM_THRESHOLD = 64 * 1024
"""Payloads this large or larger use shared memory."""
SHM_POOL_BYTES = 64 * 1024 * 1024
"""Size of each session's shared-memory pool."""
ENV_DOMAIN = "VISNAV_DOMAIN"
ENV_CONNECT = "VISNAV_CONNECT"
ENV_LISTEN = "VISNAV_LISTEN"
DEFAULT_DOMAIN = 0
_MAX_DOMAIN = 2**31 - 1
_ENDPOINT_RE = re.compile(r"^(tcp|udp|quic|tls|unixsock-stream)/.+$")


def resolve_domain(domain: str | int | None, env: Mapping[str, str] | None = None) -> int:
    """Return the graph domain id: the argument, else ``VISNAV_DOMAIN``, else 0.

    The domain is an integer like ``ROS_DOMAIN_ID`` (any value >= 0; tests pick
    large random ones to stay private).

    Raises:
        TransportError: the domain is not a non-negative integer.
    """
    env = os.environ if env is None else env
    value = domain if domain is not None else env.get(ENV_DOMAIN, str(DEFAULT_DOMAIN))
    try:
        number = int(value)
    except (TypeError, ValueError):
        number = -1
    if isinstance(value, bool) or number < 0 or number > _MAX_DOMAIN:
        msg = (
            f"{ENV_DOMAIN} / domain is {value!r}: expected an integer from 0 to {_MAX_DOMAIN} "
            "(for example VISNAV_DOMAIN=42)"
        )
        raise TransportError(msg)
    return number


def rendezvous_port(domain: int) -> int:
    """Return the loopback port where the processes of ``domain`` meet."""
    return 20000 + zlib.crc32(str(domain).encode()) % 10000


_PORTED = ("tcp", "udp", "quic", "tls")


def _check_endpoint(ep: str, var: str) -> None:
    """Refuse a locator Zenoh would accept silently but never listen on or connect to."""
    example = "tcp/0.0.0.0:7447" if var == ENV_LISTEN else "tcp/192.168.1.5:7447"
    proto, _, address = ep.partition("/")
    address = re.split(r"[?#]", address, maxsplit=1)[0]  # Zenoh locator metadata/config
    if not _ENDPOINT_RE.match(ep) or not address:
        problem = "expected a Zenoh locator PROTOCOL/ADDRESS"
    elif proto not in _PORTED:
        return
    else:
        host, sep, port = address.rpartition(":")
        lowest = 0 if var == ENV_LISTEN else 1
        if not sep or address.endswith("]"):
            problem = "it has no port: expected HOST:PORT after the protocol"
        elif not host or host == "[]":
            problem = "it has no host: expected HOST:PORT after the protocol"
        elif not port.isdigit() or not lowest <= int(port) <= 65535:
            problem = f"port {port!r} is not a number from {lowest} to 65535"
        else:
            return
    msg = f"{var}={ep!r}: {problem} (for example {var}={example})"
    raise TransportError(msg)


def _endpoints(value: str, var: str) -> tuple[str, ...]:
    eps = tuple(e.strip() for e in value.split(",") if e.strip())
    for ep in eps:
        _check_endpoint(ep, var)
    return eps


@dataclasses.dataclass(frozen=True)
class TransportConfig:
    """Where a session listens and connects.

    Attributes:
        domain: the graph domain (first chunk of every key).
        connect: extra endpoints to connect to (other machines).
        listen: extra endpoints to listen on.
    """

    domain: int = DEFAULT_DOMAIN
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()

    @classmethod
    def from_env(
        cls, domain: str | int | None = None, env: Mapping[str, str] | None = None
    ) -> TransportConfig:
        """Build the configuration from arguments and ``VISNAV_*`` environment variables."""
        env = os.environ if env is None else env
        return cls(
            domain=resolve_domain(domain, env),
            connect=_endpoints(env.get(ENV_CONNECT, ""), ENV_CONNECT),
            listen=_endpoints(env.get(ENV_LISTEN, ""), ENV_LISTEN),
        )

    def zenoh_config(self) -> dict[str, Any]:
        """Return the Zenoh configuration (as a JSON-able dict)."""
        meet = f"tcp/127.0.0.1:{rendezvous_port(self.domain)}"
        return {
            "mode": "peer",
            "listen": {
                "endpoints": [meet, "tcp/127.0.0.1:0", *self.listen],
                "exit_on_failure": False,
            },
            "connect": {
                "endpoints": [meet, *self.connect],
                "exit_on_failure": False,
                "timeout_ms": 0,
                "retry": {
                    "period_init_ms": 200,
                    "period_max_ms": 1000,
                    "period_increase_factor": 2,
                },
            },
            "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": True}},
            # large payloads go through shared memory between processes of one machine
            "transport": {"shared_memory": {"enabled": True}},
        }


LATCHED_CHUNK = "_latched"
"""Key chunk under a topic key where transient-local publishers answer for their cache."""


def latched_key(key: str, zid: str, publisher_id: int) -> str:
    """Key of one transient-local publisher's cache queryable."""
    return f"{key}/{LATCHED_CHUNK}/{zid}/{publisher_id}"


class ZenohPublisher:
    """A Zenoh publisher that knows whether any remote subscriber matches.

    Transient-local publishers keep their last ``cache_depth`` samples and answer
    queries for them on :func:`latched_key` (late-joining subscribers fetch them).
    visnav does this itself rather than with zenoh-ext's advanced publisher, whose
    history queries keep one sample per key expression: with two latched publishers
    of one topic (two static TF broadcasters) a late joiner got only one of them.

    Volatile publishers that may drop (not ``block``) given ``remote_subscriptions``
    skip samples while every remote subscription is a paused paced one
    (:meth:`wants_sample`, see :mod:`visnav.graph.transport_pace`).
    """

    def __init__(
        self,
        session: zenoh.Session,
        key: str,
        *,
        cache_depth: int | None,
        block: bool = False,
        shm: Any = None,
        publisher_id: int = 0,
        remote_subscriptions: RemoteSubscriptions | None = None,
    ) -> None:
        self._shm = shm
        # As rmw_zenoh: block only for keep-all reliable topics, else drop under congestion
        # (blocking puts of fresh buffers also cost ~8x throughput, measured in bench_graph).
        cc = zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP
        self._pub: Any = session.declare_publisher(
            key, allowed_destination=zenoh.Locality.REMOTE, congestion_control=cc
        )
        status: Any = self._pub.matching_status
        self._matching = bool(getattr(status, "matching", status))
        self._listener: Any = self._pub.declare_matching_listener(self._on_matching)
        self._cache: deque[tuple[bytes, bytes | None]] | None = None
        self._queryable: Any = None
        self._cache_lock = threading.Lock()
        if cache_depth is not None:
            self._cache = deque(maxlen=cache_depth)
            self._qkey = latched_key(key, str(session.zid()), publisher_id)
            self._queryable = session.declare_queryable(
                self._qkey, self._on_query, allowed_origin=zenoh.Locality.REMOTE
            )
        self._pace: PaceTracker | None = None
        if cache_depth is None and not block and remote_subscriptions is not None:
            self._pace = PaceTracker(session, key, remote_subscriptions)

    def _on_matching(self, status: Any) -> None:
        self._matching = bool(status.matching)

    def _on_query(self, query: Any) -> None:
        with self._cache_lock:
            samples = list(self._cache or ())
        for payload, attachment in samples:
            query.reply(self._qkey, payload, attachment=attachment)

    @property
    def has_subscribers(self) -> bool:
        """True when a remote subscriber matches (always True for latched publishers)."""
        return self._cache is not None or self._matching

    def wants_sample(self) -> bool:
        """Whether to send the next sample: a remote subscriber matches and one can take it.

        False while every remote subscription is a paced one that is paused (counted in
        :attr:`skipped`); the caller then skips serializing the sample too.
        """
        if self._cache is not None:
            return True
        # The matching listener's callback can come tens of ms after Zenoh's routing (and
        # the graph's liveliness token) know a new subscriber: ask Zenoh (~1 us) before
        # skipping, or a sample published on seeing the subscription is lost.
        if not self._matching:
            status: Any = self._pub.matching_status
            if not getattr(status, "matching", status):
                return False
        pace = self._pace
        return pace is None or not pace.all_paused()

    @property
    def skipped(self) -> int:
        """Samples skipped because every remote subscription was paused."""
        return 0 if self._pace is None else self._pace.skipped

    def put(self, payload: bytes | bytearray, attachment: bytes | None = None) -> None:
        """Send one payload (with an optional attachment).

        Payloads of at least :data:`SHM_THRESHOLD` bytes are copied into a shared-memory
        buffer when a provider is available: peers on this machine then map it instead of
        receiving it through a socket (measured in ``bench/bench_graph.py``).
        """
        if self._cache is not None:
            with self._cache_lock:
                self._cache.append((bytes(payload), attachment))
        if self._shm is not None and len(payload) >= SHM_THRESHOLD:
            # never block: subscribers keep received samples (their shared-memory chunks)
            # queued until their executor takes them, so a full pool means slow readers
            try:
                buf = self._shm.alloc(len(payload), policy=zshm.GarbageCollect())
            except Exception:  # noqa: BLE001 - fall back to the socket path
                buf = None
            if buf is not None:
                buf[:] = payload
                self._pub.put(buf, attachment=attachment)
                return
        self._pub.put(payload, attachment=attachment)

    def close(self) -> None:
        """Undeclare the publisher (and its cache queryable)."""
        if self._pace is not None:
            self._pace.close()
        with contextlib.suppress(Exception):
            self._listener.undeclare()
            self._pub.undeclare()
            if self._queryable is not None:
                self._queryable.undeclare()


def detach_small(payload: zenoh.ZBytes) -> zenoh.ZBytes | bytes:
    """Copy a payload below :data:`SHM_THRESHOLD` bytes out of Zenoh's receive buffers."""
    return payload.to_bytes() if len(payload) < SHM_THRESHOLD else payload


class ZenohTransport:
    """A Zenoh session configured for one visnav graph domain."""

    def __init__(
        self,
        config: TransportConfig,
        *,
        remote_subscriptions: RemoteSubscriptions | None = None,
    ) -> None:
        """Open the session.

        Args:
            config: where to listen and connect.
            remote_subscriptions: the subscriptions of a data key in other sessions (the
                context's graph); without it publishers never skip samples for paused
                paced subscriptions.

        Raises:
            TransportError: Zenoh cannot open the session.
        """
        self.config = config
        self._remote_subscriptions = remote_subscriptions
        try:
            self._session = zenoh.open(zenoh.Config.from_json5(json.dumps(config.zenoh_config())))
        except Exception as exc:
            msg = (
                f"cannot open the Zenoh session for domain {config.domain!r}: {exc}; "
                f"check {ENV_CONNECT}/{ENV_LISTEN}"
            )
            raise TransportError(msg) from exc
        self._closed = False
        self._lock = threading.Lock()
        self._shm: Any = None
        self._shm_failed = False
        self._refresher = PaceRefresher()

    @property
    def session(self) -> zenoh.Session:
        """The underlying Zenoh session."""
        return self._session

    @property
    def zid(self) -> str:
        """This session's Zenoh id (hex)."""
        return str(self._session.zid())

    def publisher(
        self,
        key: str,
        *,
        cache_depth: int | None = None,
        block: bool = False,
        publisher_id: int = 0,
    ) -> ZenohPublisher:
        """Declare a publisher on ``key``.

        Args:
            key: the data key expression.
            cache_depth: keep this many samples for late-joining subscribers (transient local).
            block: block under congestion instead of dropping (keep-all reliable topics).
            publisher_id: the publisher's entity id (names its cache queryable).
        """
        return ZenohPublisher(
            self._session,
            key,
            cache_depth=cache_depth,
            block=block,
            shm=self._shm_provider(),
            publisher_id=publisher_id,
            remote_subscriptions=self._remote_subscriptions,
        )

    def pace_reporter(self, key: str, entity_id: int, has_room: Callable[[], bool]) -> PaceReporter:
        """Declare where a paced subscription of ``key`` reports whether it has room."""
        return PaceReporter(self._session, key, self.zid, entity_id, has_room, self._refresher)

    def _shm_provider(self) -> Any:
        """The session's shared-memory provider (made on first use; None if unavailable)."""
        with self._lock:
            if self._shm is None and not self._shm_failed:
                try:
                    self._shm = zshm.ShmProvider.default_backend(SHM_POOL_BYTES)
                except Exception:  # noqa: BLE001 - no shared memory: sockets only
                    self._shm_failed = True
            return self._shm

    def subscriber(
        self,
        key: str,
        callback: Callable[[zenoh.ZBytes | bytes, zenoh.ZBytes | None], None],
        *,
        history: bool = False,
    ) -> Any:
        """Declare a subscriber to remote samples on ``key``; ``history`` fetches cached samples.

        ``callback(payload, attachment)`` runs on a Zenoh thread. Payloads of at least
        :data:`SHM_THRESHOLD` bytes come as the sample's :class:`zenoh.ZBytes`, uncopied:
        the receiver copies them out (``to_bytes()``) when, and only if, it needs them.
        Holding one holds its buffer, which may be a chunk of the sender's shared-memory
        pool (senders fall back to sockets when their pool is full, see
        :meth:`ZenohPublisher.put`). Smaller payloads come copied, as ``bytes``: they
        may be slices of a whole receive batch, which holding would pin.
        """

        def on_sample(sample: zenoh.Sample) -> None:
            callback(detach_small(sample.payload), sample.attachment)

        sub = self._session.declare_subscriber(key, on_sample, allowed_origin=zenoh.Locality.REMOTE)
        if history:
            self.fetch_latched(key, callback)
        return sub

    def ring_subscriber(self, key: str, capacity: int) -> Any:
        """Declare a subscriber to remote samples on ``key`` whose queue stays in Zenoh.

        The newest ``capacity`` samples wait in Zenoh's ring buffer (older ones are dropped
        there, with no Python code run); take them with ``sub.handler.recv()`` (blocks,
        releasing the GIL; raises once the subscriber is undeclared or the session closed)
        or ``sub.handler.try_recv()``. Small payloads should be copied out when taken (see
        :meth:`subscriber`).
        """
        return self._session.declare_subscriber(
            key, zenoh.handlers.RingChannel(capacity), allowed_origin=zenoh.Locality.REMOTE
        )

    def fetch_latched(
        self,
        key: str,
        callback: Callable[[zenoh.ZBytes | bytes, zenoh.ZBytes | None], None],
        zid: str | None = None,
    ) -> None:
        """Ask transient-local publishers of ``key`` (of one session, or all) for their cache.

        Replies arrive on a Zenoh thread through ``callback(payload, attachment)``; the
        subscription drops samples it already has (by publisher and sequence number).
        """
        selector = f"{key}/{LATCHED_CHUNK}/{zid}/*" if zid else f"{key}/{LATCHED_CHUNK}/**"

        def on_reply(reply: Any) -> None:
            ok = reply.ok
            if ok is not None:
                callback(detach_small(ok.payload), ok.attachment)

        self._session.get(
            selector,
            on_reply,
            target=zenoh.QueryTarget.ALL,
            consolidation=zenoh.ConsolidationMode.NONE,
            timeout=5.0,
            allowed_destination=zenoh.Locality.REMOTE,
        )

    def token(self, key: str) -> Any:
        """Declare a liveliness token (undeclared when the session closes)."""
        return self._session.liveliness().declare_token(key)

    def watch_liveliness(
        self, key: str, on_put: Callable[[str], None], on_delete: Callable[[str], None]
    ) -> Any:
        """Follow liveliness tokens matching ``key`` (current ones are reported first)."""

        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind == zenoh.SampleKind.PUT:
                on_put(str(sample.key_expr))
            else:
                on_delete(str(sample.key_expr))

        return self._session.liveliness().declare_subscriber(key, on_sample, history=True)

    def peers(self) -> list[str]:
        """Return the Zenoh ids of the connected peers."""
        return [str(z) for z in self._session.info.peers_zid()]

    def close(self) -> None:
        """Close the session (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._refresher.close()
        with contextlib.suppress(Exception):
            self._session.close()  # type: ignore[no-untyped-call]
