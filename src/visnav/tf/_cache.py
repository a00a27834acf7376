"""Per-frame time caches of a :class:`visnav.tf.Buffer` (tf2's ``TimeCache``/``StaticCache``).

One :class:`FrameCache` per child frame holds that frame's samples: a stamp in
integer nanoseconds, the parent frame id *of that sample* (a frame may be
re-parented over time, as in tf2) and the pose of the child in the parent.
Stamps are kept in an ascending list so a lookup is one ``bisect``; next to them,
per pair of neighbouring samples, the slerp constants of that interval (a
:data:`Span`, computed once on insertion instead of on every lookup).

Not thread safe on its own: the buffer holds its lock around every call.
"""

from __future__ import annotations

from bisect import bisect_left
from math import acos, sin

from visnav.tf._scalar import COS_TINY_THETA, Pose7, interpolate

__all__ = ["FrameCache", "Sample", "Span", "span"]

Sample = tuple[str, Pose7]
"""``(parent frame id, pose of the child in the parent)``."""

Span = tuple[
    str, int, float,
    float, float, float, float, float, float, float,
    float, float, float, float, float, float, float,
    float, float,
]  # fmt: skip
"""The interval from one sample to the next of the same parent, ready to interpolate:
``(parent, t0, 1 / (t1 - t0), older tx, ty, tz, qx, qy, qz, qw, newer tx, ty, tz,
qx, qy, qz, qw, theta, 1 / sin(theta))``: the newer quaternion negated when that is
the shorter arc, ``theta`` the arc between them (0.0 below ``_scalar``'s tiny angle,
where the slerp weights are linear). The numbers
:func:`visnav.tf._scalar.interpolate_py` derives on every call."""


def span(t0: int, older: Sample, t1: int, newer: Sample) -> Span | None:
    """Return the interval's :data:`Span`; None when the parents differ (no interpolation)."""
    parent = older[0]
    if parent != newer[0]:
        return None
    atx, aty, atz, x0, y0, z0, w0 = older[1]
    btx, bty, btz, x1, y1, z1, w1 = newer[1]
    dot = x0 * x1 + y0 * y1 + z0 * z1 + w0 * w1
    if dot < 0.0:  # the shorter arc: -q1 is the same rotation
        dot = -dot
        x1 = -x1
        y1 = -y1
        z1 = -z1
        w1 = -w1
    theta = inv_sin = 0.0
    if dot < COS_TINY_THETA:
        theta = acos(dot)
        inv_sin = 1.0 / sin(theta)
    return (parent, t0, 1.0 / (t1 - t0), atx, aty, atz, x0, y0, z0, w0,
            btx, bty, btz, x1, y1, z1, w1, theta, inv_sin)  # fmt: skip


# tf2 divides the sample count by at least 100 microseconds when it reports a rate.
_MIN_RATE_SPAN_NS = 100_000


class FrameCache:
    """The samples of one child frame: a sliding time window, or one static sample.

    Attributes:
        is_static: a static cache holds one sample valid at every time (a newer
            static transform replaces it).
        authority: who inserted the newest sample (tf2's broadcaster / authority).
        cache_time_ns: how far behind the newest stamp samples are kept (dynamic only).
        stamps: the sample stamps in ascending order (dynamic; ``[0]`` for static).
        samples: the samples, parallel to ``stamps``.
        spans: parallel to ``stamps``: ``spans[i]`` is the interval from sample ``i - 1``
            to sample ``i`` (``spans[0]`` is None).
    """

    __slots__ = ("authority", "cache_time_ns", "is_static", "samples", "spans", "stamps")

    def __init__(self, *, is_static: bool, cache_time_ns: int) -> None:
        self.is_static = is_static
        self.cache_time_ns = cache_time_ns
        self.authority = ""
        self.stamps: list[int] = []
        self.samples: list[Sample] = []
        self.spans: list[Span | None] = []

    def insert(self, stamp: int, parent: str, pose: Pose7) -> bool:
        """Store a sample; return False if it is older than the cache window (tf2's TF_OLD_DATA).

        A static cache keeps only the newest insertion. A dynamic sample at an existing
        stamp replaces the stored one (the later insertion wins, as in tf2's lookups);
        after insertion, samples older than ``newest - cache_time`` are dropped.
        """
        sample = (parent, pose)
        if self.is_static:
            self.stamps = [0]
            self.samples = [sample]
            self.spans = [None]
            return True
        stamps = self.stamps
        samples = self.samples
        spans = self.spans
        if not stamps or stamp > stamps[-1]:
            spans.append(span(stamps[-1], samples[-1], stamp, sample) if samples else None)
            stamps.append(stamp)
            samples.append(sample)
            cutoff = stamp - self.cache_time_ns
            if stamps[0] < cutoff:
                k = bisect_left(stamps, cutoff)
                del stamps[:k]
                del samples[:k]
                del spans[:k]
                spans[0] = None
            return True
        if stamp < stamps[-1] - self.cache_time_ns:
            return False
        i = bisect_left(stamps, stamp)
        before = span(stamps[i - 1], samples[i - 1], stamp, sample) if i else None
        if stamps[i] == stamp:
            samples[i] = sample
            spans[i] = before
        else:
            stamps.insert(i, stamp)
            samples.insert(i, sample)
            spans.insert(i, before)
        if i + 1 < len(samples):
            spans[i + 1] = span(stamp, sample, stamps[i + 1], samples[i + 1])
        return True

    def get(self, time_ns: int) -> Sample | None:
        """Return the sample at ``time_ns`` (0: the newest), interpolated; None if outside.

        Between two samples with the same parent the translation is interpolated
        linearly and the rotation by slerp; if the parent changed between them the
        older sample is returned unchanged (tf2's rule).
        """
        samples = self.samples
        if self.is_static or time_ns == 0:
            return samples[-1]
        stamps = self.stamps
        i = bisect_left(stamps, time_ns)
        n = len(stamps)
        if i < n and stamps[i] == time_ns:
            return samples[i]
        if i in (0, n):
            return None
        older = samples[i - 1]
        newer = samples[i]
        if older[0] != newer[0]:
            return older
        t0 = stamps[i - 1]
        ratio = (time_ns - t0) / (stamps[i] - t0)
        return older[0], interpolate(older[1], newer[1], ratio)

    def latest(self) -> tuple[int, str]:
        """Return ``(newest stamp, its parent)``; the stamp is 0 for a static cache (as tf2)."""
        if self.is_static:
            return 0, self.samples[0][0]
        return self.stamps[-1], self.samples[-1][0]

    @property
    def newest_ns(self) -> int:
        """The newest stamp (0 for a static cache, as tf2 reports it)."""
        return 0 if self.is_static else self.stamps[-1]

    @property
    def oldest_ns(self) -> int:
        """The oldest stamp still stored (0 for a static cache)."""
        return 0 if self.is_static else self.stamps[0]

    @property
    def parent(self) -> str:
        """The parent of the newest sample."""
        return self.samples[-1][0]

    def rate_hz(self) -> float:
        """Samples per second of stamp time, as tf2's ``allFramesAsYAML`` reports it."""
        span = max(self.newest_ns - self.oldest_ns, _MIN_RATE_SPAN_NS)
        return len(self.samples) * 1e9 / span
