"""Precomputed lookup chains of a :class:`visnav.tf.Buffer`: the fast path of ``lookup_transform``.

A lookup walks both frames up to their common ancestor (:func:`visnav.tf._tree.walk`).
Most programs ask the same few frame pairs again and again, so the buffer keeps, per
``(target, source)``, a :class:`Plan`: the links of each side in walking order, runs of
static links composed once into one pose, and for each dynamic link the parent the
walk expects.

Using a plan gives exactly the general walk's answer as long as every dynamic link's
sample at the lookup time has the expected parent (checked on every use) and the
frames' caches are the ones the plan was built from. The buffer therefore drops every
plan when a cache is created or replaced, a static transform is inserted or the buffer
is cleared; a parent mismatch or a missing sample makes the caller fall back to the
general walk, which also produces tf2's errors.

Plans are built from the newest parents of each link. The caller holds the buffer lock.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Callable
from math import sin

from visnav.tf import _scalar
from visnav.tf._cache import FrameCache, Sample, Span
from visnav.tf._scalar import Pose7, compose
from visnav.tf._tree import MAX_GRAPH_DEPTH

__all__ = [
    "DOWNWARD",
    "GENERAL",
    "UPWARD",
    "Plan",
    "SideFn",
    "Step",
    "build_plan",
    "latest_time",
    "make_side",
    "reference_side",
    "run_plan",
    "side",
]

Step = tuple[list[int], list[Sample], list[Span | None], str, Pose7]
"""``(stamps, samples, spans, expected parent, pose)``: a dynamic link's cache lists
(the FrameCache mutates them in place, so they stay current; never empty) and
``IDENTITY``; or three empty lists and the composed pose of a run of static links."""

Caches = dict[str, FrameCache]

UPWARD = 0
"""Plan kind: the target is an ancestor of the source (only ``source_steps``)."""
DOWNWARD = 1
"""Plan kind: the source is the root above the target (the inverse of ``target_steps``)."""
GENERAL = 2
"""Plan kind: both sides up to a common ancestor (:func:`run_plan`)."""


class Plan:
    """The links between two frames, from each frame up to their common ancestor.

    Attributes:
        source_steps: links from the source frame upwards, in walking order.
        target_steps: links from the target frame upwards (empty when the target is an
            ancestor of the source).
        dynamic: every dynamic step of both sides (for the latest common time).
        ancestor_cache: the common ancestor's own cache when it has a parent and the
            target is not on the source's path (None otherwise): the general walk
            then also walks above the ancestor, which only matters in a tree with a
            loop at the lookup time; :func:`run_plan` checks that it has none.
        guard: the frames of both paths (a walk above the ancestor reaching one of
            them means a loop).
        kind: :data:`UPWARD`, :data:`DOWNWARD` or :data:`GENERAL` (which of the above
            the lookup needs).
    """

    __slots__ = ("ancestor_cache", "dynamic", "guard", "kind", "source_steps", "target_steps")

    def __init__(
        self,
        source_steps: list[tuple[FrameCache | None, Step]],
        target_steps: list[tuple[FrameCache | None, Step]],
        *,
        ancestor_cache: FrameCache | None = None,
        guard: frozenset[str] = frozenset(),
    ) -> None:
        self.source_steps = tuple(step for _, step in source_steps)
        self.target_steps = tuple(step for _, step in target_steps)
        self.dynamic = tuple(
            (cache, step[3]) for cache, step in (*source_steps, *target_steps) if cache is not None
        )
        self.ancestor_cache = ancestor_cache if target_steps else None
        self.guard = guard
        if not target_steps:
            self.kind = UPWARD
        elif not source_steps and self.ancestor_cache is None:
            self.kind = DOWNWARD
        else:
            self.kind = GENERAL


def _path(caches: Caches, frame: str, stop: str | None) -> list[tuple[str, FrameCache]] | None:
    """``[(child, cache), ...]`` from ``frame`` up to ``stop`` or a root; None on a loop."""
    out: list[tuple[str, FrameCache]] = []
    seen = {frame}
    cache = caches.get(frame)
    while cache is not None and frame != stop:
        out.append((frame, cache))
        frame = cache.parent
        if frame in seen or len(out) > MAX_GRAPH_DEPTH:
            return None
        seen.add(frame)
        cache = caches.get(frame)
    return out


def _steps(links: list[tuple[str, FrameCache]]) -> list[tuple[FrameCache | None, Step]]:
    """Merge runs of static links into one step each (poses composed once)."""
    steps: list[tuple[FrameCache | None, Step]] = []
    run: Pose7 | None = None
    run_parent = ""
    for _, cache in links:
        if cache.is_static:
            parent, pose = cache.samples[-1]
            run = pose if run is None else _scalar.compose(pose, run)
            run_parent = parent
            continue
        if run is not None:
            steps.append((None, ([], [], [], run_parent, run)))
            run = None
        steps.append(
            (cache, (cache.stamps, cache.samples, cache.spans, cache.parent, _scalar.IDENTITY))
        )
    if run is not None:
        steps.append((None, ([], [], [], run_parent, run)))
    return steps


def build_plan(caches: Caches, target: str, source: str) -> Plan | None:
    """Return the plan between two distinct known frames by their newest parents.

    Returns:
        The plan, or None when the frames are not connected (or the tree has a loop):
        the general walk then raises the right error.
    """
    up = _path(caches, source, target)
    if up is None:
        return None
    top = up[-1][1].parent if up else source
    if top == target:
        return Plan(_steps(up), [])
    index = {source: 0}
    for k, (_, link) in enumerate(up, start=1):
        index[link.parent] = k
    down: list[tuple[str, FrameCache]] = []
    frame = target
    while frame not in index:
        cache = caches.get(frame)
        if cache is None or len(down) > MAX_GRAPH_DEPTH:
            return None
        down.append((frame, cache))
        frame = cache.parent
    below = up[: index[frame]]
    guard = frozenset([frame, *(f for f, _ in below), *(f for f, _ in down)])
    return Plan(_steps(below), _steps(down), ancestor_cache=caches.get(frame), guard=guard)


def _no_loop_above(plan: Plan, caches: Caches, t: int) -> bool:
    """Whether the walk above the common ancestor at ``t`` (0: newest) avoids both paths.

    The general walk goes on from the ancestor towards the root; meeting a frame of
    either path there means the tree has a loop at ``t`` and the general walk may
    answer differently (or raise): the caller then falls back to it.
    """
    cache = plan.ancestor_cache
    if cache is None:
        return True
    guard = plan.guard
    above: set[str] = set()
    while cache is not None:
        sample = cache.get(t)
        if sample is None:
            return True
        frame = sample[0]
        if frame in guard or frame in above or len(above) > MAX_GRAPH_DEPTH:
            return False
        above.add(frame)
        cache = caches.get(frame)
    return True


def latest_time(plan: Plan, caches: Caches) -> int | None:
    """tf2's latest common time over the plan's links, or None if a newest parent moved.

    The minimum of the dynamic links' newest stamps (0 for an all-static chain).
    """
    if plan.ancestor_cache is not None and not _no_loop_above(plan, caches, 0):
        return None
    common = 0
    for cache, parent in plan.dynamic:
        samples = cache.samples
        if samples[-1][0] != parent:
            return None
        stamp = cache.stamps[-1]
        if common == 0 or stamp < common:
            common = stamp
    return common


SideFn = Callable[[tuple[Step, ...], int], "Pose7 | None"]


def make_side(
    interpolate: Callable[[Pose7, Pose7, float], Pose7],
    interpolate_compose: Callable[[Pose7, Pose7, float, Pose7], Pose7],
    compose: Callable[[Pose7, Pose7], Pose7],
) -> SideFn:
    """Return :func:`side` using the given arithmetic (interpreted or numba-compiled)."""

    def side(steps: tuple[Step, ...], t: int) -> Pose7 | None:
        """Compose one side's links at ``t``; None when a link has no sample or moved parent.

        ``FrameCache.get`` is inlined here (this is the hot loop of every lookup): between
        two samples of the expected parent the pose is interpolated (and composed in the
        same call); between samples of different parents the older one is used (tf2).
        """
        acc: Pose7 | None = None
        for stamps, samples, _, parent, pose in steps:
            if stamps:
                i = bisect_left(stamps, t)
                if 0 < i < len(stamps) and stamps[i] != t:
                    older = samples[i - 1]
                    if older[0] != parent:
                        return None
                    newer = samples[i]
                    if newer[0] == parent:
                        t0 = stamps[i - 1]
                        ratio = (t - t0) / (stamps[i] - t0)
                        if acc is None:
                            acc = interpolate(older[1], newer[1], ratio)
                        else:
                            acc = interpolate_compose(older[1], newer[1], ratio, acc)
                        continue
                    pose = older[1]  # noqa: PLW2901 - hot loop: no extra local
                else:
                    if i == len(stamps) or stamps[i] != t:
                        return None
                    sample = samples[i]
                    if sample[0] != parent:
                        return None
                    pose = sample[1]  # noqa: PLW2901
            acc = pose if acc is None else compose(pose, acc)
        return acc if acc is not None else _scalar.IDENTITY

    return side


def side(steps: tuple[Step, ...], t: int) -> Pose7 | None:
    """Compose one side's links at ``t``: the interpreted default of :func:`make_side`'s.

    The same answer (to rounding) with all the arithmetic written out here: the
    accumulated pose lives in seven locals (no tuple per link, no calls), and each
    interval's slerp constants come from the cache's :data:`~visnav.tf._cache.Span`
    (computed on insertion), which leaves two ``sin`` calls per interpolated link.
    None when a link has no sample at ``t`` or its parent there is not the expected one.
    """
    have = False
    tx = ty = tz = bx = by = bz = 0.0
    bw = 1.0
    for stamps, samples, spans, parent, pose in steps:
        if stamps:  # a dynamic link (a static run has no stamps)
            i = bisect_left(stamps, t)
            if 0 < i < len(stamps) and stamps[i] != t:
                span = spans[i]
                if span is not None:  # both samples have one parent: interpolate
                    (p, t0, inv_dt, atx, aty, atz, x0, y0, z0, w0,
                     btx, bty, btz, x1, y1, z1, w1, theta, inv_sin) = span  # fmt: skip
                    if p != parent:
                        return None
                    ratio = (t - t0) * inv_dt
                    r0 = 1.0 - ratio
                    if theta:
                        s0 = sin(r0 * theta) * inv_sin
                        s1 = sin(ratio * theta) * inv_sin
                    else:
                        s0 = r0
                        s1 = ratio
                    ax = s0 * x0 + s1 * x1
                    ay = s0 * y0 + s1 * y1
                    az = s0 * z0 + s1 * z1
                    aw = s0 * w0 + s1 * w1
                    if have:
                        cx = 2.0 * (ay * tz - az * ty)
                        cy = 2.0 * (az * tx - ax * tz)
                        cz = 2.0 * (ax * ty - ay * tx)
                        tx, ty, tz, bx, by, bz, bw = (
                            tx + aw * cx + ay * cz - az * cy + r0 * atx + ratio * btx,
                            ty + aw * cy + az * cx - ax * cz + r0 * aty + ratio * bty,
                            tz + aw * cz + ax * cy - ay * cx + r0 * atz + ratio * btz,
                            aw * bx + ax * bw + ay * bz - az * by,
                            aw * by - ax * bz + ay * bw + az * bx,
                            aw * bz + ax * by - ay * bx + az * bw,
                            aw * bw - ax * bx - ay * by - az * bz,
                        )
                    else:
                        tx = r0 * atx + ratio * btx
                        ty = r0 * aty + ratio * bty
                        tz = r0 * atz + ratio * btz
                        bx, by, bz, bw = ax, ay, az, aw
                        have = True
                    continue
                older = samples[i - 1]  # parents differ: the older sample, unchanged (tf2)
                if older[0] != parent:
                    return None
                pose = older[1]  # noqa: PLW2901
            else:
                if i == len(stamps) or stamps[i] != t:
                    return None
                sample = samples[i]
                if sample[0] != parent:
                    return None
                pose = sample[1]  # noqa: PLW2901
        if have:
            atx, aty, atz, ax, ay, az, aw = pose
            cx = 2.0 * (ay * tz - az * ty)
            cy = 2.0 * (az * tx - ax * tz)
            cz = 2.0 * (ax * ty - ay * tx)
            tx, ty, tz, bx, by, bz, bw = (
                tx + aw * cx + ay * cz - az * cy + atx,
                ty + aw * cy + az * cx - ax * cz + aty,
                tz + aw * cz + ax * cy - ay * cx + atz,
                aw * bx + ax * bw + ay * bz - az * by,
                aw * by - ax * bz + ay * bw + az * bx,
                aw * bz + ax * by - ay * bx + az * bw,
                aw * bw - ax * bx - ay * by - az * bz,
            )
        else:
            tx, ty, tz, bx, by, bz, bw = pose
            have = True
    return (tx, ty, tz, bx, by, bz, bw)


reference_side: SideFn = make_side(
    _scalar.interpolate, _scalar.interpolate_compose, _scalar.compose
)
"""The same as :func:`side` through the ``_scalar`` functions (the tests' reference)."""


def run_plan(plan: Plan, t: int, caches: Caches, side: SideFn = side) -> Pose7 | None:
    """Return ``T_target_source`` at ``t`` (nonzero) by the plan, or None to fall back.

    None means a link has no sample at ``t`` or its parent at ``t`` is not the one the
    plan expects: the general walk then answers (or raises tf2's error).
    """
    if not plan.target_steps:
        return side(plan.source_steps, t)
    if plan.ancestor_cache is not None and not _no_loop_above(plan, caches, t):
        return None
    target_side = side(plan.target_steps, t)
    if target_side is None:
        return None
    if not plan.source_steps:
        return _scalar.inverse(target_side)
    source_side = side(plan.source_steps, t)
    if source_side is None:
        return None
    return compose(_scalar.inverse(target_side), source_side)
