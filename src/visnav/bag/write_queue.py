"""The recorder's writer thread: the executor hands messages over, a thread writes them.

Compression (bz2, zstd, lz4), CRCs and disk writes run on this thread, so the executor
that receives messages never waits for them (``rosbag record`` works the same way: its
subscribers fill a queue that a writer thread empties). The queue is bounded by bytes
(``rosbag record --buffsize``, 256 MiB by default): when the writer falls that far behind,
new messages are dropped and counted per topic, never silently. The last sixteenth of the
buffer is kept for small messages (up to 64 KiB), so that while images are being dropped,
``/clock``, TF, odometry and the like are still recorded.

A message may also be queued as a job (:meth:`WriteQueue.put_job`): a function run on the
writer thread that returns the bytes to write (the recorder compresses images this way, off
the executor's thread). A job that raises ``ValueError`` drops that message (counted, the
first error kept in :attr:`WriteQueue.job_errors`); the recording goes on.

The thread wakes every ``wake_period_s`` (20 ms) and writes what arrived meanwhile, or at
once when ``wake_bytes`` are waiting, rather than on every message: the car's recorder gets
~1,000 messages per simulated second (``/clock`` at 500 Hz), and waking the thread for each
cost the executor's thread a GIL hand-over per message (~3 % of its time).

A write error (disk full, file size limit, I/O error) ends the thread: the error is kept
in :attr:`WriteQueue.error`, later messages are counted as dropped, and the owner closes
the bag (what reached the file stays readable).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

from visnav.bag.errors import BagError
from visnav.bag.writer import BagWriter

__all__ = ["DEFAULT_BUFFER_BYTES", "SMALL_MESSAGE_BYTES", "WriteQueue"]

DEFAULT_BUFFER_BYTES = 256 << 20
"""Bytes of messages waiting for the writer before new ones are dropped (``rosbag -b 256``)."""

SMALL_MESSAGE_BYTES = 64 << 10
"""Messages up to this size may use the buffer's reserve (the last sixteenth)."""

WAKE_BYTES = 4 << 20
"""Bytes waiting that wake the writer thread before its period ends."""

_Job = Callable[[], bytes]
_Item = tuple[int, int, "bytes | _Job", int, int]  # handle, record time, data, publish, size


