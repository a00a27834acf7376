"""Rate faults: silent topics, declared vs measured rate, jitter, gaps, intermittent, stopped."""

from __future__ import annotations

from typing import Any

import numpy as np

from visnav.msgs import ns_to_time

IMG = "/camera/image_raw"


def test_clean_stream_has_no_rate_finding(dr: Any, clean_events: Any) -> None:
    report = dr.run(clean_events, expect={"topics": {IMG: {"rate": 30}, "/odom": {"rate": 50}}})
    dr.none_of(report, "rates.mismatch", "rates.jitter", "rates.gap", "rates.intermittent")
    dr.none_of(report, "rates.stopped", "rates.no_messages")


def test_no_messages_on_a_published_topic(dr: Any, clean_events: Any) -> None:
    events = dr.drop(clean_events, "/odom")
    graph = dr.car_graph(dr.endpoint("subscription", "/odom", "nav_msgs/msg/Odometry", "ekf"))
    report = dr.run(events, graph=graph)
    f = dr.one(report, "rates.no_messages", subject="/odom", severity=dr.S.WARNING)
    assert f.evidence["subscribers"] == ["/ekf"]
    assert f.evidence["publishers"] == ["/sim"]


def test_no_messages_on_an_expected_topic_is_an_error(dr: Any, clean_events: Any) -> None:
    events = dr.drop(clean_events, "/odom")
    report = dr.run(events, graph=dr.car_graph(), expect={"topics": {"/odom": {}}})
    dr.one(report, "rates.no_messages", subject="/odom", severity=dr.S.ERROR)


def test_measured_rate_below_declared(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, IMG, lambda m, i: m if i % 2 == 0 else None)
    report = dr.run(events, expect={"topics": {IMG: {"rate": 30}}})
    f = dr.one(report, "rates.mismatch", subject=IMG, declared_hz=30.0)
    assert abs(f.evidence["measured_hz"] - 15.0) < 0.5
    assert f.severity is dr.S.WARNING  # 15 Hz is not below half of 30 Hz


def test_far_off_rate_is_an_error(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, IMG, lambda m, i: m if i % 3 == 0 else None)
    report = dr.run(events, expect={"topics": {IMG: {"rate": 30}}})
    f = dr.one(report, "rates.mismatch", subject=IMG, severity=dr.S.ERROR)
    assert abs(f.evidence["measured_hz"] - 10.0) < 0.5


def test_rate_within_tolerance_passes(dr: Any, clean_events: Any) -> None:
    report = dr.run(clean_events, expect={"topics": {IMG: {"rate": 28, "rate_tolerance": 0.1}}})
    dr.none_of(report, "rates.mismatch")


def _stamp(m: Any, t_ns: int) -> Any:
    m.header.stamp = ns_to_time(t_ns)
    return m


def test_jitter(dr: Any, clean_events: Any) -> None:
    rng = np.random.default_rng(1)
    offsets = rng.uniform(-15e6, 15e6, size=200).astype(np.int64)
    events = dr.mutate(
        clean_events,
        "/odom",
        lambda m, i: _stamp(m, max(0, round(i * 20e6) + int(offsets[i]))),
    )
    report = dr.run(events)
    f = dr.one(report, "rates.jitter", subject="/odom", measured_on="stamps")
    assert f.evidence["period_cv"] > 0.5


def test_one_gap(dr: Any, clean_events: Any) -> None:
    # drop 0.8 s of images in the middle
    events = dr.mutate(clean_events, IMG, lambda m, i: None if 30 <= i < 54 else m)
    report = dr.run(events)
    f = dr.one(report, "rates.gap", subject=IMG, gaps=1)
    assert abs(f.evidence["longest_gap_s"] - 0.833) < 0.05
    assert abs(f.evidence["gap_starts_at_s"] - 29 / 30) < 0.05


def test_intermittent(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, IMG, lambda m, i: m if (i // 8) % 2 == 0 else None)
    report = dr.run(events)
    f = dr.one(report, "rates.intermittent", subject=IMG)
    assert f.evidence["gaps"] >= 3
    dr.none_of(report, "rates.gap")


def test_stopped(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, "/odom", lambda m, i: m if i < 60 else None)
    report = dr.run(events)
    f = dr.one(report, "rates.stopped", subject="/odom")
    assert abs(f.evidence["silent_for_s"] - (3.0 - 59 / 50)) < 0.1
