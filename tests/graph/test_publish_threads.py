"""Publisher.publish from several threads at once: every message arrives intact.

The publisher serializes into one reused buffer before Zenoh copies it; without the
publisher's lock a second thread rewrote (and zeroed) that buffer while the first was
still handing it over, and both could read the same running sequence number. Zenoh's
put is quick, so the test also runs with a put that takes 0.1 ms longer (a blocking,
congested reliable topic). On the old code the slow-put case failed in 6 of 6 runs
(11-25 of 600 messages torn, others duplicated); the plain-put case is flaky there
(it failed in 3 of 7 runs, with one to six torn messages).
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from visnav.graph import Context, HistoryPolicy, MessageInfo, Node, QoSProfile, SerializedMessage
from visnav.msgs import String
from visnav.msgs.errors import MessageError

THREADS = 4
PER_THREAD = 150
BODY = 3000  # characters: one size for every message, so the buffer is always reused


def _text(thread: int, i: int) -> str:
    head = f"{thread}:{i:05d}:"
    return head + chr(ord("a") + thread) * (BODY - len(head))


def _intact(text: str) -> bool:
    thread, i, body = text.split(":", 2)
    return text == _text(int(thread), int(i)) and len(body) > 0


@pytest.fixture
def fast_switching() -> Iterator[None]:
    """Let threads switch every microsecond (the default 5 ms hides most interleavings)."""
    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    yield
    sys.setswitchinterval(old)


@pytest.mark.parametrize("put_delay_s", [0.0, 1e-4])
def test_threads_publishing_on_one_publisher_send_only_intact_messages(
    domain: int, fast_switching: None, put_delay_s: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    with Context(domain) as a, Context(domain) as b:
        tx, rx = Node("sender", context=a), Node("receiver", context=b)
        got: list[tuple[SerializedMessage, MessageInfo]] = []
        qos = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL)  # reliable, blocking: no drops
        rx.create_subscription(String, "/chatter", lambda m, i: got.append((m, i)), qos, raw=True)
        pub = tx.create_publisher(String, "/chatter", qos)
        deadline = time.monotonic() + 10.0
        while not (pub._zpub is not None and pub._zpub.has_subscribers):
            assert time.monotonic() < deadline, "publisher never matched"
            b.spin_once(0.01)
        if put_delay_s:
            put = pub._zpub.put

            def slow_put(payload: bytearray, attachment: bytes | None = None) -> None:
                time.sleep(put_delay_s)
                put(payload, attachment)

            monkeypatch.setattr(pub._zpub, "put", slow_put)
        start = threading.Barrier(THREADS)

        def talk(thread: int) -> None:
            start.wait()
            for i in range(PER_THREAD):
                pub.publish(String(data=_text(thread, i)))

        talkers = [threading.Thread(target=talk, args=(t,)) for t in range(THREADS)]
        for t in talkers:
            t.start()
        total = THREADS * PER_THREAD
        deadline = time.monotonic() + 30.0
        while len(got) < total and time.monotonic() < deadline:
            b.spin_once(0.05)
        for t in talkers:
            t.join()
        b.spin_some()
    assert len(got) == total
    bad: list[Any] = []
    for raw, _ in got:
        try:
            text = raw.deserialize().data
        except MessageError as exc:  # a torn buffer: terminator or length overwritten
            bad.append(exc)
            continue
        if not _intact(text):
            bad.append(text[:20])
    assert not bad, f"{len(bad)} of {total} messages arrived torn, e.g. {bad[:3]}"
    texts = sorted(raw.deserialize().data[:12] for raw, _ in got)
    assert texts == sorted(_text(t, i)[:12] for t in range(THREADS) for i in range(PER_THREAD))
    seqs = sorted(info.publication_sequence_number for _, info in got)
    assert seqs == list(range(1, total + 1))  # each message its own sequence number
