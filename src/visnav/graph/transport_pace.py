"""Publisher-side pacing: a keep-last publisher skips samples no remote subscriber can take.

A paced subscription (``create_subscription(..., paced=True)``) that is paused cannot take
a sample: Zenoh would carry every sample to it (a shared-memory copy in the publisher, a
receive in the subscriber's process) only for its ring to drop all but the newest few. So
each paced subscription reports on ``<data key>/_pace/<zid>/<entity id>`` whether it has
room (``b"1"``) or is paused (``b"0"``, repeated every :data:`PACE_REFRESH_S` while paused),
and a volatile keep-last publisher of the key keeps a :class:`PaceTracker`: while every
remote subscription of its topic (from the graph's liveliness tokens) has said "paused"
within the last :data:`PACE_LEASE_S`, the publisher skips the sample (no serialization, no
put). A subscription that is not paced never reports, so it is never counted as full; a
lost or late report only costs samples that are sent after all (the lease runs out).

This mirrors what a ROS 1 publisher does when a subscriber cannot keep up: its per-connection
queue, in the publisher's process, drops what the TCP socket does not take, so a flooding
publisher sends a slow subscriber only what it reads. rmw_zenoh has no such scheme: there
Zenoh carries every sample and the subscriber's queue drops the excess.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Collection
from typing import Any

import zenoh

__all__ = [
    "PACE_CHUNK",
    "PACE_LEASE_S",
    "PACE_REFRESH_S",
    "PaceRefresher",
    "PaceReporter",
    "PaceTracker",
    "RemoteSubscriptions",
    "pace_key",
    "parse_pace_report",
]

PACE_CHUNK = "_pace"
"""Key chunk under a topic key where paced subscriptions report whether they have room."""
PACE_REFRESH_S = 0.05
"""How often a paused subscription repeats that it is paused."""
PACE_LEASE_S = 0.25
"""How long a publisher trusts one "paused" report (so a lost "room" report, or a subscriber
that died paused, costs at most this long of skipped samples)."""

_PRUNE_AT = 64

RemoteSubscriptions = Callable[[str], Collection[tuple[str, int]]]
"""``f(data key) -> {(zid, entity id)}``: the subscriptions of the key in other sessions."""


def pace_key(key: str, zid: str, entity_id: int) -> str:
    """Key where one paced subscription of ``key`` reports whether it has room."""
    return f"{key}/{PACE_CHUNK}/{zid}/{entity_id}"


def parse_pace_report(key: str, payload: bytes) -> tuple[tuple[str, int], bool] | None:
    """``((zid, entity id), has room)`` of a report on :func:`pace_key`, or None if malformed."""
    parts = key.rsplit("/", 3)
    if len(parts) != 4 or parts[1] != PACE_CHUNK or not parts[2] or payload not in (b"0", b"1"):
        return None
    entity = parts[3]
    if not entity.isascii() or not entity.isdigit():
        return None
    return (parts[2], int(entity)), payload == b"1"


class PaceReporter:
    """Reports one paced subscription's state to the publishers of its key.

    Args:
        session: the subscription's Zenoh session.
        key: the topic's data key.
        zid: the session's id.
        entity_id: the subscription's entity id.
        has_room: returns the subscription's current state (True: it takes samples).
        refresher: repeats "paused" while the subscription stays paused.
    """

    def __init__(
        self,
        session: zenoh.Session,
        key: str,
        zid: str,
        entity_id: int,
        has_room: Callable[[], bool],
        refresher: PaceRefresher,
    ) -> None:
        self._has_room = has_room
        self._refresher = refresher
        self._lock = threading.Lock()
        self._closed = False
        self._pub: Any = session.declare_publisher(
            pace_key(key, zid, entity_id),
            allowed_destination=zenoh.Locality.REMOTE,
            # never stall the reporting thread (the executor) on a congested link: a lost
            # "paused" is repeated every PACE_REFRESH_S, a lost "room" expires with the lease
            congestion_control=zenoh.CongestionControl.DROP,
            priority=zenoh.Priority.INTERACTIVE_HIGH,
            express=True,
        )

    def report(self) -> None:
        """Send the subscription's state as it is now (safe from any thread).

        The state is read under the lock, so when two threads report at once the last
        report sent is the latest state.
        """
        with self._lock:
            if self._closed:
                return
            room = self._has_room()
            with contextlib.suppress(Exception):  # zenoh.ZError: the session is closing
                self._pub.put(b"1" if room else b"0")
        if room:
            self._refresher.discard(self)
        else:
            self._refresher.add(self)

    def refresh(self) -> None:
        """Repeat "paused" if the subscription still is (the refresher's thread calls it)."""
        with self._lock:
            if self._closed or self._has_room():
                return
            with contextlib.suppress(Exception):
                self._pub.put(b"0")

    def close(self) -> None:
        """Say "room" one last time (publishers stop skipping at once) and undeclare."""
        self._refresher.discard(self)
        with self._lock:
            if self._closed:
                return
            self._closed = True
            with contextlib.suppress(Exception):  # the session may be closing
                self._pub.put(b"1")
            with contextlib.suppress(Exception):
                self._pub.undeclare()


class PaceRefresher:
    """One thread per session that repeats "paused" every :data:`PACE_REFRESH_S`.

    Not the subscription's pump thread: that one may be blocked waiting for a sample.
    The thread starts with the first paused subscription and ends with :meth:`close`.
    """

    def __init__(self) -> None:
        self._paused: set[PaceReporter] = set()
        self._cond = threading.Condition()
        self._closed = False
        self._thread: threading.Thread | None = None

    def add(self, reporter: PaceReporter) -> None:
        """Repeat ``reporter``'s "paused" until :meth:`discard`."""
        with self._cond:
            if self._closed:
                return
            self._paused.add(reporter)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="visnav-pace", daemon=True)
                self._thread.start()
            self._cond.notify()

    def discard(self, reporter: PaceReporter) -> None:
        """Stop repeating for ``reporter``."""
        with self._cond:
            self._paused.discard(reporter)

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._paused and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                self._cond.wait(PACE_REFRESH_S)
                if self._closed:
                    return
                paused = list(self._paused)
            for reporter in paused:
                reporter.refresh()

    def close(self) -> None:
        """End the thread."""
        with self._cond:
            self._closed = True
            self._paused.clear()
            self._cond.notify_all()


