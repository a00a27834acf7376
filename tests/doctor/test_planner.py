"""Planner input faults: inputs not published, sensor range short of the horizon, blind ahead."""

from __future__ import annotations

from typing import Any

CLOUD = "/depth_camera/points"
PC2 = "sensor_msgs/msg/PointCloud2"


def test_planner_input_not_published(dr: Any, clean_events: Any) -> None:
    expect = {"planner": {"inputs": [CLOUD, "/scan", "/odom"]}}
    report = dr.run(clean_events, expect=expect)
    f = dr.one(report, "planner.inputs_missing", subject="/scan", severity=dr.S.ERROR)
    assert f.evidence["publishers"] == []
    assert len(report.find("planner.inputs_missing")) == 1


def test_known_planner_in_the_graph(dr: Any, clean_events: Any) -> None:
    sub = dr.endpoint(
        "subscription", "/grid_map/cloud", PC2, "ego_planner_node", namespace="/drone", entity=50
    )
    odom = dr.endpoint(
        "subscription",
        "/odom",
        "nav_msgs/msg/Odometry",
        "ego_planner_node",
        namespace="/drone",
        entity=51,
    )
    report = dr.run(clean_events, graph=dr.car_graph(sub, odom))
    f = dr.one(report, "planner.inputs_missing", subject="/grid_map/cloud")
    assert f.evidence["planner_nodes"] == ["/drone/ego_planner_node"]
    dr.none_of(report, "topics.no_publisher")  # reported once, as a planner input


def test_planner_input_silent(dr: Any, clean_events: Any) -> None:
    report = dr.run(
        dr.drop(clean_events, CLOUD),
        graph=dr.car_graph(),
        expect={"planner": {"inputs": [CLOUD]}},
    )
    f = dr.one(report, "planner.inputs_missing", subject=CLOUD)
    assert f.evidence["publishers"] == ["/sim"]
    assert "delivered no message" in f.title


def test_sensor_range_shorter_than_horizon(dr: Any, clean_events: Any) -> None:
    expect = {
        "planner": {"horizon": 7.5, "sensors": [CLOUD]},
        "topics": {CLOUD: {"clip_far": 5.0}},
    }
    report = dr.run(clean_events, expect=expect)
    f = dr.one(report, "planner.range_short", subject=CLOUD, severity=dr.S.ERROR)
    assert f.evidence["sensor_range_m"] == 5.0
    assert f.evidence["planner_horizon_m"] == 7.5
    ok = {"planner": {"horizon": 4.0, "sensors": [CLOUD]}, "topics": {CLOUD: {"clip_far": 5.0}}}
    dr.none_of(dr.run(clean_events, expect=ok), "planner.range_short")


def test_measured_reach_with_a_known_planner_default(dr: Any, clean_events: Any) -> None:
    sub = dr.endpoint("subscription", CLOUD, PC2, "ego_planner_node", entity=50)
    report = dr.run(clean_events, graph=dr.car_graph(sub))
    f = dr.one(report, "planner.range_short", subject=CLOUD, severity=dr.S.WARNING)
    assert f.evidence["planner_horizon_m"] == 7.5
    assert "ego_planner_node" in f.evidence["horizon_from"]
    assert f.evidence["measured_p99_reach_m"] < 6.0


def test_sensor_looking_backwards(dr: Any, clean_events: Any) -> None:
    def turn(m: Any, i: int) -> Any:
        for t in m.transforms:
            if t.child_frame_id == "depth_camera_link":
                t.transform.rotation.z, t.transform.rotation.w = 1.0, 0.0
        return m

    events = dr.mutate(clean_events, "/tf_static", turn)
    report = dr.run(events, expect={"planner": {"horizon": 4.0, "sensors": [CLOUD]}})
    f = dr.one(report, "planner.fov_ahead", subject=CLOUD, base_frame="base_footprint")
    assert f.evidence["fraction_ahead"] == 0.0
    assert abs(f.evidence["bearing_min_deg"]) > 140
    dr.none_of(dr.run(clean_events, expect={"planner": {"sensors": [CLOUD]}}), "planner.fov_ahead")
