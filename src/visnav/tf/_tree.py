"""Walking the frame tree of a :class:`visnav.tf.Buffer` (tf2's ``walkToTopParent``).

Functions over the buffer's ``{child frame: FrameCache}`` map; the caller holds
the buffer's lock. Each child's cache records the parent per sample, so the tree
is only defined at a given time: the walk asks every link for its sample at that
time. The errors they raise carry tf2's facts (frames, times, direction).
"""

from __future__ import annotations

from visnav.tf import _scalar
from visnav.tf._cache import FrameCache
from visnav.tf._scalar import IDENTITY, Pose7
from visnav.tf.errors import ConnectivityException, ExtrapolationException, LookupException

__all__ = [
    "MAX_GRAPH_DEPTH",
    "connectivity_error",
    "extrapolation_error",
    "fmt_time",
    "latest_common_time",
    "loop_error",
    "root_of",
    "walk",
]

Caches = dict[str, FrameCache]

NS_PER_S = 1_000_000_000
MAX_GRAPH_DEPTH = 1000
"""tf2's limit: a longer walk means the tree has a loop."""


def fmt_time(ns: int) -> str:
    """Seconds with 6 decimals, exact for integer nanoseconds (as tf2's ``displayTimePoint``)."""
    sign = "-" if ns < 0 else ""
    sec, rem = divmod(abs(ns), NS_PER_S)
    return f"{sign}{sec}.{rem // 1000:06d}"


def latest_common_time(caches: Caches, target: str, source: str) -> int:
    """tf2's ``getLatestCommonTime``: the time that time 0 stands for in a lookup.

    The minimum, over the links from source and from target up to their common
    ancestor, of each link's newest stamp; static links (stamp 0) are ignored and
    an all-static chain gives 0. Parents are taken from the newest samples.

    Raises:
        ConnectivityException: the frames are in different trees.
        LookupException: the tree has a loop.
    """
    src_index: dict[str, int] = {source: 0}  # frame -> number of source links below it
    src_stamps: list[int] = []
    frame = source
    cache = caches.get(frame)
    while cache is not None:
        stamp, frame = cache.latest()
        src_stamps.append(stamp)
        if frame == target:
            return min((s for s in src_stamps if s), default=0)
        if frame in src_index or len(src_stamps) > MAX_GRAPH_DEPTH:
            raise loop_error(caches)
        src_index[frame] = len(src_stamps)
        cache = caches.get(frame)
    common = 0
    frame = target
    depth = 0
    while frame not in src_index:
        cache = caches.get(frame)
        if cache is None:
            raise connectivity_error(caches, target, source)
        stamp, frame = cache.latest()
        if stamp and (common == 0 or stamp < common):
            common = stamp
        depth += 1
        if depth > MAX_GRAPH_DEPTH:
            raise loop_error(caches)
    for stamp in src_stamps[: src_index[frame]]:
        if stamp and (common == 0 or stamp < common):
            common = stamp
    return common


def walk(caches: Caches, target: str, source: str, t: int, cache_time_ns: int) -> Pose7:
    """Compose ``T_target_source`` at time ``t`` (nonzero) through the common ancestor.

    Walks up from source recording ``T_frame_source`` for every frame reached, then
    up from target until it meets that chain. A link without data at ``t`` stops the
    source walk (the target walk may still meet the chain below it, as in tf2).

    Raises:
        ExtrapolationException: a needed link has no data at ``t``.
        ConnectivityException: the frames are in different trees at ``t``.
        LookupException: the tree has a loop.
    """
    compose = _scalar.compose
    chain: dict[str, Pose7] = {source: IDENTITY}
    acc = IDENTITY
    frame = source
    gap: str | None = None
    cache = caches.get(frame)
    while cache is not None:
        sample = cache.get(t)
        if sample is None:
            gap = frame
            break
        frame = sample[0]
        acc = compose(sample[1], acc)
        if frame == target:
            return acc
        if frame in chain:
            raise loop_error(caches)
        chain[frame] = acc
        cache = caches.get(frame)
    acc_t = IDENTITY
    frame = target
    depth = 0
    while frame not in chain:
        cache = caches.get(frame)
        if cache is None:
            if gap is not None:
                gap_cache = caches[gap]
                raise extrapolation_error(gap, gap_cache, t, target, source, cache_time_ns)
            raise connectivity_error(caches, target, source)
        sample = cache.get(t)
        if sample is None:
            raise extrapolation_error(frame, cache, t, target, source, cache_time_ns)
        frame = sample[0]
        acc_t = compose(sample[1], acc_t)
        depth += 1
        if depth > MAX_GRAPH_DEPTH:
            raise loop_error(caches)
    # frame is the common ancestor A: T_target_source = inv(T_A_target) @ T_A_source.
    return compose(_scalar.inverse(acc_t), chain[frame])


