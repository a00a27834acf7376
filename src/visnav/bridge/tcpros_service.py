"""TCPROS for services: the server's side of a connection and a client's call.

A ROS 1 service client connects to the server's TCPROS port (``rosrpc://host:port`` from the
master's ``lookupService``) and sends a header with ``callerid``, ``service``, ``md5sum`` and
optionally ``persistent=1`` (``rosservice`` first sends ``probe=1`` with ``md5sum=*`` to learn
the type). The server answers with a header (``callerid``, ``md5sum``, ``type``,
``request_type``, ``response_type``) or a lone ``error``. Then each request is a length-prefixed
frame, and each reply one *ok* byte (1 success, 0 failure) followed by a length-prefixed frame:
the response's bytes, or the error text. A persistent connection carries call after call;
otherwise the connection ends after one.

Everything a peer sends is checked with limits; a broken peer costs its own connection
(:class:`~visnav.bridge.errors.TcprosError`, logged) and nothing more.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import struct
from collections.abc import Callable
from dataclasses import dataclass
from urllib.parse import urlsplit

from visnav.bridge.errors import Ros1ServiceError, TcprosError
from visnav.bridge.srvmap import Ros1ServiceType
from visnav.bridge.tcpros import encode_header, read_exact, read_frame, read_header

__all__ = [
    "MAX_SERVICE_FRAME_BYTES",
    "ServedService",
    "ServiceHandler",
    "call_service",
    "parse_rosrpc_uri",
    "probe_service",
    "serve_service_connection",
    "service_md5_refusal",
]

_log = logging.getLogger("visnav.bridge")
_U32 = struct.Struct("<I")

MAX_SERVICE_FRAME_BYTES = 256 << 20
"""Largest request or response accepted (256 MiB: a large map's ``GetMap`` is a few MB)."""

ServiceHandler = Callable[[bytes], bytes]
"""Turns a request's ROS 1 bytes into the response's; an exception is the error reply."""


@dataclass
class ServedService:
    """One service a :class:`~visnav.bridge.ros1_node.Ros1Node` serves to ROS 1."""

    name: str
    stype: Ros1ServiceType
    handler: ServiceHandler
    calls: int = 0
    failures: int = 0


def service_md5_refusal(service: str, ours: Ros1ServiceType, header: dict[str, str]) -> str:
    """rospy's refusal text when a client's ``md5sum`` differs ('' when it matches or is ``*``)."""
    theirs = header.get("md5sum", "")
    if theirs in ("*", ours.md5sum):
        return ""
    return (
        f"request from [{header.get('callerid', '?')}]: md5sums do not match: [{theirs}] vs. "
        f"[{ours.md5sum}] (service {service} is {ours.ros1_name} in visnav; both sides must "
        "build the same .srv definition)"
    )


def _reply(sock: socket.socket, ok: bool, payload: bytes) -> None:
    sock.sendall(b"\x01" if ok else b"\x00")
    sock.sendall(_U32.pack(len(payload)) + payload)


def serve_service_connection(
    sock: socket.socket,
    header: dict[str, str],
    served: ServedService,
    *,
    caller_id: str,
    peer: str,
) -> None:
    """Serve one ROS 1 service connection whose header was read (closes ``sock``).

    Args:
        sock: the accepted socket.
        header: the client's connection header.
        served: the service.
        caller_id: this node's name.
        peer: the client, for logs.
    """
    try:
        refusal = service_md5_refusal(served.name, served.stype, header)
        if refusal:
            _log.warning("refused a call of %s from %s: %s", served.name, peer, refusal)
            sock.sendall(encode_header({"error": refusal}))
            return
        sock.sendall(
            encode_header(
                {
                    "callerid": caller_id,
                    "service": served.name,
                    "md5sum": served.stype.md5sum,
                    "type": served.stype.ros1_name,
                    "request_type": served.stype.request.ros1_name,
                    "response_type": served.stype.response.ros1_name,
                }
            )
        )
        if header.get("probe") == "1":
            return
        persistent = header.get("persistent", "").lower() in ("1", "true")
        sock.settimeout(None if persistent else 60.0)
        first = True
        while first or persistent:
            try:
                request = read_frame(sock, max_size=MAX_SERVICE_FRAME_BYTES)
            except TcprosError as exc:
                if not first and "after 0 of 4 bytes" in str(exc):
                    return  # a persistent client closed between calls
                raise
            first = False
            served.calls += 1
            try:
                response = served.handler(bytes(request))
            except Exception as exc:  # noqa: BLE001 - any failure is the caller's error reply
                served.failures += 1
                _reply(sock, False, str(exc).encode())
            else:
                _reply(sock, True, response)
    except (TcprosError, OSError) as exc:
        _log.warning("dropped a ROS 1 call of %s from %s: %s", served.name, peer, exc)
    finally:
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)
        sock.close()