class PaceTracker:
    """A publisher's view of which remote paced subscriptions of its key are paused.

    Args:
        session: the publisher's Zenoh session.
        key: the topic's data key.
        remote_subscriptions: the key's subscriptions in other sessions (from the graph).
        clock: monotonic seconds (for tests).
    """

    def __init__(
        self,
        session: zenoh.Session,
        key: str,
        remote_subscriptions: RemoteSubscriptions,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._key = key
        self._remote = remote_subscriptions
        self._clock = clock
        self._paused: dict[tuple[str, int], float] = {}  # (zid, entity id) -> lease end
        self._lock = threading.Lock()  # for writers; all_paused reads without it
        self.skipped = 0
        """Samples skipped because every remote subscription was paused."""
        self._sub: Any = session.declare_subscriber(
            f"{key}/{PACE_CHUNK}/*/*", self._on_report, allowed_origin=zenoh.Locality.REMOTE
        )

    def _on_report(self, sample: zenoh.Sample) -> None:
        report = parse_pace_report(str(sample.key_expr), sample.payload.to_bytes())
        if report is None:
            return  # not a visnav subscription's report
        source, room = report
        paused = self._paused
        with self._lock:  # reports from two sessions may come on two Zenoh threads at once
            if not room:
                now = self._clock()
                if len(paused) >= _PRUNE_AT:  # subscriptions that went away paused
                    for gone in [k for k, lease in paused.items() if lease < now]:
                        paused.pop(gone, None)
                paused[source] = now + PACE_LEASE_S
            else:
                paused.pop(source, None)

    def all_paused(self) -> bool:
        """Whether every remote subscription of the key is paused (False when there is none).

        Counts a True answer in :attr:`skipped`: the caller skips the sample.
        """
        paused = self._paused
        if not paused:  # the common case: nobody paused
            return False
        subs = self._remote(self._key)
        if not subs:
            return False
        now = self._clock()
        for source in subs:
            lease = paused.get(source)
            if lease is None or lease < now:
                return False
        self.skipped += 1
        return True

    def close(self) -> None:
        """Stop listening for reports."""
        with contextlib.suppress(Exception):
            self._sub.undeclare()