def root_of(caches: Caches, frame: str) -> str:
    """The root reached from ``frame`` by the newest parents (for error messages)."""
    seen = {frame}
    cache = caches.get(frame)
    while cache is not None:
        frame = cache.parent
        if frame in seen:
            break
        seen.add(frame)
        cache = caches.get(frame)
    return frame


def connectivity_error(caches: Caches, target: str, source: str) -> ConnectivityException:
    """The error for two frames in unconnected trees, naming both roots."""
    target_root = root_of(caches, target)
    source_root = root_of(caches, source)
    msg = (
        f"Could not find a connection between '{target}' and '{source}': they are in "
        f"different trees ('{target}' under root '{target_root}', '{source}' under root "
        f"'{source_root}'). TF has two or more unconnected trees; publish a transform "
        f"that links them (for example '{target_root}' -> '{source_root}')."
    )
    return ConnectivityException(
        msg,
        target_frame=target,
        source_frame=source,
        target_root=target_root,
        source_root=source_root,
    )


def loop_error(caches: Caches) -> LookupException:
    """The error for a tree with a loop, listing every frame and its newest parent."""
    listing = "".join(f"Frame {f} exists with parent {c.parent}.\n" for f, c in caches.items())
    return LookupException(f"The tf tree is invalid because it contains a loop:\n{listing}")


def extrapolation_error(
    frame: str, cache: FrameCache, t: int, target: str, source: str, cache_time_ns: int
) -> ExtrapolationException:
    """The error for link ``frame`` having no data at ``t``: direction, times, held range."""
    oldest, newest = cache.oldest_ns, cache.newest_ns
    link = f"frame [{frame}] (parent [{cache.parent}])"
    if oldest == newest:
        direction = "single"
        what = (
            f"Lookup would require extrapolation at time {fmt_time(t)} s, but {link} has "
            f"one sample only, at time {fmt_time(newest)} s"
        )
        hint = "Use time 0 (latest), or wait with a timeout for a second sample."
    elif t > newest:
        direction = "future"
        what = (
            f"Lookup would require extrapolation into the future: requested time "
            f"{fmt_time(t)} s is {(t - newest) / NS_PER_S:.6f} s after the latest data "
            f"for {link}, at time {fmt_time(newest)} s (held: {fmt_time(oldest)} .. "
            f"{fmt_time(newest)} s)"
        )
        hint = "Use time 0 for the latest common time, or wait with a timeout."
    else:
        direction = "past"
        what = (
            f"Lookup would require extrapolation into the past: requested time "
            f"{fmt_time(t)} s is {(oldest - t) / NS_PER_S:.6f} s before the earliest "
            f"data for {link}, at time {fmt_time(oldest)} s (held: {fmt_time(oldest)} .. "
            f"{fmt_time(newest)} s; cache_time {cache_time_ns / NS_PER_S:g} s)"
        )
        hint = (
            "The buffer keeps cache_time seconds behind each frame's newest sample: "
            "a larger cache_time keeps more history."
            if t < newest - cache_time_ns
            else "The link has no data that old: it started publishing later."
        )
    msg = f"{what}, when looking up transform from frame [{source}] to frame [{target}]. {hint}"
    return ExtrapolationException(
        msg,
        direction=direction,
        frame=frame,
        requested_ns=t,
        earliest_ns=oldest,
        latest_ns=newest,
        target_frame=target,
        source_frame=source,
    )
