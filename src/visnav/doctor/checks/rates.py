"""Rate checks: silent topics, measured vs declared rate, jitter, gaps, intermittent streams.

Rates are measured in ROS time: on header stamps when the topic has sane stamps,
otherwise on arrival times mapped through ``/clock`` (so a simulator running slower
than real time still shows its sensors' declared rates). A *gap* is a period longer
than ``max(5 x median period, median + 0.2 s)``.

Only *periodic* topics are judged on their timing: those with a declared rate and those
of the types sensors and state publishers stream (images, camera_info, scans, clouds,
IMU, odometry, joint states, ``/gazebo/model_states``, ...). Other topics (goals, paths,
plans, markers, maps) are *event* topics: they publish when something happens, so an
uneven period or a pause is their normal life, and silence is reported as information
only. Jitter measured on arrival times is judged only for periods of 5 ms and more:
below that, arrival times show how the transport batches messages, not when the
publisher sent them (the simulator's per-step ``/gazebo/model_states`` at 1 kHz).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from visnav.doctor.context import CheckContext
from visnav.doctor.findings import Finding, Severity
from visnav.doctor.observation import TopicData

__all__ = [
    "PERIODIC_TYPES",
    "StreamStats",
    "check_no_messages",
    "check_rates",
    "is_periodic",
    "stream_stats",
]

_SKIP = frozenset({"/clock", "/tf", "/tf_static", "/rosout", "/parameter_events"})
_MIN_MESSAGES = 5
_MIN_ARRIVAL_JITTER_PERIOD_S = 0.005
PERIODIC_TYPES = frozenset(
    {
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/CompressedImage",
        "sensor_msgs/msg/CameraInfo",
        "sensor_msgs/msg/LaserScan",
        "sensor_msgs/msg/MultiEchoLaserScan",
        "sensor_msgs/msg/PointCloud2",
        "sensor_msgs/msg/PointCloud",
        "sensor_msgs/msg/Imu",
        "sensor_msgs/msg/Range",
        "sensor_msgs/msg/JointState",
        "sensor_msgs/msg/MagneticField",
        "sensor_msgs/msg/NavSatFix",
        "sensor_msgs/msg/FluidPressure",
        "sensor_msgs/msg/Temperature",
        "nav_msgs/msg/Odometry",
        "rosgraph_msgs/msg/Clock",
        "tf2_msgs/msg/TFMessage",
        "gazebo_msgs/msg/ModelStates",
        "gazebo_msgs/msg/LinkStates",
    }
)
"""Types that sensors and state publishers stream at a rate."""


@dataclass(frozen=True)
class StreamStats:
    """Timing of one topic's stream.

    Attributes:
        domain: ``"stamps"`` or ``"arrival"`` (arrival mapped to ROS time).
        count: messages.
        rate_hz: mean rate over periods that are not gaps.
        median_period_s: median period.
        cv: coefficient of variation of the periods that are not gaps, a period that is
            a whole multiple of the median counted as that many (lost messages).
        gaps: ``(start s from first message, length s)`` of every gap.
        span_s: first to last message.
    """

    domain: str
    count: int
    rate_hz: float
    median_period_s: float
    cv: float
    gaps: tuple[tuple[float, float], ...]
    span_s: float


def _series(ctx: CheckContext, topic: TopicData) -> tuple[str, NDArray[np.int64]]:
    ref = ctx.reference_ns(topic)
    stamps = topic.stamp_ns
    valid = stamps > 0
    if topic.has_stamps and float(valid.mean()) >= 0.9:
        offset = np.median((stamps[valid] - ref[valid]).astype(np.float64)) / 1e9
        if abs(offset) < 10.0:
            return "stamps", np.sort(stamps[valid])
    return "arrival", np.sort(ref)


def _grid_cv(periods: NDArray[np.float64], median: float) -> float:
    """std / mean of the periods, a lost message's double (triple, ...) period as that many.

    Messages a subscriber dropped are not the publisher's jitter (a 1 kHz IMU read by a
    busy observer).
    """
    if periods.size < 2 or median <= 0:
        return 0.0
    ratio = periods / median
    k = np.rint(ratio)
    lost = (k >= 2) & (np.abs(ratio - k) <= 0.1)
    grid = np.where(lost, periods / np.maximum(k, 1.0), periods)
    mean = float(grid.mean())
    return float(grid.std() / mean) if mean > 0 else 0.0


def stream_stats(ctx: CheckContext, topic: TopicData) -> StreamStats | None:
    """Timing statistics of a topic (None with fewer than 5 messages or no time span)."""
    if topic.count < _MIN_MESSAGES:
        return None
    domain, t = _series(ctx, topic)
    periods = np.diff(t).astype(np.float64) / 1e9
    periods = periods[periods > 0]
    if periods.size < _MIN_MESSAGES - 1:
        return None
    med = float(np.median(periods))
    limit = max(5.0 * med, med + 0.2)
    is_gap = periods > limit
    normal = periods[~is_gap]
    rate = normal.size / float(normal.sum()) if normal.size and normal.sum() > 0 else 0.0
    cv = _grid_cv(normal, med)
    starts = (np.cumsum(periods) - periods)[is_gap]
    gaps = tuple((float(s), float(g)) for s, g in zip(starts, periods[is_gap], strict=True))
    return StreamStats(
        domain=domain,
        count=topic.count,
        rate_hz=rate,
        median_period_s=med,
        cv=cv,
        gaps=gaps,
        span_s=float(t[-1] - t[0]) / 1e9,
    )


def is_periodic(ctx: CheckContext, name: str, type_name: str | None) -> bool:
    """True for a topic judged on its timing: a declared rate or a streamed type."""
    if _declared_rate(ctx, name) is not None:
        return True
    return type_name in PERIODIC_TYPES


def _type_of(ctx: CheckContext, name: str) -> str | None:
    data = ctx.obs.topics.get(name)
    if data is not None:
        return data.type_name
    exp = ctx.expected(name)
    if exp is not None and exp.type is not None:
        return exp.type
    return next((e.type_name for e in ctx.endpoints(name)), None)


def check_no_messages(
    ctx: CheckContext, *, skip: frozenset[str] = frozenset()
) -> Iterator[Finding]:
    """``rates.no_messages``: a topic with a publisher (or in the bag, or expected) is silent.

    Args:
        ctx: the check context.
        skip: topics another check reports (planner inputs).
    """
    for name in sorted(ctx.all_topic_names() - skip):
        data = ctx.obs.topics.get(name)
        if data is not None and data.count > 0:
            continue
        if name in ctx.obs.undecodable:
            continue
        pubs = ctx.endpoints(name, "publisher")
        if ctx.has_graph and not pubs:
            continue
        subs = ctx.endpoints(name, "subscription")
        exp = ctx.expected(name)
        event = not is_periodic(ctx, name, _type_of(ctx, name))
        if exp is not None and not exp.optional:
            severity = Severity.ERROR
        elif subs and not event:
            severity = Severity.WARNING
        else:
            severity = Severity.INFO
        yield Finding(
            severity,
            "rates.no_messages",
            f"{name} delivered no message in {ctx.obs.duration_s:.1f} s",
            {
                "topic": name,
                "observed_s": round(ctx.obs.duration_s, 3),
                "publishers": sorted({e.node_fqn for e in pubs}),
                "subscribers": sorted({e.node_fqn for e in subs}),
            },
            (
                "nothing to fix if no such event happened while observing (an event topic: "
                "goals, paths, plans, markers)"
                if event and severity is Severity.INFO
                else "check that the publishing node is running and producing data (its "
                "inputs, its trigger); observe longer with --duration if the topic is slow"
            ),
            name,
        )


def _declared_rate(ctx: CheckContext, name: str) -> tuple[float, float, str] | None:
    exp = ctx.expected(name)
    decl = ctx.declared.get(name)
    if decl is None or decl.rate is None:
        return None
    tol = exp.rate_tolerance if exp is not None else 0.15
    return decl.rate, tol, decl.source


def check_rates(ctx: CheckContext) -> Iterator[Finding]:
    """``rates.mismatch``, ``.jitter``, ``.gap``, ``.intermittent`` and ``.stopped``."""
    for topic in ctx.obs.topics.values():
        if topic.name in _SKIP or topic.latched or topic.count < _MIN_MESSAGES:
            continue
        if not is_periodic(ctx, topic.name, topic.type_name):
            continue
        stats = stream_stats(ctx, topic)
        if stats is None:
            continue
        yield from _rate_findings(ctx, topic, stats)


def _rate_findings(ctx: CheckContext, topic: TopicData, s: StreamStats) -> Iterator[Finding]:
    name = topic.name
    base = {"topic": name, "measured_on": s.domain, "messages": s.count}
    declared = _declared_rate(ctx, name)
    if declared is not None and s.rate_hz > 0:
        rate, tol, source = declared
        rel = s.rate_hz / rate - 1.0
        if abs(rel) > tol:
            far_off = s.rate_hz < 0.5 * rate or s.rate_hz > 2 * rate
            severity = Severity.ERROR if far_off else Severity.WARNING
            yield Finding(
                severity,
                "rates.mismatch",
                f"{name} runs at {s.rate_hz:.3g} Hz, declared {rate:.3g} Hz",
                {
                    **base,
                    "measured_hz": round(s.rate_hz, 3),
                    "declared_hz": rate,
                    "tolerance": tol,
                    "declared_by": source,
                },
                "find what throttles the publisher (CPU, a slow input, a timer period) or "
                "correct the declared rate",
                name,
            )
    judge_jitter = s.domain == "stamps" or s.median_period_s >= _MIN_ARRIVAL_JITTER_PERIOD_S
    if s.count >= 10 and s.cv > 0.5 and judge_jitter:
        yield Finding(
            Severity.WARNING,
            "rates.jitter",
            f"{name} period varies by {s.cv:.0%} (std / mean)",
            {
                **base,
                "median_period_s": round(s.median_period_s, 6),
                "period_cv": round(s.cv, 3),
                "rate_hz": round(s.rate_hz, 3),
            },
            "publish from a steady timer, stamp at acquisition time, and keep slow work "
            "out of the publishing callback",
            name,
        )
    # arrival times of a fast stream show delivery batching, not the publisher's pauses
    gaps = s.gaps if judge_jitter else ()
    total_gap = sum(g for _, g in gaps)
    if len(gaps) >= 3 or (gaps and total_gap > 0.3 * s.span_s):
        yield Finding(
            Severity.WARNING,
            "rates.intermittent",
            f"{name} stopped {len(gaps)} times ({total_gap:.2f} s of {s.span_s:.2f} s)",
            {
                **base,
                "gaps": len(gaps),
                "gap_total_s": round(total_gap, 3),
                "span_s": round(s.span_s, 3),
                "longest_gap_s": round(max(g for _, g in gaps), 3),
                "median_period_s": round(s.median_period_s, 6),
            },
            "the publisher stalls repeatedly: check its inputs, its CPU load and the network "
            "(best-effort QoS drops bursts); look at the node's log",
            name,
        )
    elif gaps:
        start, length = max(gaps, key=lambda g: g[1])
        yield Finding(
            Severity.WARNING,
            "rates.gap",
            f"{name} paused for {length:.2f} s ({length / s.median_period_s:.0f} periods)",
            {
                **base,
                "gaps": len(gaps),
                "longest_gap_s": round(length, 3),
                "gap_starts_at_s": round(start, 3),
                "median_period_s": round(s.median_period_s, 6),
            },
            "find what blocked the publisher at that time (a long callback, a full queue, "
            "a reconnect)",
            name,
        )
    ref = ctx.reference_ns(topic)
    end = ctx.end_clock_ns
    silent_s = (end - int(ref.max())) / 1e9
    if silent_s > max(1.0, 10 * s.median_period_s):
        yield Finding(
            Severity.WARNING,
            "rates.stopped",
            f"{name} stopped {silent_s:.2f} s before the end of the observation",
            {
                **base,
                "silent_for_s": round(silent_s, 3),
                "median_period_s": round(s.median_period_s, 6),
            },
            "the publisher died or lost its input: check that the node is alive "
            "(visnav node list) and its log",
            name,
        )
