"""TCPROS: the connection header and the length-prefixed message frames of ROS 1 topics.

A TCPROS connection starts with each side sending a header: a little-endian ``uint32`` length,
then fields, each a ``uint32`` length and ``key=value`` bytes. The subscriber sends ``callerid``,
``topic``, ``type``, ``md5sum``, ``message_definition`` and ``tcp_nodelay``; the publisher
answers with ``callerid``, ``type``, ``md5sum``, ``message_definition`` and ``latching``, or with
a lone ``error`` field. Messages follow, each a ``uint32`` length and the ROS 1 bytes.

These functions read and write that format with limits, and raise :class:`TcprosError` for
anything else, so a broken peer costs its own connection and nothing more.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Mapping

from visnav.bridge.errors import TcprosError

__all__ = [
    "MAX_FRAME_BYTES",
    "MAX_HEADER_BYTES",
    "decode_header",
    "encode_header",
    "frame",
    "read_exact",
    "read_frame",
    "read_header",
    "split_frames",
]

MAX_HEADER_BYTES = 1 << 20
"""Largest connection header accepted (1 MiB; real ones are a few KB of definitions)."""
MAX_FRAME_BYTES = 1 << 30
"""Largest message accepted (1 GiB, roscpp's own limit)."""

_U32 = struct.Struct("<I")


def encode_header(fields: Mapping[str, str]) -> bytes:
    """Encode a connection header, length prefix included.

    Raises:
        TcprosError: a key is empty or holds ``=``.
    """
    parts: list[bytes] = []
    for key, value in fields.items():
        if not key or "=" in key:
            msg = f"TCPROS header key {key!r} is invalid: expected a non-empty name without '='"
            raise TcprosError(msg)
        item = f"{key}={value}".encode()
        parts.append(_U32.pack(len(item)))
        parts.append(item)
    body = b"".join(parts)
    return _U32.pack(len(body)) + body


def decode_header(data: bytes | bytearray | memoryview) -> dict[str, str]:
    """Decode the fields of a connection header (the bytes after its length prefix).

    Raises:
        TcprosError: a field length runs past the end, a field has no ``=``, or is not UTF-8.
    """
    view = memoryview(data)
    out: dict[str, str] = {}
    pos = 0
    end = len(view)
    while pos < end:
        if end - pos < 4:
            msg = f"TCPROS header ends inside a field length at byte {pos} of {end}"
            raise TcprosError(msg)
        (size,) = _U32.unpack_from(view, pos)
        pos += 4
        if size > end - pos:
            msg = (
                f"TCPROS header field at byte {pos - 4} claims {size} bytes but only "
                f"{end - pos} remain"
            )
            raise TcprosError(msg)
        raw = bytes(view[pos : pos + size])
        pos += size
        key, sep, value = raw.partition(b"=")
        if not sep or not key:
            msg = f"TCPROS header field {raw[:40]!r} is not key=value"
            raise TcprosError(msg)
        try:
            out[key.decode()] = value.decode()
        except UnicodeDecodeError as exc:
            msg = f"TCPROS header field {raw[:40]!r} is not UTF-8: {exc}"
            raise TcprosError(msg) from exc
    return out


def frame(payload: bytes | bytearray | memoryview) -> bytes:
    """Return the 4-byte length prefix of one message (send it, then the payload)."""
    return _U32.pack(len(payload))


def split_frames(
    buffer: bytes | bytearray | memoryview, *, max_size: int = MAX_FRAME_BYTES
) -> tuple[list[bytes], int]:
    """Split complete frames off the front of a byte stream.

    Returns:
        The payloads of the complete frames and the number of bytes they used (the rest is
        an incomplete frame that needs more bytes).

    Raises:
        TcprosError: a frame claims more than ``max_size`` bytes.
    """
    view = memoryview(buffer)
    frames: list[bytes] = []
    pos = 0
    while len(view) - pos >= 4:
        (size,) = _U32.unpack_from(view, pos)
        if size > max_size:
            msg = f"TCPROS frame of {size} bytes exceeds the limit of {max_size} bytes"
            raise TcprosError(msg)
        if len(view) - pos - 4 < size:
            break
        frames.append(bytes(view[pos + 4 : pos + 4 + size]))
        pos += 4 + size
    return frames, pos


def read_exact(sock: socket.socket, size: int, *, what: str = "data") -> bytearray:
    """Read exactly ``size`` bytes.

    Raises:
        TcprosError: the peer closed the connection first (says after how many bytes).
        OSError: the socket failed.
    """
    buf = bytearray(size)
    view = memoryview(buf)
    got = 0
    while got < size:
        n = sock.recv_into(view[got:], size - got)
        if n == 0:
            msg = f"peer closed the connection after {got} of {size} bytes of {what}"
            raise TcprosError(msg)
        got += n
    return buf


def _read_length(sock: socket.socket, limit: int, what: str) -> int:
    (size,) = _U32.unpack(read_exact(sock, 4, what=f"{what} length"))
    if size > limit:
        msg = f"{what} of {size} bytes exceeds the limit of {limit} bytes"
        raise TcprosError(msg)
    return int(size)


def read_header(sock: socket.socket) -> dict[str, str]:
    """Read and decode one connection header.

    Raises:
        TcprosError: closed early, too large or malformed.
    """
    size = _read_length(sock, MAX_HEADER_BYTES, "TCPROS header")
    return decode_header(read_exact(sock, size, what="TCPROS header"))


def read_frame(sock: socket.socket, *, max_size: int = MAX_FRAME_BYTES) -> bytearray:
    """Read one message frame; return its payload.

    Raises:
        TcprosError: closed mid-frame or the frame is larger than ``max_size``.
    """
    size = _read_length(sock, max_size, "TCPROS message")
    return read_exact(sock, size, what="a TCPROS message")