def parse_rosrpc_uri(uri: str) -> tuple[str, int]:
    """``(host, port)`` of a ``rosrpc://host:port`` URI.

    Raises:
        Ros1ServiceError: not such a URI.
    """
    parts = urlsplit(uri)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "rosrpc" or not parts.hostname or port is None:
        msg = f"service URI {uri!r} is not rosrpc://HOST:PORT"
        raise Ros1ServiceError(msg)
    return parts.hostname, port


def _connect(uri: str, timeout_s: float) -> socket.socket:
    host, port = parse_rosrpc_uri(uri)
    sock = socket.create_connection((host, port), timeout=timeout_s)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def probe_service(
    uri: str, service: str, *, caller_id: str, timeout_s: float = 5.0
) -> dict[str, str]:
    """The server's connection header (``type``, ``md5sum``, ...) without calling it.

    Raises:
        Ros1ServiceError: the server cannot be reached or answers with an error.
    """
    try:
        with _connect(uri, timeout_s) as sock:
            sock.sendall(
                encode_header(
                    {"callerid": caller_id, "service": service, "md5sum": "*", "probe": "1"}
                )
            )
            header = read_header(sock)
    except (OSError, TcprosError) as exc:
        msg = f"ROS 1 service {service} at {uri} did not answer a probe: {exc}"
        raise Ros1ServiceError(msg) from exc
    if "error" in header:
        msg = f"ROS 1 service {service} at {uri} refused a probe: {header['error']}"
        raise Ros1ServiceError(msg)
    return header


def call_service(
    uri: str,
    service: str,
    stype: Ros1ServiceType,
    request: bytes,
    *,
    caller_id: str,
    timeout_s: float = 10.0,
) -> bytes:
    """Call a ROS 1 service once (a fresh connection) and return the response's bytes.

    Raises:
        Ros1ServiceError: the server cannot be reached, refuses (another MD5 sum), fails
            the call (its error text), or breaks the protocol; each names the service.
    """
    try:
        with _connect(uri, timeout_s) as sock:
            sock.sendall(
                encode_header(
                    {
                        "callerid": caller_id,
                        "service": service,
                        "md5sum": stype.md5sum,
                        "type": stype.ros1_name,
                    }
                )
            )
            header = read_header(sock)
            if "error" in header:
                msg = f"ROS 1 service {service} refused the call: {header['error']}"
                raise Ros1ServiceError(msg)
            sock.sendall(_U32.pack(len(request)) + request)
            ok = read_exact(sock, 1, what="the reply's ok byte")[0]
            payload = bytes(read_frame(sock, max_size=MAX_SERVICE_FRAME_BYTES))
    except (OSError, TcprosError) as exc:
        msg = f"ROS 1 service {service} at {uri}: {exc}"
        raise Ros1ServiceError(msg) from exc
    if ok == 0:  # rospy reads any other value as success
        text = payload.decode(errors="replace")
        msg = f"ROS 1 service {service} failed: {text}"
        raise Ros1ServiceError(msg)
    return payload
