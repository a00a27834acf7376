"""Time faults: sim time without /clock, wall-clock stamps, zero, far and backwards stamps."""

from __future__ import annotations

from typing import Any

from visnav.doctor import LiveObserver, diagnose
from visnav.graph import Context, Node
from visnav.msgs import Clock, ns_to_time
from visnav.msgs.time import time_to_ns

INFO = "/camera/camera_info"


def _stamp(fn: Any) -> Any:
    def apply(m: Any, i: int) -> Any:
        m.header.stamp = ns_to_time(fn(time_to_ns(m.header.stamp), i))
        return m

    return apply


def test_use_sim_time_without_clock_live() -> None:
    with Context(transport="local") as ctx:
        Node("planner", context=ctx, use_sim_time=True)
        Node("mapper", namespace="/robot", context=ctx, use_sim_time=True)
        observer = LiveObserver(ctx)
        ctx.spin_some()
        report = diagnose(observer.observation())
    f = report.find("time.sim_time_no_clock")[0]
    assert f.evidence["clock_subscribers"] == ["/planner", "/robot/mapper"]
    assert f.evidence["clock_publishers"] == []
    assert report.has_errors


def test_use_sim_time_without_clock_in_a_bag(dr: Any, clean_events: Any) -> None:
    events = dr.drop(clean_events, "/clock")
    report = dr.run(events, expect={"use_sim_time": True})
    dr.one(report, "time.sim_time_no_clock", subject="/clock", clock_messages=0)
    dr.none_of(dr.run(clean_events, expect={"use_sim_time": True}), "time.sim_time_no_clock")


def test_wall_clock_stamps_under_sim_time(dr: Any, clean_events: Any) -> None:
    wall = 1_700_000_123_000_000_000
    events = dr.mutate(clean_events, "/odom", _stamp(lambda t, i: wall + t))
    report = dr.run(events)
    f = dr.one(report, "time.wall_stamps", subject="/odom", severity=dr.S.ERROR)
    assert abs(f.evidence["median_stamp_s"] - 1_700_000_124.5) < 0.1
    assert f.evidence["clock_s"] == 3.0
    assert f.evidence["publishers"] == ["sim:diff_drive"]
    dr.none_of(report, "time.stamp_offset")


def test_zero_stamps(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, INFO, _stamp(lambda t, i: 0)))
    f = dr.one(report, "time.zero_stamp", subject=INFO, severity=dr.S.ERROR)
    assert f.evidence["zero_stamps"] >= 70  # all but those at sim time < 0.5 s


def test_zero_stamp_at_sim_start_is_fine(dr: Any, clean_events: Any) -> None:
    dr.none_of(dr.run(clean_events), "time.zero_stamp")


def test_stamps_late(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, "/odom", _stamp(lambda t, i: max(1, t - 2_000_000_000)))
    report = dr.run(events)
    f = dr.one(report, "time.stamp_offset", subject="/odom", severity=dr.S.WARNING)
    assert -2.01 < f.evidence["median_stamp_minus_clock_s"] < -1.0
    assert f.evidence["clock"] == "/clock"


def test_stamps_in_the_future(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, "/odom", _stamp(lambda t, i: t + 700_000_000))
    report = dr.run(events)
    f = dr.one(report, "time.stamp_offset", subject="/odom", severity=dr.S.ERROR)
    assert abs(f.evidence["median_stamp_minus_clock_s"] - 0.699) < 0.01


def test_sim_stamps_without_clock(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.drop(clean_events, "/clock"))
    f = dr.one(report, "time.stamp_offset", subject="/odom", severity=dr.S.ERROR)
    assert "look like sim time" in f.title
    assert f.evidence["clock"] == "receive time"


def test_stamps_going_backwards(dr: Any, clean_events: Any) -> None:
    def swap(t: int, i: int) -> int:
        return t + 20_000_000 if i % 10 == 4 else t - 20_000_000 if i % 10 == 5 else t

    report = dr.run(dr.mutate(clean_events, "/odom", _stamp(swap)))
    f = dr.one(report, "time.backwards", subject="/odom", stream="sim:diff_drive")
    assert f.evidence["backward_steps"] == 15
    assert abs(f.evidence["largest_step_back_s"] - 0.02) < 1e-9


def test_transforms_going_backwards(dr: Any, clean_events: Any) -> None:
    def back(m: Any, i: int) -> Any:
        if i == 40:
            m.transforms[0].header.stamp = ns_to_time(100_000_000)
        return m

    report = dr.run(dr.mutate(clean_events, "/tf", back))
    f = dr.one(report, "time.backwards", subject="base_footprint", topic="/tf")
    assert f.evidence["backward_steps"] == 1


def test_clock_going_backwards(dr: Any, clean_events: Any) -> None:
    def reset(m: Any, i: int) -> Any:
        return Clock(clock=ns_to_time(max(0, (i - 150) * 10_000_000))) if i >= 150 else m

    report = dr.run(dr.mutate(clean_events, "/clock", reset))
    f = dr.one(report, "time.backwards", subject="/clock", severity=dr.S.WARNING)
    assert f.evidence["backward_jumps"] == 1
    assert abs(f.evidence["largest_jump_back_s"] - 1.49) < 1e-6


def test_two_publishers_do_not_look_backwards(dr: Any, clean_events: Any) -> None:
    # a second odometry publisher with its own (monotonic) stamps, interleaved
    extra = [
        e._replace(publisher="other:2", receive_ns=e.receive_ns + 5_000_000)
        for e in clean_events
        if e.topic == "/odom"
    ]
    events = sorted([*clean_events, *extra], key=lambda e: e.receive_ns)
    dr.none_of(dr.run(events), "time.backwards")
