"""The lookup fast path (cached chains, visnav.tf._plan) answers exactly as the general walk.

Random trees with dynamic and static links, re-parented frames, static replacements
and clears; every lookup is made twice (the second through the cached chain) and
compared with tf2's walk run directly on the buffer's caches (including the errors).
"""

from __future__ import annotations

import math
import random
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.msgs import Header, Quaternion, Time, Transform, TransformStamped, Vector3
from visnav.tf import Buffer, TransformException

S = 1_000_000_000
FRAMES = ["map", "odom", "base", "cam", "opt", "arm", "tool"]


def tf(parent: str, child: str, stamp_ns: int, rng: random.Random) -> TransformStamped:
    q = [rng.gauss(0, 1) for _ in range(4)]
    n = math.sqrt(sum(v * v for v in q))
    return TransformStamped(
        Header(Time(*divmod(stamp_ns, S)), parent),
        child,
        Transform(
            Vector3(rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-2, 2)),
            Quaternion(*[v / n for v in q]),
        ),
    )


def reference(buf: Buffer, target: str, source: str, t: int) -> object:
    """The general walk's answer (pose tuple, resolved time) or its exception type and text."""
    try:
        if target == source:
            buf.lookup_transform(target, source, t)
            return "identity"
        with buf._lock:
            return buf._lookup_walk(target, source, t)
    except TransformException as exc:
        return type(exc), str(exc)


def fast(buf: Buffer, target: str, source: str, t: int) -> object:
    try:
        if target == source:
            buf.lookup_transform(target, source, t)
            return "identity"
        with buf._lock:
            return buf._lookup(target, source, t)
    except TransformException as exc:
        return type(exc), str(exc)


