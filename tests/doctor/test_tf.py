"""TF faults: unknown frames, broken chains, cycles, two parents, quaternions, timing, statics."""

from __future__ import annotations

from typing import Any

from visnav.doctor.checks.transforms import find_cycles
from visnav.doctor.synthetic import StreamEvent
from visnav.msgs import Header, Quaternion, TFMessage, Transform, TransformStamped, Vector3
from visnav.msgs.time import ns_to_time, time_to_ns

IMG = "/camera/image_raw"
CLOUD = "/depth_camera/points"
TFT = "tf2_msgs/msg/TFMessage"


def _tf(parent: str, child: str, t_ns: int, q: Any = (0, 0, 0, 1), xyz: Any = (0, 0, 0)) -> Any:
    return TransformStamped(
        Header(stamp=ns_to_time(t_ns), frame_id=parent),
        child,
        Transform(Vector3(*map(float, xyz)), Quaternion(*map(float, q))),
    )


def _add_tf(events: Any, transforms: Any, *, topic: str = "/tf", publisher: str = "x:1") -> Any:
    """Add one TF message per transform, received like the clean stream's /clock at its stamp."""
    start = events[0].receive_ns
    extra = [
        StreamEvent(topic, TFT, start + time_to_ns(t.header.stamp) + 1, TFMessage([t]), publisher)
        for t in transforms
    ]
    return sorted([*events, *extra], key=lambda e: e.receive_ns)


def _frame(frame: str) -> Any:
    def apply(m: Any, i: int) -> Any:
        m.header.frame_id = frame
        return m

    return apply


def test_unknown_frame_with_suggestion(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, IMG, _frame("camera_optical"))
    report = dr.run(dr.drop(events, "/camera/camera_info"))
    f = dr.one(report, "tf.unknown_frame", subject="camera_optical", severity=dr.S.ERROR)
    assert f.evidence["topics"] == [IMG]
    assert f.evidence["similar_frames"][0] == "camera_optical_frame"


def test_fixed_frame_never_published(dr: Any, clean_events: Any) -> None:
    report = dr.run(clean_events, fixed_frame="map")
    (f,) = report.find("tf.chain_broken")  # one finding per missing link
    assert f.subject == "map -> base_footprint"
    assert f.evidence["missing_frame"] == "map"
    assert "map -> depth_camera_optical_frame" in f.evidence["also_broken"]
    assert "localisation" in f.fix


def test_chain_broken_names_the_missing_link(dr: Any, clean_events: Any) -> None:
    # a map frame exists (a static landmark) but nothing publishes map -> odom
    events = _add_tf(clean_events, [_tf("map", "landmark", 0)], topic="/tf_static")
    report = dr.run(events, fixed_frame="map")
    f = dr.one(report, "tf.chain_broken", subject="map -> base_footprint")
    assert f.evidence["missing_link"] == "map -> odom"
    assert "map -> camera_optical_frame" in f.evidence["also_broken"]
    assert f.evidence["target_tree_root"] == "map"
    assert f.evidence["source_tree_root"] == "odom"
    assert "map -> odom" in f.fix
    # publishing map -> odom fixes it
    fixed = _add_tf(events, [_tf("map", "odom", 0)], topic="/tf_static")
    dr.none_of(dr.run(fixed, fixed_frame="map"), "tf.chain_broken")


def test_expected_chain(dr: Any, clean_events: Any) -> None:
    events = _add_tf(clean_events, [_tf("arm_base", "gripper", 0)], topic="/tf_static")
    report = dr.run(events, expect={"tf_chains": [["base_link", "gripper"]]})
    f = dr.one(report, "tf.chain_broken", subject="base_link -> gripper")
    assert f.evidence["missing_link"] == "odom -> arm_base"
    assert "--expect" in f.evidence["needed_because"]


def test_unknown_frame_without_any_tf_is_a_warning(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.drop(clean_events, "/tf", "/tf_static"))
    f = dr.one(report, "tf.unknown_frame", subject="camera_optical_frame", severity=dr.S.WARNING)
    assert "no transform is published at all" in f.title


def test_find_cycles() -> None:
    assert find_cycles({("a", "b"), ("b", "c"), ("c", "a"), ("d", "a")}) == [["a", "b", "c"]]
    assert find_cycles({("a", "b")}) == []


def test_cycle(dr: Any, clean_events: Any) -> None:
    # a transform published in the wrong direction: base_link as the child of camera_link
    events = _add_tf(clean_events, [_tf("camera_link", "base_link", 0)], topic="/tf_static")
    report = dr.run(events)
    f = dr.one(report, "tf.cycle", subject="base_link")
    assert f.evidence["cycle"] == ["base_link", "camera_link"]


