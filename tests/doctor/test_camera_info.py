"""camera_info faults: K, size, field of view, distortion, stamps and frames vs the image."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from visnav.msgs import ns_to_time

IMG = "/camera/image_raw"
INFO = "/camera/camera_info"


def _set(**fields: Any) -> Any:
    def apply(m: Any, i: int) -> Any:
        for k, v in fields.items():
            setattr(m, k, v)
        return m

    return apply


def test_image_without_camera_info(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.drop(clean_events, INFO))
    f = dr.one(report, "camera_info.missing", subject=IMG, severity=dr.S.INFO)
    assert f.evidence["expected_camera_info"] == INFO


def test_k_all_zero(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, INFO, _set(k=np.zeros(9))))
    f = dr.one(report, "camera_info.k_zero", subject=INFO, severity=dr.S.ERROR)
    assert f.evidence["k"] == [0.0] * 9


def test_p_all_zero(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, INFO, _set(p=np.zeros(12))))
    f = dr.one(report, "camera_info.k_zero", subject=INFO)
    assert f.evidence["p"] == [0.0] * 12


def test_k_of_another_resolution(dr: Any, clean_events: Any) -> None:
    # calibration made at 2x the resolution: cx, cy at the image's corner
    def scaled(m: Any, i: int) -> Any:
        m.k = m.k * np.array([2, 1, 2, 1, 2, 2, 1, 1, 1.0])
        return m

    report = dr.run(dr.mutate(clean_events, INFO, scaled))
    f = dr.one(report, "camera_info.k_vs_size", subject=INFO)
    assert "outside the 64x48 image" in f.evidence["problems"][0]


def test_camera_info_size_differs_from_image(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, INFO, _set(width=640, height=480)))
    f = dr.one(report, "camera_info.k_vs_size", subject=INFO, image_width=64, image_height=48)
    assert "camera_info is 640x480 but the images are 64x48" in f.evidence["problems"]


def test_fx_vs_declared_hfov_from_expect(dr: Any, clean_events: Any) -> None:
    # the stream's fx is for 80 deg; declare 60 deg
    report = dr.run(clean_events, expect={"topics": {INFO: {"hfov": math.radians(60)}}})
    f = dr.one(report, "camera_info.fx_vs_fov", subject=INFO, width=64)
    assert abs(f.evidence["expected_fx"] - 32 / math.tan(math.radians(30))) < 1e-3
    assert abs(math.degrees(f.evidence["implied_hfov_rad"]) - 80.0) < 0.01
    dr.none_of(
        dr.run(clean_events, expect={"topics": {INFO: {"hfov": 1.3962634}}}),
        "camera_info.fx_vs_fov",
    )


URDF = """<robot name="r">
  <link name="base_link"/><link name="camera_link"/>
  <joint name="j" type="fixed"><parent link="base_link"/><child link="camera_link"/></joint>
  <gazebo reference="camera_link">
    <sensor type="camera" name="camera">
      <update_rate>30</update_rate>
      <camera><horizontal_fov>{hfov}</horizontal_fov>
        <image><width>64</width><height>48</height><format>R8G8B8</format></image>
        <clip><near>0.05</near><far>50</far></clip></camera>
      <plugin name="cam" filename="libgazebo_ros_camera.so">
        <camera_name>camera</camera_name><frame_name>camera_optical_frame</frame_name>
      </plugin>
    </sensor>
  </gazebo>
</robot>"""


def test_fx_vs_hfov_declared_in_robot_description(dr: Any, clean_events: Any) -> None:
    ok = dr.run(clean_events, robot_description=URDF.format(hfov=1.3962634))
    dr.none_of(ok, "camera_info.fx_vs_fov", "rates.mismatch")
    report = dr.run(clean_events, robot_description=URDF.format(hfov=1.047))
    f = dr.one(report, "camera_info.fx_vs_fov", subject=INFO)
    assert f.evidence["declared_hfov_rad"] == 1.047
    assert "robot_description sensor 'camera'" in f.evidence["declared_by"]


def test_d_length_for_plumb_bob(dr: Any, clean_events: Any) -> None:
    report = dr.run(dr.mutate(clean_events, INFO, _set(d=np.zeros(4))))
    f = dr.one(report, "camera_info.d_length", distortion_model="plumb_bob", d_length=4)
    assert f.evidence["expected_length"] == 5


def test_unknown_distortion_where_rectification_is_needed(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, INFO, _set(distortion_model="", d=np.array([0.1, 0, 0, 0, 0])))
    report = dr.run(events, expect={"topics": {INFO: {"rectify": True}}})
    f = dr.one(report, "camera_info.distortion_unknown", subject=INFO, severity=dr.S.ERROR)
    assert f.evidence["rectification_needed"] is True
    # without a rectifier it is a warning
    f = dr.one(dr.run(events), "camera_info.distortion_unknown", severity=dr.S.WARNING)


def test_rectified_topic_makes_unknown_model_an_error(dr: Any, clean_events: Any) -> None:
    events = dr.mutate(clean_events, INFO, _set(distortion_model="fisheye62"))
    rect = [e._replace(topic="/camera/image_rect") for e in clean_events if e.topic == IMG]
    report = dr.run(sorted(events + rect, key=lambda e: e.receive_ns))
    f = dr.one(report, "camera_info.distortion_unknown", subject=INFO, severity=dr.S.ERROR)
    assert f.evidence["because"] == "/camera/image_rect exists"


def test_stamps_do_not_match(dr: Any, clean_events: Any) -> None:
    def late(m: Any, i: int) -> Any:
        m.header.stamp = ns_to_time(round(i * 1e9 / 30) + 5_000_000)
        return m

    report = dr.run(dr.mutate(clean_events, INFO, late))
    f = dr.one(report, "camera_info.stamp_mismatch", subject=IMG, matched_fraction=0.0)
    assert abs(f.evidence["median_offset_s"] - 0.005) < 1e-6


def test_frames_do_not_match(dr: Any, clean_events: Any) -> None:
    def other(m: Any, i: int) -> Any:
        m.header.frame_id = "camera_link"
        return m

    report = dr.run(dr.mutate(clean_events, INFO, other))
    dr.one(
        report,
        "camera_info.frame_mismatch",
        subject=IMG,
        image_frame_id="camera_optical_frame",
        camera_info_frame_id="camera_link",
    )