def same(a: object, b: object) -> bool:
    if isinstance(a, tuple) and isinstance(a[0], tuple) and isinstance(b, tuple):
        (pa, ta), (pb, tb) = a, b
        return ta == tb and all(abs(x - y) < 1e-9 for x, y in zip(pa, pb, strict=True))
    return a == b


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_cached_chains_equal_the_general_walk(seed: int) -> None:
    rng = random.Random(seed)
    buf = Buffer(cache_time=5.0)
    known = [f for f in FRAMES if f in ("map", "odom")]
    for step in range(rng.randint(5, 40)):
        action = rng.random()
        child = rng.choice(FRAMES[1:])
        parents = [f for f in FRAMES if f != child]
        parent = rng.choice(parents[: rng.randint(1, len(parents))])
        stamp = rng.randint(1, 12) * S // 2
        if action < 0.55:
            buf.set_transform(tf(parent, child, stamp, rng), "t")
        elif action < 0.75:
            buf.set_transform_static(tf(parent, child, 0, rng), "t")
        elif action < 0.8:
            buf.clear()
        known = buf.get_frames() or known
        for _ in range(3):
            target, source = rng.choice(known), rng.choice(known)
            t = rng.choice([0, rng.randint(0, 13) * S // 3, stamp])
            want = reference(buf, target, source, t)
            first = fast(buf, target, source, t)
            second = fast(buf, target, source, t)  # through the cached chain if any
            assert same(first, want), (step, target, source, t)
            assert same(second, want), (step, target, source, t)


def test_a_reparented_frame_is_not_served_from_a_stale_chain() -> None:
    rng = random.Random(3)
    buf = Buffer()
    buf.set_transform(tf("map", "base", 1 * S, rng), "t")
    buf.set_transform(tf("map", "base", 2 * S, rng), "t")
    buf.set_transform_static(tf("odom", "x", 0, rng), "t")
    buf.lookup_transform("map", "base", int(1.5 * S))  # caches the chain map <- base
    buf.set_transform(tf("odom", "base", 3 * S, rng), "t")  # base moves under odom
    buf.set_transform(tf("odom", "base", 4 * S, rng), "t")
    with pytest.raises(TransformException):
        buf.lookup_transform("map", "base", int(3.5 * S))
    assert buf.can_transform("map", "base", int(1.5 * S))
    assert buf.can_transform("odom", "base", int(3.5 * S))


@pytest.fixture(scope="module")
def kernels() -> tuple[Any, Any, Any]:
    from visnav.tf._scalar import jit_kernels

    return jit_kernels()


@pytest.mark.slow
@pytest.mark.ci
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_jit_buffer_equals_the_interpreted_one(kernels: tuple[Any, Any, Any], seed: int) -> None:
    del kernels  # compiled once for the module; Buffer(jit=True) then loads them
    rng = random.Random(seed)
    plain, fast = Buffer(), Buffer(jit=True)
    for k in range(30):
        msg = tf(rng.choice(["map", "odom"]), rng.choice(["base", "cam"]), k * S // 10, rng)
        if msg.header.frame_id != msg.child_frame_id:
            plain.set_transform(msg, "t")
            fast.set_transform(msg, "t")
    for _ in range(20):
        target, source = rng.choice(FRAMES[:4]), rng.choice(FRAMES[:4])
        t = rng.choice([0, rng.randint(0, 30) * S // 10 + rng.randint(0, S // 10)])
        if not plain.can_transform(target, source, t):
            assert not fast.can_transform(target, source, t)
            continue
        for _ in range(2):  # the second lookup goes through the cached chain
            a = plain.lookup_transform(target, source, t).transform
            b = fast.lookup_transform(target, source, t).transform
            va = [a.translation.x, a.translation.y, a.translation.z, a.rotation.w]
            vb = [b.translation.x, b.translation.y, b.translation.z, b.rotation.w]
            assert all(abs(x - y) < 1e-12 for x, y in zip(va, vb, strict=True))


@pytest.mark.slow
@pytest.mark.ci
def test_compiled_kernels_equal_the_python_ones(kernels: tuple[Any, Any, Any]) -> None:
    from visnav.tf import _scalar

    interpolate, interpolate_compose, compose = kernels
    rng = random.Random(5)
    for _ in range(200):
        poses = []
        for _ in range(3):
            m = tf("p", "c", 0, rng).transform
            t, q = m.translation, m.rotation
            poses.append((t.x, t.y, t.z, q.x, q.y, q.z, q.w))
        a, b, c = poses
        r = rng.random()
        for got, want in (
            (interpolate(a, b, r), _scalar.interpolate_py(a, b, r)),
            (interpolate_compose(a, b, r, c), _scalar.interpolate_compose_py(a, b, r, c)),
            (compose(a, b), _scalar.compose_py(a, b)),
        ):
            assert all(abs(x - y) < 1e-13 for x, y in zip(got, want, strict=True))


@settings(max_examples=80, deadline=None)
@given(
    stamps=st.lists(st.integers(1, 40), min_size=1, max_size=40),
    parents=st.lists(st.sampled_from(["odom", "map"]), min_size=40, max_size=40),
)
def test_interval_spans_follow_every_insertion(stamps: list[int], parents: list[str]) -> None:
    """Out-of-order, replacing and window-dropping inserts keep each span its interval's."""
    from visnav.tf._cache import FrameCache, span

    rng = random.Random(len(stamps))
    cache = FrameCache(is_static=False, cache_time_ns=10 * S // 4)
    for k, stamp in enumerate(stamps):
        m = tf(parents[k], "base", 0, rng).transform
        t, q = m.translation, m.rotation
        cache.insert(stamp * S // 4, parents[k], (t.x, t.y, t.z, q.x, q.y, q.z, q.w))
        assert len(cache.spans) == len(cache.stamps) == len(cache.samples)
        assert cache.spans[0] is None
        for i in range(1, len(cache.stamps)):
            stamps, samples = cache.stamps, cache.samples
            want = span(stamps[i - 1], samples[i - 1], stamps[i], samples[i])
            assert cache.spans[i] == want


@pytest.mark.parametrize("angle", [0.0, 1e-9, 3e-8, 1e-5, 0.2, 3.0, math.pi])
def test_fused_chain_equals_the_scalar_functions(angle: float) -> None:
    """The default (fused) chain loop against the ``_scalar`` functions, tiny arcs included."""
    from visnav.tf._plan import reference_side, side

    buf = Buffer()
    for k in range(4):
        a = 0.3 + angle * (k % 2)  # alternate: the arc between samples is ``angle``
        quat = Quaternion(0.0, math.sin(a / 2), 0.0, math.cos(a / 2))
        buf.set_transform(
            TransformStamped(
                Header(Time(k, 0), "odom"), "base", Transform(Vector3(k, 0.5 * k, 0.0), quat)
            ),
            "t",
        )
        buf.set_transform(
            TransformStamped(
                Header(Time(k, 0), "map"), "odom", Transform(Vector3(0.1 * k, 0.0, 1.0), quat)
            ),
            "t",
        )
    buf.set_transform_static(
        TransformStamped(
            Header(Time(0, 0), "base"),
            "cam",
            Transform(Vector3(0.1, 0.0, 0.5), Quaternion(-0.5, 0.5, -0.5, 0.5)),
        ),
        "t",
    )
    buf.lookup_transform("map", "cam", S // 2)  # builds the chain
    plan = buf._plans["map", "cam"]
    for t in (S // 3, S, 3 * S // 2, 2 * S + 1, 3 * S - 1, 3 * S):
        got = side(plan.source_steps, t)
        want = reference_side(plan.source_steps, t)
        assert got is not None
        assert want is not None
        assert all(abs(x - y) < 1e-13 for x, y in zip(got, want, strict=True)), t
