"""Issue 18 item 3 (a)-(c): doctor's fixes, each from the symptom a user meets.

(a) SLAM reads ``image_raw`` of a lens with distortion and nothing rectifies it;
(b) the camera mount ``base_link -> camera_link`` is missing: the fix names the URDF joint,
not ``map -> camera_link``; (c) camera_info is unpublished: a suggested remap leads to a
topic of the subscriber's type, never to an Image topic.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from visnav.cli.tf import static_transform_from_args
from visnav.msgs import TFMessage

IMG = "/camera/image_raw"
INFO = "/camera/camera_info"
INFO_TYPE = "sensor_msgs/msg/CameraInfo"
IMAGE_TYPE = "sensor_msgs/msg/Image"
D_LENS = [-0.28, 0.07, 0.001, -0.0005, 0.0]

URDF = """<robot name="car">
  <link name="base_footprint"/><link name="base_link"/>
  <link name="camera_link"/><link name="camera_optical_frame"/>
  <joint name="base_joint" type="fixed">
    <parent link="base_footprint"/><child link="base_link"/><origin xyz="0 0 0.08"/></joint>
  <joint name="camera_joint" type="fixed">
    <parent link="base_link"/><child link="camera_link"/><origin xyz="0.16 0 0.25"/></joint>
  <joint name="camera_optical_joint" type="fixed">
    <parent link="camera_link"/><child link="camera_optical_frame"/>
    <origin rpy="-1.5707963 0 -1.5707963"/></joint>
