"""Per-frame time caches of a :class:`visnav.tf.Buffer` (tf2's ``TimeCache``/``StaticCache``).

One :class:`FrameCache` per child frame holds that frame's samples: a stamp in
integer nanoseconds, the parent frame id *of that sample* (a frame may be
re-parented over time, as in tf2) and the pose of the child in the parent.
Stamps are kept in an ascending list so a lookup is one ``bisect``.

Not thread safe on its own: the buffer holds its lock around every call.
"""

from __future__ import annotations

from bisect import bisect_left

from visnav.tf._scalar import Pose7, interpolate

__all__ = ["FrameCache", "Sample"]

Sample = tuple[str, Pose7]
"""``(parent frame id, pose of the child in the parent)``."""

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
    """

    __slots__ = ("authority", "cache_time_ns", "is_static", "samples", "stamps")

    def __init__(self, *, is_static: bool, cache_time_ns: int) -> None:
        self.is_static = is_static
        self.cache_time_ns = cache_time_ns
        self.authority = ""
        self.stamps: list[int] = []
        self.samples: list[Sample] = []

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
            return True
        stamps = self.stamps
        samples = self.samples
        if not stamps or stamp > stamps[-1]:
            stamps.append(stamp)
            samples.append(sample)
            cutoff = stamp - self.cache_time_ns
            if stamps[0] < cutoff:
                k = bisect_left(stamps, cutoff)
                del stamps[:k]
                del samples[:k]
            return True
        if stamp < stamps[-1] - self.cache_time_ns:
            return False
        i = bisect_left(stamps, stamp)
        if stamps[i] == stamp:
            samples[i] = sample
        else:
            stamps.insert(i, stamp)
            samples.insert(i, sample)
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
