"""Frame faults: the rotated cloud, images in body frames, scans in optical frames, odometry."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from visnav.doctor.checks.frames import cloud_convention
from visnav.doctor.synthetic import StreamEvent
from visnav.msgs import LaserScan, make, xyz_to_cloud
from visnav.msgs.pointcloud import cloud_to_xyz

IMG = "/camera/image_raw"
INFO = "/camera/camera_info"
CLOUD = "/depth_camera/points"


def _frame(frame: str) -> Any:
    def apply(m: Any, i: int) -> Any:
        m.header.frame_id = frame
        return m

    return apply


def test_cloud_convention_statistics() -> None:
    rng = np.random.default_rng(0)
    optical = np.column_stack(
        [rng.uniform(-2, 2, 500), rng.uniform(-1, 1, 500), rng.uniform(1, 5, 500)]
    )
    assert cloud_convention(optical)[0] == "optical"
    body = optical[:, [2, 0, 1]] * [1, -1, -1]
    assert cloud_convention(body)[0] == "body"
    ring = np.column_stack([np.cos(np.arange(500)), np.sin(np.arange(500)), np.zeros(500)]) * 3
    assert cloud_convention(ring)[0] is None


def test_optical_cloud_in_a_body_frame(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, CLOUD, _frame("depth_camera_link")))
    f = dr.one(report, "frames.rotated_cloud", subject=CLOUD, frame_is="body", data_look="optical")
    assert f.evidence["fraction_z_positive"] == 1.0
    assert "'depth_camera_optical_frame'" in f.fix
    assert f.evidence["decided_by"].startswith("TF")


@pytest.mark.parametrize("frame", ["odom", "map", "world"])
def test_a_cloud_in_a_world_frame_has_no_convention(dr: Any, clean_events: Any, frame: str) -> None:
    # an accumulated map (SLAM's map points in 'map') has points on every side of the
    # origin, or all above the ground: "in front" says nothing about a convention
    report = dr.run(dr.mutate(clean_events, CLOUD, _frame(frame)))
    dr.none_of(report, "frames.rotated_cloud")


def test_body_cloud_in_an_optical_frame(dr: Any, clean_events: Any) -> None:
    def to_body(m: Any, i: int) -> Any:
        p = cloud_to_xyz(m)
        return xyz_to_cloud(np.column_stack([p[:, 2], -p[:, 0], -p[:, 1]]), header=m.header)

    report = dr.run(dr.mutate(clean_events, CLOUD, to_body))
    dr.one(report, "frames.rotated_cloud", subject=CLOUD, frame_is="optical", data_look="body")


def test_image_in_the_camera_body_frame(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(
        dr.mutate(clean_events, IMG, _frame("camera_link")), INFO, _frame("camera_link")
    )
    report = dr.run(events)
    f = dr.one(report, "frames.image_in_body_frame", subject=IMG, frame_id="camera_link")
    assert f.evidence["optical_frame_on_tf"] == "camera_optical_frame"
    dr.one(report, "frames.image_in_body_frame", subject=INFO)


def test_scan_in_an_optical_frame(dr: Any, clean_events: Any) -> None:
    t0 = clean_events[0].receive_ns
    scans = []
    for k in range(20):
        scan = make(LaserScan, angle_min=-0.5, angle_max=0.5, angle_increment=0.1, range_max=10.0)
        scan.header.frame_id = "camera_optical_frame"
        scan.ranges = np.full(11, 3.0, dtype=np.float32)
        scans.append(StreamEvent("/scan", "sensor_msgs/msg/LaserScan", t0 + k * 100_000_000, scan))
    report = dr.run(sorted([*clean_events, *scans], key=lambda e: e.receive_ns))
    f = dr.one(report, "frames.scan_in_optical_frame", subject="/scan")
    assert f.evidence["frame_is"] == "optical"


def _odom(**fields: Any) -> Any:
    def apply(m: Any, i: int) -> Any:
        if "frame_id" in fields:
            m.header.frame_id = fields["frame_id"]
        if "child" in fields:
            m.child_frame_id = fields["child"]
        if "dx" in fields:
            m.pose.pose.position.x += fields["dx"]
        return m

    return apply


def test_odometry_child_not_on_tf(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, "/odom", _odom(child="base")))
    f = dr.one(report, "frames.odom_tf_mismatch", subject="/odom", child_frame_id="base")
    assert f.evidence["tf_children_of_frame_id"] == ["base_footprint"]
    assert "'base_footprint'" in f.fix


def test_odometry_pose_disagrees_with_tf(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, "/odom", _odom(dx=0.3)))
    f = dr.one(report, "frames.odom_tf_mismatch", subject="/odom", severity=dr.S.ERROR)
    assert abs(f.evidence["max_position_error_m"] - 0.3) < 1e-6
    assert f.evidence["disagreeing"] == f.evidence["compared"]


def test_odometry_frame_id_typo(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, "/odom", _odom(frame_id="odometry")))
    f = dr.one(report, "frames.odom_tf_mismatch", subject="/odom", severity=dr.S.ERROR)
    assert f.evidence["similar_frames"] == ["odom"]


def test_odometry_frame_equals_child(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, "/odom", _odom(frame_id="base_footprint")))
    dr.one(
        report,
        "frames.odom_tf_mismatch",
        subject="/odom",
        frame_id="base_footprint",
        child_frame_id="base_footprint",
    )


def test_ground_truth_in_a_world_frame_is_info(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, "/odom", _odom(frame_id="world")))
    dr.one(report, "frames.odom_tf_mismatch", subject="/odom", severity=dr.S.INFO)


def test_empty_frame_id(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, CLOUD, _frame("")))
    f = dr.one(report, "frames.empty_frame_id", subject=CLOUD, severity=dr.S.ERROR)
    assert f.evidence["empty"] == f.evidence["messages"] == 61


def test_leading_slash(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, IMG, _frame("/camera_optical_frame")))
    f = dr.one(report, "frames.leading_slash", subject="/camera_optical_frame")
    assert f.evidence["topics"] == [IMG]
