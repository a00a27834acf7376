"""OutConnection: queueing and dropping under a slow peer never breaks the frame stream."""

from __future__ import annotations

import socket
import threading

from visnav.bridge.connections import ConnectionStats, OutConnection
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
    assert stats.messages == len(got)
    conn.close()
    theirs.close()
    assert closed.wait(5.0)
