"""``PacedFeed``: a live feed in another process than the publishers, asking only for what it shows.

A viewer shows an image, a cloud or a scan a few times a second (the display rates of
:data:`~visnav.viz.display_sink.DISPLAY_RATES_HZ`), while the simulator publishes them
at 10-30 Hz. Over Zenoh every sample a remote subscription takes costs the publisher's
process a serialization and a copy, so a viewer that subscribes normally and drops what
it does not show still slows the simulation down. :class:`PacedFeed` subscribes to the
display-rated topics with *paced* subscriptions of depth 1 (see
:mod:`visnav.graph.subscription`) and pauses each one after a message for the time until
the next one is due: while paused, the publishers skip the viewer's samples (no
serialization, no transfer, and a camera whose only subscriber is a paused viewer does
not render for it).

How long a pause lasts: the display period in wall-clock seconds, and at least the
display period in stamp time at the real-time factor the topic's stamps show (a run
at a real-time factor of 0.5 gets a message every 0.4 wall seconds for a 5 Hz display
rate, as many per simulated second as at real time), at most :data:`MAX_PAUSE_S`. A
message the display rate skips (it came early) pauses the subscription for the rest of
the period; one that was due but not taken (the viewer's queue is full) for a whole
one. Topics that are latched (transient local), keep-all, or of a type shown in full
(TF, markers, strings) are subscribed to as :class:`~visnav.viz.LiveFeed` does.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable, Collection
from typing import Any

from visnav.graph.context import Context
from visnav.graph.qos import DurabilityPolicy, HistoryPolicy, QoSProfile
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import time_to_ns
from visnav.viz.display_sink import DISPLAY_RATES_HZ, DisplaySink
from visnav.viz.sink import RerunSink
from visnav.viz.sources import LiveFeed

__all__ = ["MAX_PAUSE_S", "MIN_PAUSE_S", "PacedFeed", "pause_s"]

_LOG = logging.getLogger("visnav.viz")

MAX_PAUSE_S = 1.0
"""The longest a paced subscription stays paused (wall seconds)."""

MIN_PAUSE_S = 0.01
"""The shortest pause (wall seconds): below it the subscription is not paused."""


def pause_s(
    period_s: float,
    *,
    kept: bool,
    since_kept_s: float | None,
    rate: float | None,
) -> float:
    """How long to pause a paced subscription after a message (wall seconds).

    Args:
        period_s: the display period of the message's kind (stamp seconds).
        kept: the message was queued to be shown (else the display rate skipped it, or
            the viewer's queue was full).
        since_kept_s: stamp seconds from the last shown message to this one (None: none
            shown before, or no stamp).
        rate: stamp seconds per wall second the topic shows (the run's real-time
            factor; None: not known yet).

    Returns:
        The pause, between 0 and :data:`MAX_PAUSE_S` (0: do not pause).
    """
    if not period_s > 0:
        return 0.0
    speed = rate if rate is not None and rate > 0 and math.isfinite(rate) else 1.0
    early = not kept and since_kept_s is not None and since_kept_s < period_s
    if early:  # the rest of the period
        wait = max(period_s - max(since_kept_s or 0.0, 0.0), 0.0) / speed
    else:  # shown, or due but not taken (the viewer's queue is full): a whole period
        wait = max(period_s, period_s / speed)
    wait = min(wait, MAX_PAUSE_S)
    return wait if wait >= MIN_PAUSE_S else 0.0


def _stamp_ns(msg: Any) -> int | None:
    header = getattr(msg, "header", None)
    return time_to_ns(header.stamp) if header is not None else None


class PacedFeed(LiveFeed):
    """A :class:`~visnav.viz.LiveFeed` whose display-rated topics are paced (module doc).

    Call :meth:`spin_once` (or :meth:`run`) from one thread: it resumes the subscriptions
    whose pause is over, then runs the callbacks.

    Args:
        sink: the sink (pacing needs a :class:`~visnav.viz.display_sink.DisplaySink`:
            with a bare :class:`~visnav.viz.RerunSink` every message is taken).
        context: the graph context to join.
        topics: only these topics (plus ``/tf`` and ``/tf_static``).
        accept: ``accept(topic, type)`` false leaves a topic out for now.
    """

    def __init__(
        self,
        sink: RerunSink | DisplaySink,
        context: Context,
        *,
        topics: Collection[str] | None = None,
        accept: Callable[[str, str], bool] | None = None,
    ) -> None:
        self._paced: dict[str, Any] = {}
        self._resume_at: dict[str, float] = {}
        self._kept: dict[str, tuple[int, float]] = {}  # topic -> (stamp ns, wall s) last shown
        self._rate: dict[str, float] = {}
        self.pauses = 0
        """Times a subscription was paused."""
        super().__init__(sink, context, topics=topics, accept=accept)

    @property
    def paced_topics(self) -> list[str]:
        """The topics subscribed to with paced subscriptions."""
        return list(self._paced)

    def _subscribe(self, topic: str, type_name: str, qos: Any) -> None:
        if type_name not in DISPLAY_RATES_HZ or not _paceable(qos):
            super()._subscribe(topic, type_name, qos)
            return
        cls = get_message_class(type_name)
        one = dataclasses.replace(qos, depth=1)

        def on_msg(msg: Any) -> None:
            self.received += 1
            kept = self.sink.log(topic, msg)
            self._after(topic, msg, kept)

        sub = self.node.create_subscription(cls, topic, on_msg, one, paced=True)
        self._subscribed[topic] = self._paced[topic] = sub
        _LOG.debug("viewer: subscribed to %s (%s), paced", topic, type_name)

    def _after(self, topic: str, msg: Any, kept: bool) -> None:
        """Pause ``topic``'s subscription until its next message is due."""
        sink = self.sink
        if not isinstance(sink, DisplaySink):
            return
        period = sink.period_s(msg)
        stamp = _stamp_ns(msg)
        now = time.monotonic()
        last = self._kept.get(topic)
        since = None if stamp is None or last is None else (stamp - last[0]) / 1e9
        if kept and stamp is not None:
            if last is not None and since is not None and since > 0 and now > last[1]:
                self._rate[topic] = since / (now - last[1])
            self._kept[topic] = (stamp, now)
        wait = pause_s(period, kept=kept, since_kept_s=since, rate=self._rate.get(topic))
        if wait > 0:
            self._paced[topic].pause()
            self._resume_at[topic] = now + wait
            self.pauses += 1

    def resume_due(self) -> float:
        """Resume the subscriptions whose pause is over; seconds until the next is due."""
        if not self._resume_at:
            return math.inf
        now = time.monotonic()
        for topic, at in list(self._resume_at.items()):
            if at <= now:
                del self._resume_at[topic]
                self._paced[topic].resume()
        return min((at - now for at in self._resume_at.values()), default=math.inf)

    def spin_once(self, timeout_s: float = 0.05) -> None:
        """Resume what is due, then run callbacks for ``timeout_s`` at most (or to a resume)."""
        wait = self.resume_due()
        super().spin_once(max(0.0, min(timeout_s, wait)))

    def close(self) -> None:
        """Destroy the viewer node (and its subscriptions)."""
        self._paced.clear()
        self._resume_at.clear()
        super().close()


def _paceable(qos: Any) -> bool:
    """Keep-last volatile QoS: what a paced subscription needs."""
    return (
        isinstance(qos, QoSProfile)
        and qos.history is HistoryPolicy.KEEP_LAST
        and qos.durability is DurabilityPolicy.VOLATILE
    )
