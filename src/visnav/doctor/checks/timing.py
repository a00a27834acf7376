"""Time checks: sim time without /clock, wall-clock stamps under /clock, zero, offset, backwards.

Stamps are compared with the ROS time at each message's arrival (``/clock`` when
published, else the observer's clock). Sim time is recognised by its value: a
``/clock`` below 1e9 s (before 2001) is a simulation's, header stamps above it are
wall-clock (Unix) time.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterator

import numpy as np

from visnav.doctor.context import CheckContext
from visnav.doctor.findings import Finding, Severity
from visnav.doctor.observation import NO_STAMP, TopicData

__all__ = ["WALL_TIME_NS", "check_sim_time", "check_stamps"]

WALL_TIME_NS = 1_000_000_000 * 1_000_000_000
"""Stamps above 1e9 s (September 2001) are wall-clock time; a sim clock stays below."""

_SKIP = frozenset({"/clock", "/tf_static", "/rosout", "/parameter_events"})
_TF = "tf2_msgs/msg/TFMessage"
_ZERO_OK_NS = 500_000_000


def check_sim_time(ctx: CheckContext) -> Iterator[Finding]:
    """``time.sim_time_no_clock`` (and ``time.backwards`` of /clock)."""
    clock = ctx.obs.topics.get("/clock")
    has_clock_msgs = clock is not None and clock.count > 0
    subs = ctx.endpoints("/clock", "subscription")
    pubs = ctx.endpoints("/clock", "publisher")
    wants = ctx.expect is not None and ctx.expect.use_sim_time is True
    if (subs or wants) and not has_clock_msgs:
        nodes = sorted({e.node_fqn for e in subs})
        yield Finding(
            Severity.ERROR,
            "time.sim_time_no_clock",
            "nodes use sim time but no /clock is "
            + ("published" if not pubs else "arriving")
            + (f" ({len(nodes)} node(s) wait on /clock)" if nodes else ""),
            {
                "clock_subscribers": nodes,
                "clock_publishers": sorted({e.node_fqn for e in pubs}),
                "clock_messages": 0 if clock is None else clock.count,
                **({"expected_by": ctx.expect.source} if wants and ctx.expect else {}),
            },
            "start the simulator (visnav sim) or play the bag with --clock; otherwise set "
            "use_sim_time:=false on these nodes: without /clock their time stays at 0, "
            "timers never fire and TF lookups fail",
            "/clock",
        )
    if has_clock_msgs and clock is not None:
        values = ctx.obs.clock_ns[np.argsort(ctx.obs.clock_receive_ns, kind="stable")]
        back = np.diff(values) < 0
        if back.any():
            jumps = np.diff(values)[back]
            yield Finding(
                Severity.WARNING,
                "time.backwards",
                f"/clock jumped backwards {int(back.sum())} time(s)",
                {
                    "topic": "/clock",
                    "backward_jumps": int(back.sum()),
                    "largest_jump_back_s": round(float(-jumps.min()) / 1e9, 6),
                },
                "a simulation reset or a looping bag (bag play --loop): nodes must clear TF "
                "buffers and caches on a time jump; avoid looping while consumers run",
                "/clock",
            )


def _groups(topic: TopicData) -> dict[str, np.ndarray]:
    """Per publisher (live) or frame_id (bag), the stamps in arrival order."""
    keys = topic.publishers if any(topic.publishers) else topic.frame_ids
    order = np.argsort(topic.receive_ns, kind="stable")
    idx: dict[str, list[int]] = defaultdict(list)
    for i in order.tolist():
        idx[keys[i]].append(i)
    return {k: topic.stamp_ns[v] for k, v in idx.items()}


def check_stamps(ctx: CheckContext) -> Iterator[Finding]:
    """``time.wall_stamps``, ``time.zero_stamp``, ``time.stamp_offset``, ``time.backwards``."""
    sim = ctx.uses_sim_clock and ctx.clock.last_ns < WALL_TIME_NS
    for topic in ctx.obs.topics.values():
        if topic.name in _SKIP or not topic.count or not bool((topic.stamp_ns != NO_STAMP).any()):
            continue
        stamps = topic.stamp_ns
        has = stamps != NO_STAMP
        # A zero stamp is right at time zero (a simulation's first step): only flag it later.
        zero = has & (stamps == 0) & (ctx.reference_ns(topic) > _ZERO_OK_NS)
        name = topic.name
        is_tf = topic.type_name == _TF
        if zero.any():
            frac = float(zero.sum()) / float(has.sum())
            yield Finding(
                Severity.ERROR if frac >= 0.5 else Severity.WARNING,
                "time.zero_stamp",
                f"{name}: {frac:.0%} of header stamps are zero",
                {"topic": name, "zero_stamps": int(zero.sum()), "messages": int(has.sum())},
                "stamp each message with the acquisition time (node.get_clock().now() or the "
                "sensor's time); time 0 means 'latest' to tf2 and breaks synchronisers",
                name,
            )
        good = has & (stamps > 0)
        if not good.any():
            continue
        ref = ctx.reference_ns(topic)[good]
        st = stamps[good]
        offsets = (st - ref).astype(np.float64) / 1e9
        med = float(np.median(offsets))
        med_stamp = float(np.median(st)) / 1e9
        wall = sim and med_stamp * 1e9 >= WALL_TIME_NS
        if wall:
            yield Finding(
                Severity.ERROR,
                "time.wall_stamps",
                f"{name} is stamped with wall time ({med_stamp:.3f} s) while /clock runs sim "
                f"time ({ctx.clock.last_ns / 1e9:.3f} s)",
                {
                    "topic": name,
                    "median_stamp_s": round(med_stamp, 3),
                    "clock_s": round(ctx.clock.last_ns / 1e9, 3),
                    "publishers": sorted({p for p in topic.publishers if p}),
                },
                "set use_sim_time:=true on the publishing node (and stamp with its clock, not "
                "time.time()): its data are 1.7e9 s in the future for every sim-time consumer",
                name,
            )
        elif not is_tf and not topic.latched and (med < -1.0 or med > 0.2):
            looks_sim = not ctx.uses_sim_clock and med_stamp * 1e9 < WALL_TIME_NS
            severity = Severity.ERROR if (med > 0.2 or med < -5.0) else Severity.WARNING
            where = "ahead of" if med > 0 else "behind"
            yield Finding(
                severity,
                "time.stamp_offset",
                f"{name} stamps are {abs(med):.3g} s {where} the clock"
                + (" (they look like sim time, but no /clock is published)" if looks_sim else ""),
                {
                    "topic": name,
                    "median_stamp_minus_clock_s": round(med, 6),
                    "max_abs_offset_s": round(float(np.abs(offsets).max()), 6),
                    "clock": "/clock" if ctx.uses_sim_clock else "receive time",
                },
                "publish /clock (simulator, bag play --clock) for sim-time stamps"
                if looks_sim
                else "stamp with the acquisition time from the same clock the consumers use; "
                "a constant offset means a wrong time base or a missing use_sim_time",
                name,
            )
        if not is_tf:
            yield from _backwards(topic)
    yield from _tf_backwards(ctx)


def _tf_backwards(ctx: CheckContext) -> Iterator[Finding]:
    groups: dict[tuple[str, str], list[int]] = defaultdict(list)
    for r in sorted(ctx.obs.tf, key=lambda r: r.receive_ns):
        if not r.is_static and r.stamp_ns > 0:
            groups[(r.child.lstrip("/"), r.authority)].append(r.stamp_ns)
    for (child, authority), values in sorted(groups.items()):
        d = np.diff(np.asarray(values, dtype=np.int64))
        back = d < 0
        if not back.any():
            continue
        yield Finding(
            Severity.ERROR,
            "time.backwards",
            f"/tf: transforms of '{child}' went backwards in time {int(back.sum())} time(s)",
            {
                "topic": "/tf",
                "child_frame": child,
                "authority": authority or "unknown",
                "backward_steps": int(back.sum()),
                "largest_step_back_s": round(float(-d[back].min()) / 1e9, 6),
            },
            "stamp transforms from a monotonic clock; tf2 drops or misorders older data "
            "(TF_OLD_DATA) and interpolates across the jump",
            child,
        )


def _backwards(topic: TopicData) -> Iterator[Finding]:
    for key, stamps in sorted(_groups(topic).items()):
        s = stamps[stamps != NO_STAMP]
        d = np.diff(s)
        back = d < 0
        if not back.any():
            continue
        yield Finding(
            Severity.ERROR,
            "time.backwards",
            f"{topic.name}: header stamps went backwards {int(back.sum())} time(s)",
            {
                "topic": topic.name,
                "stream": key or "all",
                "backward_steps": int(back.sum()),
                "largest_step_back_s": round(float(-d[back].min()) / 1e9, 6),
                "messages": int(s.size),
            },
            "stamp from a monotonic source (the node's clock at acquisition); two publishers "
            "on one topic with different clocks also cause this",
            topic.name,
        )
        return
