"""TCPROS header and framing: round trips, limits, and fuzzing (only TcprosError escapes)."""

from __future__ import annotations

import socket
import struct
import threading

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.bridge.errors import TcprosError
from visnav.bridge.tcpros import (
    decode_header,
    encode_header,
    frame,
    read_frame,
    read_header,
    split_frames,
)

_keys = st.text(min_size=1, max_size=12).filter(lambda k: "=" not in k)


@given(st.dictionaries(_keys, st.text(max_size=40), max_size=8))
def test_header_round_trip(fields: dict[str, str]) -> None:
    data = encode_header(fields)
    (size,) = struct.unpack_from("<I", data)
    assert size == len(data) - 4
    assert decode_header(data[4:]) == fields


def test_header_bytes_match_ros1_layout() -> None:
    # rospy writes each field as <len><key=value>, the whole prefixed with its length
    assert encode_header({"a": "b"}) == b"\x07\x00\x00\x00\x03\x00\x00\x00a=b"
    assert decode_header(b"\x03\x00\x00\x00a=b\x05\x00\x00\x00c=d=e") == {"a": "b", "c": "d=e"}


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (b"\x09\x00\x00\x00a=b", "claims 9 bytes"),
        (b"\x03\x00\x00\x00abc", "not key=value"),
        (b"\x02\x00", "inside a field length"),
        (b"\x03\x00\x00\x00=ab", "not key=value"),
        (b"\x03\x00\x00\x00a=\xff", "not UTF-8"),
    ],
)
def test_bad_header_names_the_fault(data: bytes, words: str) -> None:
    with pytest.raises(TcprosError, match=words):
        decode_header(data)


def test_encode_refuses_bad_key() -> None:
    with pytest.raises(TcprosError, match="key 'a=b' is invalid"):
        encode_header({"a=b": "c"})


@settings(max_examples=300)
@given(st.binary(max_size=200))
def test_fuzz_decode_header(data: bytes) -> None:
    try:
        fields = decode_header(data)
    except TcprosError:
        return
    assert all(isinstance(k, str) and k for k in fields)


@settings(max_examples=300)
@given(st.binary(max_size=200), st.integers(min_value=0, max_value=64))
def test_fuzz_split_frames(data: bytes, limit: int) -> None:
    try:
        frames, used = split_frames(data, max_size=limit)
    except TcprosError:
        return
    assert used == sum(4 + len(f) for f in frames)
    assert used <= len(data)


@given(st.lists(st.binary(max_size=50), max_size=6), st.binary(max_size=3))
def test_split_frames_round_trip(payloads: list[bytes], tail: bytes) -> None:
    stream = b"".join(frame(p) + p for p in payloads)
    frames, used = split_frames(stream + tail)
    assert frames == payloads
    assert used == len(stream)


def _feed(data: bytes) -> socket.socket:
    a, b = socket.socketpair()

    def write() -> None:
        a.sendall(data)
        a.close()

    threading.Thread(target=write, daemon=True).start()
    return b


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=120))
def test_fuzz_socket_reads(data: bytes) -> None:
    sock = _feed(data)
    try:
        read_header(sock)
        while True:
            read_frame(sock, max_size=1000)
    except TcprosError:
        pass
    finally:
        sock.close()


def test_peer_closing_mid_message_is_named() -> None:
    sock = _feed(frame(b"x" * 10) + b"xxxx")
    with pytest.raises(TcprosError, match="closed the connection after 4 of 10 bytes"):
        read_frame(sock)
    sock.close()


def test_oversized_frame_refused() -> None:
    sock = _feed(struct.pack("<I", 2000))
    with pytest.raises(TcprosError, match="2000 bytes exceeds the limit of 1000"):
        read_frame(sock, max_size=1000)
    sock.close()


def test_send_parts_survives_partial_writes() -> None:
    from visnav.bridge.connections import send_parts

    a, b = socket.socketpair()
    a.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    body = bytes(range(256)) * 12_000  # 3 MB: many partial sendmsg calls
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(bytes(read_frame(b))))
    reader.start()
    sent = send_parts(a, (b"\x01\x02\x03\x04", memoryview(body)[4:]))
    reader.join(timeout=10)
    a.close()
    b.close()
    assert sent == len(body) + 4
    assert got == [b"\x01\x02\x03\x04" + body[4:]]