class WriteQueue:
    """Write serialized messages into a :class:`BagWriter` on a thread of its own.

    Args:
        writer: the open bag.
        max_bytes: most bytes waiting; messages that would exceed it are dropped.
        flush_period_s: put buffered messages into the file at least this often.
        wake_period_s: the thread writes what is queued at least this often.
        name: the thread's name.
    """

    def __init__(
        self,
        writer: BagWriter,
        *,
        max_bytes: int = DEFAULT_BUFFER_BYTES,
        flush_period_s: float = 0.5,
        wake_period_s: float = 0.02,
        name: str = "visnav-bag-writer",
    ) -> None:
        self.writer = writer
        self.max_bytes = max_bytes
        self.flush_period_s = flush_period_s
        self.wake_period_s = wake_period_s
        self.error: BaseException | None = None
        self.dropped: dict[int, int] = {}
        """Messages dropped per topic handle (buffer full, or after a write error)."""
        self.written = 0
        self.job_errors: dict[int, str] = {}
        """Per topic handle, the first error of a job that dropped its message."""
        self.peak_bytes = 0
        self.last_flush_monotonic = time.monotonic()
        self._items: deque[_Item] = deque()
        self._bytes = 0
        self._cond = threading.Condition()
        self.writer_lock = threading.Lock()
        """Held while the thread uses the writer; hold it to add a topic meanwhile."""
        self._closing = False
        self._abandon = False
        self._flush_wanted = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    @property
    def failed(self) -> bool:
        """True once a write failed (the thread has ended)."""
        return self.error is not None

    @property
    def pending_bytes(self) -> int:
        """Bytes waiting for the writer."""
        return self._bytes

    def put(self, handle: int, t_ns: int, data: bytes, publish_ns: int) -> bool:
        """Queue one message; return False when it was dropped (counted in :attr:`dropped`)."""
        return self._put(handle, t_ns, data, publish_ns, len(data))

    def put_job(self, handle: int, t_ns: int, job: _Job, publish_ns: int, *, size: int) -> bool:
        """Queue a message made on the writer thread by ``job()`` (see the module docstring).

        Args:
            handle: the topic handle.
            t_ns: record time.
            job: returns the serialized message; a ``ValueError`` drops it.
            publish_ns: publish time.
            size: bytes the job holds while it waits (counted against the buffer).

        Returns:
            False when the message was dropped at once (buffer full, closing, failed).
        """
        return self._put(handle, t_ns, job, publish_ns, size)

    def _put(self, handle: int, t_ns: int, data: bytes | _Job, publish_ns: int, size: int) -> bool:
        limit = self.max_bytes if size <= SMALL_MESSAGE_BYTES else self.max_bytes * 15 // 16
        with self._cond:
            if (
                self.error is not None
                or self._closing
                or (self._bytes + size > limit and self._items)
            ):
                self.dropped[handle] = self.dropped.get(handle, 0) + 1
                return False
            self._items.append((handle, t_ns, data, publish_ns, size))
            self._bytes += size
            self.peak_bytes = max(self.peak_bytes, self._bytes)
            if self._bytes >= WAKE_BYTES:  # else the thread's period picks it up
                self._cond.notify()
        return True

    def request_flush(self) -> None:
        """Ask the thread to put what it wrote so far into the file."""
        with self._cond:
            self._flush_wanted = True
            self._cond.notify()

    def close(self, timeout_s: float | None = None) -> None:
        """Write what is queued, then end the thread (idempotent).

        Args:
            timeout_s: wait at most this long for the queue to drain (None: no limit).
        """
        with self._cond:
            self._closing = True
            self._cond.notify()
        self._thread.join(timeout_s)

    def abandon(self) -> None:
        """Drop what is still queued (counted in :attr:`dropped`) so :meth:`close` is quick."""
        with self._cond:
            self._abandon = True
            self._drop(list(self._items))
            self._items.clear()
            self._bytes = 0
            self._cond.notify()

    def _run_job(self, handle: int, job: _Job) -> bytes | None:
        """The job's bytes, or None (dropped and counted) when it raised ValueError."""
        try:
            return job()
        except ValueError as exc:
            with self._cond:
                self.dropped[handle] = self.dropped.get(handle, 0) + 1
                self.job_errors.setdefault(handle, str(exc))
            return None

    def _drop(self, items: list[_Item]) -> None:
        for item in items:
            self.dropped[item[0]] = self.dropped.get(item[0], 0) + 1

    def _run(self) -> None:
        writer = self.writer
        while True:
            with self._cond:
                deadline = self.last_flush_monotonic + self.flush_period_s
                wake = time.monotonic() + self.wake_period_s
                while not self._closing and not self._flush_wanted:
                    now = time.monotonic()
                    due = now >= wake or self._bytes >= WAKE_BYTES
                    if now >= deadline or (self._items and due):
                        break
                    if now >= wake:  # nothing came this period
                        wake = now + self.wake_period_s
                    self._cond.wait(min(deadline, wake) - now)
                batch = list(self._items)
                self._items.clear()
                flush = self._flush_wanted or time.monotonic() >= deadline
                self._flush_wanted = False
                closing = self._closing
            done = 0
            try:
                for handle, t_ns, data, publish_ns, _size in batch:
                    if self._abandon:
                        with self._cond:
                            self._drop(batch[done:])
                        break
                    payload = data if isinstance(data, bytes) else self._run_job(handle, data)
                    if payload is not None:
                        with self.writer_lock:
                            writer.write(handle, t_ns, payload, publish_ns=publish_ns)
                        self.written += 1
                    done += 1
                written_bytes = sum(item[4] for item in batch[:done])
                with self._cond:  # once per batch: the executor's put takes this lock too
                    self._bytes = max(0, self._bytes - written_bytes)
                if flush and not closing:
                    with self.writer_lock:
                        writer.flush()
                    self.last_flush_monotonic = time.monotonic()
            except (OSError, BagError, ValueError, MemoryError) as exc:
                with self._cond:
                    self.error = exc
                    self._drop([*batch[done:], *self._items])
                    self._items.clear()
                    self._bytes = 0
                return
            if closing:
                with self._cond:
                    if not self._items:
                        return
