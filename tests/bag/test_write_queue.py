"""The recorder's writer thread: bounded by bytes, a reserve for small messages, no silent loss."""

from __future__ import annotations

import errno
import time
from typing import cast

from visnav.bag.write_queue import WriteQueue
from visnav.bag.writer import BagWriter

MIB = 1 << 20


class _Sink:
    """Stands in for a BagWriter: records what is written; can fail on demand."""

    def __init__(self, fail_after: int | None = None) -> None:
        self.written: list[tuple[int, int, int]] = []
        self.flushes = 0
        self.fail_after = fail_after

    def write(self, handle: int, t_ns: int, data: bytes, *, publish_ns: int) -> None:
        if self.fail_after is not None and len(self.written) >= self.fail_after:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.written.append((handle, t_ns, len(data)))

    def flush(self) -> None:
        self.flushes += 1


def _queue(sink: _Sink, max_bytes: int = 16 * MIB) -> WriteQueue:
    return WriteQueue(cast(BagWriter, sink), max_bytes=max_bytes, flush_period_s=0.05)


def test_everything_is_written_in_order() -> None:
    sink = _Sink()
    q = _queue(sink)
    for i in range(500):
        assert q.put(i % 3, i, b"x" * 100, i)
    q.close(5.0)
    assert [t for _, t, _ in sink.written] == list(range(500))
    assert q.dropped == {}
    assert q.pending_bytes == 0


def test_full_buffer_drops_large_messages_but_keeps_small_ones() -> None:
    sink = _Sink()
    q = _queue(sink, max_bytes=16 * MIB)
    big = b"i" * MIB
    with q.writer_lock:  # the writer is stuck (a slow compressor): the buffer fills up
        time.sleep(0.05)
        accepted = sum(q.put(0, i, big, i) for i in range(40))
        small = sum(q.put(1, i, b"c" * 100, i) for i in range(1000))
        assert accepted < 40
        assert small == 1000  # /clock-like messages use the reserve
        assert q.dropped == {0: 40 - accepted}
    q.close(10.0)
    written_big = sum(1 for h, _, _ in sink.written if h == 0)
    assert written_big == accepted
    assert sum(1 for h, _, _ in sink.written if h == 1) == 1000


def test_abandon_drops_the_backlog_and_counts_it() -> None:
    sink = _Sink()
    q = _queue(sink)
    with q.writer_lock:
        for i in range(100):
            assert q.put(2, i, b"z" * 1000, i)
        q.abandon()
    q.close(5.0)
    assert len(sink.written) + q.dropped.get(2, 0) == 100
    assert q.dropped.get(2, 0) >= 99


def test_a_write_error_ends_the_thread_and_counts_the_rest() -> None:
    sink = _Sink(fail_after=10)
    q = _queue(sink)
    for i in range(30):
        q.put(5, i, b"y" * 10, i)
    deadline = time.monotonic() + 5.0
    while not q.failed and time.monotonic() < deadline:
        time.sleep(0.01)
    assert q.failed
    assert isinstance(q.error, OSError)
    assert q.error.errno == errno.ENOSPC
    assert not q.put(5, 99, b"y", 99)  # after the error: dropped, counted
    q.close(5.0)
    assert len(sink.written) == 10
    assert q.dropped[5] == 30 - 10 + 1


def test_flushes_periodically() -> None:
    sink = _Sink()
    q = _queue(sink)
    q.put(0, 1, b"a", 1)
    time.sleep(0.3)
    assert sink.flushes >= 2
    q.close(5.0)