</robot>"""


def _distorted(m: Any, i: int) -> Any:
    m.d = np.array(D_LENS)
    return m


def _slam_reads(dr: Any, topic: str = IMG, node: str = "orb_slam") -> Any:
    return dr.endpoint("subscription", topic, IMAGE_TYPE, node, entity=90)


# (a) ------------------------------------------------------------------------------


def test_slam_on_distorted_raw_images_is_a_warning(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, INFO, _distorted)
    report = dr.run(events, graph=dr.car_graph(_slam_reads(dr)))
    f = dr.one(report, "camera_info.unrectified_consumer", subject=IMG, severity=dr.S.WARNING)
    assert f.evidence["consumers"] == ["/orb_slam"]
    assert f.evidence["d"] == D_LENS
    assert f.evidence["expected_rectified_topic"] == "/camera/image_rect"
    assert "image_proc" in f.fix
    assert "/camera/image_rect" in f.fix


def test_no_warning_when_rectified_or_undistorted_or_only_recorded(
    dr: Any, clean_events: Any
) -> None:
    events = dr.mutate(clean_events, INFO, _distorted)
    # a rectifier publishes image_rect: the consumer has the choice
    rect = dr.endpoint("publisher", "/camera/image_rect", IMAGE_TYPE, "image_proc", entity=91)
    report = dr.run(events, graph=dr.car_graph(_slam_reads(dr), rect))
    dr.none_of(report, "camera_info.unrectified_consumer")
    # an ideal lens (D all zero) needs no rectification
    report = dr.run(clean_events, graph=dr.car_graph(_slam_reads(dr)))
    dr.none_of(report, "camera_info.unrectified_consumer")
    # a recorder stores the raw images, it does not use their geometry
    rec = _slam_reads(dr, node="visnav_bag_recorder")
    dr.none_of(dr.run(events, graph=dr.car_graph(rec)), "camera_info.unrectified_consumer")
    # on a bag (no graph) no consumer is known
    dr.none_of(dr.run(events), "camera_info.unrectified_consumer")


# (b) ------------------------------------------------------------------------------


def _without_mount(events: Any, dr: Any) -> Any:
    def strip(m: Any, i: int) -> Any:
        m.transforms = [t for t in m.transforms if t.child_frame_id != "camera_link"]
        return m

    return dr.mutate(events, "/tf_static", strip)


def _chain_fixes(report: Any) -> list[Any]:
    return [f for f in report.find("tf.chain_broken") if "camera_link" in f.title]


def test_missing_camera_mount_names_the_urdf_joint(dr: Any, clean_events: Any) -> None:
    events = _without_mount(clean_events, dr)
    for fixed in (None, "map", "odom"):
        report = dr.run(events, fixed_frame=fixed, robot_description=URDF)
        (f,) = _chain_fixes(report)
        assert f.evidence["missing_link"] == "base_link -> camera_link", f.evidence
        assert f.evidence["robot_description_joint"] == "camera_joint"
        assert f.fix.startswith("publish base_link -> camera_link, the fixed joint 'camera_joint'")
        assert "map -> camera_link" not in f.fix
        assert "odom -> camera_link" not in f.fix
        # the command in the fix carries the joint's origin
        assert "visnav tf static 0.16 0 0.25 0 0 0 base_link camera_link" in f.fix


def test_following_the_mount_fix_closes_the_chain(dr: Any, clean_events: Any) -> None:
    events = _without_mount(clean_events, dr)
    (f,) = _chain_fixes(dr.run(events, robot_description=URDF))
    command = f.fix.split("`")[1].split()
    assert command[:3] == ["visnav", "tf", "static"]
    mount = static_transform_from_args(command[3:])  # what `visnav tf static` publishes
    ev = events[0]._replace(topic="/tf_static", msg=TFMessage(transforms=[mount]))
    report = dr.run([events[0], ev, *events[1:]], robot_description=URDF)
    assert not _chain_fixes(report), report.format()


def test_missing_mount_without_description_hangs_it_from_the_vehicle(
    dr: Any, clean_events: Any
) -> None:
    report = dr.run(_without_mount(clean_events, dr), fixed_frame="map")
    (f,) = _chain_fixes(report)
    assert f.evidence["missing_link"] == "base_footprint -> camera_link"
    assert f.evidence["parent_guessed_from"] == "the vehicle's base frame"
    assert "map -> camera_link" not in f.fix


# (c) ------------------------------------------------------------------------------


def _info_reader(dr: Any) -> Any:
    sub = dr.endpoint("subscription", INFO, INFO_TYPE, "rectify", entity=92)
    g = dr.car_graph(sub)
    keep = [e for e in g.endpoints if not (e.topic == INFO and e.kind == "publisher")]
    return dr.graph(*keep)


def test_unpublished_camera_info_never_suggests_an_image_topic(dr: Any, clean_events: Any) -> None:
    # camera only (no depth camera): the closest name is /camera/image_raw, an Image
    events = dr.drop(
        clean_events,
        INFO,
        "/depth_camera/depth/image_raw",
        "/depth_camera/depth/camera_info",
        "/depth_camera/points",
    )
    g = _info_reader(dr)
    g = dr.graph(*[e for e in g.endpoints if not e.topic.startswith("/depth_camera")])
    f = dr.one(dr.run(events, graph=g), "topics.no_publisher", subject=INFO)
    assert "similar_published_topics" not in f.evidence, f.evidence
    assert "remap" not in f.fix
    assert IMG not in f.fix


def test_unpublished_camera_info_suggests_a_camera_info_topic(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.drop(clean_events, INFO), graph=_info_reader(dr))
    f = dr.one(report, "topics.no_publisher", subject=INFO)
    assert f.evidence["similar_published_topics"] == ["/depth_camera/depth/camera_info"]
    assert f.fix.endswith("remap the subscription to /depth_camera/depth/camera_info")


def test_expected_camera_info_suggestions_keep_the_type(dr: Any, clean_events: Any) -> None:
    events = dr.drop(clean_events, INFO, "/depth_camera/depth/camera_info")
    expect = {"topics": {INFO: {"type": INFO_TYPE}}}
    f = dr.one(dr.run(events, expect=expect), "topics.expected_missing", subject=INFO)
    assert IMG not in f.evidence.get("similar_topics", [])
    assert "remap" not in f.fix