def test_two_parents(dr: Any, clean_events: Any) -> None:
    events = _add_tf(
        clean_events,
        [_tf("world", "base_footprint", round(t * 1e8)) for t in range(30)],
        publisher="gt:7",
    )
    report = dr.run(events)
    f = dr.one(report, "tf.two_parents", subject="base_footprint", severity=dr.S.ERROR)
    assert set(f.evidence["parents"]) == {"odom", "world"}
    assert f.evidence["parents"]["world"]["authorities"] == ["gt:7"]
    assert f.evidence["parents"]["odom"]["transforms"] == 151


def test_quaternion_refused_by_tf2(dr: Any, clean_events: Any) -> None:
    def scaled(m: Any, i: int) -> Any:
        m.transforms[0].transform.rotation.w = 2.0
        return m

    report = dr.run(dr.mutate(clean_events, "/tf", scaled))
    f = dr.one(report, "tf.quaternion", subject="base_footprint", severity=dr.S.ERROR)
    assert f.evidence["norm_squared"] == 4.0
    assert f.evidence["rotation_xyzw"] == [0.0, 0.0, 0.0, 2.0]


def test_quaternion_slightly_off_is_a_warning(dr: Any, clean_events: Any) -> None:
    def sloppy(m: Any, i: int) -> Any:
        m.transforms[0].transform.rotation.w = 1.002
        return m

    report = dr.run(dr.mutate(clean_events, "/tf", sloppy))
    dr.one(report, "tf.quaternion", subject="base_footprint", severity=dr.S.WARNING)


def _shift(offset_ns: int) -> Any:
    def apply(m: Any, i: int) -> Any:
        for t in m.transforms:
            t.header.stamp = ns_to_time(max(0, time_to_ns(t.header.stamp) + offset_ns))
        return m

    return apply


def test_stale_transforms(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, "/tf", _shift(-1_500_000_000)))
    f = dr.one(report, "tf.stale", subject="base_footprint", severity=dr.S.ERROR)
    assert abs(f.evidence["median_stamp_minus_clock_s"] + 1.5) < 0.01


def test_transform_publisher_stopped(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, "/tf", lambda m, i: m if i < 50 else None)
    report = dr.run(events)
    f = dr.one(report, "tf.stale", subject="base_footprint")
    assert f.evidence["silent_for_s"] > 1.9


def test_future_transforms(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, "/tf", _shift(500_000_000)))
    f = dr.one(report, "tf.future", subject="base_footprint", severity=dr.S.ERROR)
    assert abs(f.evidence["median_stamp_minus_clock_s"] - 0.5) < 0.01


def test_extrapolation_for_the_cloud_lookup(dr: Any, clean_events: Any) -> None:
    def ahead(m: Any, i: int) -> Any:
        m.header.stamp = ns_to_time(time_to_ns(m.header.stamp) + 400_000_000)
        return m

    report = dr.run(dr.mutate(clean_events, CLOUD, ahead))
    f = dr.one(report, "tf.extrapolation", subject=CLOUD, direction="future")
    assert f.evidence["target_frame"] == "odom"
    assert f.evidence["failing_link"] == "base_footprint"
    assert f.evidence["data_stamp_s"] > f.evidence["tf_latest_s"]
    assert 6 <= f.evidence["failed"] <= 10  # the last 0.4 s of 20 Hz clouds


def test_static_transform_on_tf(dr: Any, clean_events: Any) -> None:
    mount = [
        _tf("base_link", "camera_link", round(t * 2e7), xyz=(0.16, 0, 0.25)) for t in range(150)
    ]
    report = dr.run(_add_tf(clean_events, mount))
    f = dr.one(report, "tf.static_on_tf", subject="camera_link", severity=dr.S.WARNING)
    assert f.evidence["transforms"] == 150
    assert f.evidence["translation"] == [0.16, 0.0, 0.25]


def test_constant_odometry_tf_is_not_static(dr: Any) -> None:
    events = dr.stream(speed=0.0)  # the car stands still: odom -> base is constant
    dr.none_of(dr.run(events), "tf.static_on_tf")


def test_postdated_localisation_is_a_warning(dr: Any, clean_events: Any) -> None:
    # AMCL-style map -> odom, post-dated by its transform_tolerance of 0.5 s
    start = clean_events[0].receive_ns
    extra = [
        StreamEvent("/tf", TFT, start + t, TFMessage([_tf("map", "odom", t + 500_000_000)]), "amcl")
        for t in range(0, 3_000_000_000, 100_000_000)
    ]
    events = sorted([*clean_events, *extra], key=lambda e: e.receive_ns)
    f = dr.one(dr.run(events), "tf.future", subject="odom", severity=dr.S.WARNING)
    assert abs(f.evidence["median_stamp_minus_clock_s"] - 0.5) < 0.01
