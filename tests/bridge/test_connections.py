"""OutConnection: queueing and dropping under a slow peer never breaks the frame stream."""

from __future__ import annotations

import functools
import socket
import threading
import time

from visnav.bridge.connections import ConnectionStats, LazyParts, OutConnection, Parts
from visnav.bridge.tcpros import read_frame


def test_flood_into_a_full_socket_keeps_whole_frames_in_order() -> None:
    """Partly sent frames are finished, whole queued ones dropped oldest first."""
    ours, theirs = socket.socketpair()
    ours.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    theirs.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    stats = ConnectionStats(1, "peer", "o", "/t", "x")
    closed = threading.Event()
    conn = OutConnection(ours, stats, queue_size=3, on_close=lambda _c: closed.set())
    sender = threading.Thread(target=conn.run, daemon=True)
    sender.start()
    size = 50_000  # far more than the socket buffers: most sends stop part way
    count = 60
    for i in range(count):
        conn.push((i.to_bytes(4, "little"), bytes([i % 251]) * size))
    got: list[int] = []
    theirs.settimeout(5.0)
    while not got or got[-1] != count - 1:
        payload = read_frame(theirs)
        assert len(payload) == size + 4
        i = int.from_bytes(payload[:4], "little")
        assert payload[4:] == bytes([i % 251]) * size  # a whole frame, not a spliced one
        got.append(i)
    assert got == sorted(set(got))
    assert stats.dropped > 0
    deadline = time.monotonic() + 5.0  # counted after sendmsg returns: maybe after the read
    while stats.messages != len(got) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert stats.messages == len(got)
    conn.close()
    theirs.close()
    assert closed.wait(5.0)


def test_lazy_parts_are_made_only_for_messages_sent() -> None:
    """A flood of LazyParts: the dropped ones are never made, the sent ones once each."""
    ours, theirs = socket.socketpair()
    ours.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    theirs.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    stats = ConnectionStats(1, "peer", "o", "/t", "x")
    conn = OutConnection(ours, stats, queue_size=2, on_close=lambda _c: None)
    made: list[int] = []
    size, count = 50_000, 80

    def make(i: int) -> Parts | None:
        made.append(i)
        if i % 7 == 3:
            return None  # cannot be converted: skipped, the stream stays in frames
        return (i.to_bytes(4, "little"), bytes([i % 251]) * size)

    for i in range(count):
        conn.push(LazyParts(functools.partial(make, i)))
    sender = threading.Thread(target=conn.run, daemon=True)
    sender.start()
    got: list[int] = []
    theirs.settimeout(5.0)
    last = max(i for i in range(count) if i % 7 != 3)
    while not got or got[-1] != last:
        payload = read_frame(theirs)
        i = int.from_bytes(payload[:4], "little")
        assert payload[4:] == bytes([i % 251]) * size
        got.append(i)
    assert len(made) == len(set(made))  # each made once
    assert len(made) <= 2 + 2  # the first (sent at once), the queue's last two, one in flight
    assert set(got) <= set(made)
    assert stats.dropped >= count - len(made)
    conn.close()
    theirs.close()


def test_lazy_parts_shared_by_connections_are_made_once() -> None:
    calls: list[int] = []
    lazy = LazyParts(lambda: calls.append(1) or (b"abc",))
    results: list[Parts | None] = []
    threads = [threading.Thread(target=lambda: results.append(lazy.get())) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert calls == [1]
    assert results == [(b"abc",)] * 8
