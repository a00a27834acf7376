"""Periodic vs event topics, arrival jitter of fast streams, and a far clip that hides the scene."""

from __future__ import annotations

from typing import Any

import numpy as np

from visnav.msgs import (
    Header,
    Path,
    get_message_class,
    image_to_numpy,
    ns_to_time,
    numpy_to_image,
)
from visnav.msgs.serde import msg_type_name

DEPTH = "/depth_camera/depth/image_raw"
PATH = "/drone/planning/path"


def _plan(stamp_ns: int) -> Path:
    header = Header(stamp=ns_to_time(stamp_ns), frame_id="odom")
    return Path(header=header, poses=[])


def _path_events(dr: Any, clean_events: Any, times_ns: list[int]) -> list[Any]:
    template = next(e for e in clean_events if e.topic == "/odom")
    extra = [
        template._replace(topic=PATH, type_name=msg_type_name(_plan(t)), receive_ns=t, msg=_plan(t))
        for t in times_ns
    ]
    return sorted([*clean_events, *extra], key=lambda e: e.receive_ns)


def test_an_uneven_event_topic_is_not_jitter(dr: Any, clean_events: Any) -> None:
    # a planner replans when something happens: 20 paths at very uneven intervals
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.exponential(0.1e9, size=20)).astype(np.int64) + 100_000_000
    times = times[times < 2_900_000_000]
    report = dr.run(_path_events(dr, clean_events, [int(t) for t in times]))
    dr.none_of(report, "rates.jitter", "rates.gap", "rates.intermittent", "rates.stopped")


def test_the_same_unevenness_on_a_sensor_is_jitter(dr: Any, clean_events: Any) -> None:
    rng = np.random.default_rng(1)
    offsets = rng.uniform(-15e6, 15e6, size=200).astype(np.int64)

    def stamp(m: Any, i: int) -> Any:
        m.header.stamp = ns_to_time(max(0, round(i * 20e6) + int(offsets[i])))
        return m

    report = dr.run(dr.mutate(clean_events, "/odom", stamp))
    dr.one(report, "rates.jitter", subject="/odom")


def test_a_silent_goal_topic_is_information(dr: Any, clean_events: Any) -> None:
    goal = "/move_base_simple/goal"
    graph = dr.car_graph(
        dr.endpoint("subscription", goal, "geometry_msgs/msg/PoseStamped", "move_base")
    )
    report = dr.run(clean_events, graph=graph)
    f = dr.one(report, "topics.no_publisher", subject=goal, severity=dr.S.INFO)
    assert "events" in f.fix
    # with a publisher that sends nothing (RViz open, no click yet)
    graph = dr.car_graph(
        dr.endpoint("subscription", goal, "geometry_msgs/msg/PoseStamped", "move_base"),
        dr.endpoint("publisher", goal, "geometry_msgs/msg/PoseStamped", "rviz", entity=99),
    )
    f = dr.one(dr.run(clean_events, graph=graph), "rates.no_messages", subject=goal)
    assert f.severity is dr.S.INFO
    assert "event" in f.fix
    # a silent sensor with a subscriber stays a warning
    events = dr.drop(clean_events, "/odom")
    graph = dr.car_graph(dr.endpoint("subscription", "/odom", "nav_msgs/msg/Odometry", "ekf"))
    dr.one(dr.run(events, graph=graph), "rates.no_messages", subject="/odom", severity=dr.S.WARNING)


def test_a_declared_rate_makes_an_event_type_periodic(dr: Any, clean_events: Any) -> None:
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.exponential(0.1e9, size=25)).astype(np.int64) + 100_000_000
    times = times[times < 2_900_000_000]
    events = _path_events(dr, clean_events, [int(t) for t in times])
    report = dr.run(events, expect={"topics": {PATH: {"rate": 10}}})
    dr.one(report, "rates.jitter", subject=PATH)


def test_arrival_jitter_of_a_1khz_headerless_stream_is_not_judged(
    dr: Any, clean_events: Any
) -> None:
    # /gazebo/model_states: one message per world step, delivered in bursts
    odom = next(e for e in clean_events if e.topic == "/odom")
    msg = get_message_class("gazebo_msgs/msg/ModelStates")(name=["car"], pose=[], twist=[])
    extra = []
    t = 50_000_000
    for burst in range(150):
        for k in range(10):  # ten steps arrive 20 us apart, then a 10 ms pause
            extra.append(
                odom._replace(
                    topic="/gazebo/model_states",
                    type_name="gazebo_msgs/msg/ModelStates",
                    receive_ns=t + burst * 10_000_000 + k * 20_000,
                    msg=msg,
                )
            )
    events = sorted([*clean_events, *extra], key=lambda e: e.receive_ns)
    report = dr.run(events)
    assert not [f for f in report.find("rates.jitter") if f.subject == "/gazebo/model_states"]


def test_a_far_clip_nearer_than_the_scene_is_named(dr: Any, clean_events: Any) -> None:
    def nan(m: Any, i: int) -> Any:
        a = image_to_numpy(m).copy() * np.nan
        return numpy_to_image(a, m.encoding, header=m.header)

    events = dr.mutate(clean_events, DEPTH, nan)
    report = dr.run(events, expect={"topics": {DEPTH: {"clip_far": 0.3}}})
    f = dr.one(report, "images.depth_invalid", subject=DEPTH, severity=dr.S.ERROR)
    assert f.evidence["declared_clip_far_m"] == 0.3
    assert "0.3 m" in f.fix
    assert "<far>" in f.fix


def test_messages_lost_by_the_observer_are_not_jitter(dr: Any, clean_events: Any) -> None:
    # a steady 50 Hz stream read by a busy subscriber: 1, 2 or 3 periods between messages
    rng = np.random.default_rng(7)
    keep = rng.random(400) > 0.5
    events = dr.mutate(clean_events, "/odom", lambda m, i: m if keep[i] or i == 0 else None)
    report = dr.run(events)
    dr.none_of(report, "rates.jitter")
