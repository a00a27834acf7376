"""Live observation: the clean stream published by real nodes, and the simulated car (slow)."""

from __future__ import annotations

import time
from typing import Any

import pytest

from visnav.doctor import LiveObserver, Severity, diagnose, doctor_live
from visnav.doctor.errors import DoctorError
from visnav.doctor.synthetic import CarStreamConfig, car_stream
from visnav.graph import Context, Node, qos_profile_tf_static
from visnav.msgs import get_message_class


def _publish(ctx: Context, events: Any, observer: LiveObserver) -> None:
    node = Node("car", context=ctx)
    pubs: dict[str, Any] = {}
    for ev in events:
        pub = pubs.get(ev.topic)
        if pub is None:
            qos = qos_profile_tf_static if ev.topic == "/tf_static" else 10
            pub = node.create_publisher(get_message_class(ev.type_name), ev.topic, qos)
            pubs[ev.topic] = pub
            observer.poll()  # doctor subscribes to new topics as they appear
        pub.publish(ev.msg)
        ctx.spin_some()


def test_clean_stream_published_live_has_no_error() -> None:
    events = list(car_stream(CarStreamConfig(duration_s=2.0)))
    with Context(transport="local") as ctx:
        observer = LiveObserver(ctx)
        _publish(ctx, events, observer)
        obs = observer.observation()
        observer.close()
    report = diagnose(obs, fixed_frame="odom")
    assert not report.by_severity(Severity.ERROR), report.format()
    assert not report.by_severity(Severity.WARNING), report.format()
    assert obs.topics["/camera/image_raw"].count == 61
    assert len(obs.tf) == 5 + 101
    assert report.summary["nodes"] == 1


def test_live_publisher_identity_and_authority() -> None:
    events = list(car_stream(CarStreamConfig(duration_s=0.5)))
    with Context(transport="local") as ctx:
        observer = LiveObserver(ctx)
        _publish(ctx, events, observer)
        obs = observer.observation()
    assert {r.authority for r in obs.tf} == {"/car"}
    assert len(set(obs.topics["/odom"].publishers)) == 1


def test_doctor_live_listens_for_the_duration(domain: int) -> None:
    start = time.monotonic()
    with pytest.raises(DoctorError, match=f"no topics in graph domain {domain}: "):
        doctor_live(duration_s=0.5)  # an empty domain is an error, not a healthy report
    assert 0.5 <= time.monotonic() - start < 5.0
    with Context(transport="local") as ctx:
        node = Node("talker", context=ctx)
        node.create_publisher(get_message_class("std_msgs/msg/String"), "/chatter", 10)
        report = doctor_live(context=ctx, duration_s=0.5)
    assert report.source == f"live graph, domain {domain}"
    assert report.summary["topics"] == 1, report.format()


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.parametrize(
    ("world", "robot", "fixed_frame", "image_topic"),
    [
        ("office", "car", "odom", "/camera/image_raw"),
        ("forest", "quadrotor", "world", "/depth_camera/depth/image_raw"),
    ],
)
def test_simulated_robots_have_no_error(
    world: str, robot: str, fixed_frame: str, image_topic: str
) -> None:
    from visnav.sim.simulator import RobotSpawn, Simulator

    with (
        Context(transport="local") as ctx,
        Simulator(world, [RobotSpawn(source=robot)], context=ctx) as sim,
    ):
        observer = LiveObserver(ctx)
        sim.run(1.5)
        obs = observer.observation()
    report = diagnose(obs, fixed_frame=fixed_frame)
    assert not report.has_errors, report.format()
    # declared rates and fields of view were read from robot_description and hold
    assert obs.robot_description is not None
    assert not report.find("rates.mismatch")
    assert not report.find("camera_info.fx_vs_fov")
    assert obs.topics[image_topic].count >= 29


@pytest.mark.slow
@pytest.mark.ci
def test_simulated_car_with_the_depth_frame_on_the_camera_link() -> None:
    """The rotated-cloud bug injected into a simulated run: depth <frame_name> is the link."""
    from visnav.description.robots import car_description_path
    from visnav.sim.simulator import RobotSpawn, Simulator

    urdf = (
        car_description_path()
        .read_text()
        .replace(
            "<frame_name>depth_camera_optical_frame</frame_name>",
            "<frame_name>depth_camera_link</frame_name>",
        )
    )
    with (
        Context(transport="local") as ctx,
        Simulator("office", [RobotSpawn(source=urdf)], context=ctx) as sim,
    ):
        observer = LiveObserver(ctx)
        sim.run(0.5)
        obs = observer.observation()
    report = diagnose(obs, fixed_frame="odom")
    (cloud,) = report.find("frames.rotated_cloud", "/depth_camera/points")
    assert cloud.evidence["frame_id"] == "depth_camera_link"
    assert cloud.evidence["data_look"] == "optical"
    assert "'depth_camera_optical_frame'" in cloud.fix
    (image,) = report.find("frames.image_in_body_frame", "/depth_camera/depth/image_raw")
    assert image.evidence["optical_frame_on_tf"] == "depth_camera_optical_frame"


def _far_clip_car() -> str:
    from visnav.description.robots import car_description_path

    text = car_description_path().read_text()
    start = text.index('<sensor type="depth"')
    end = text.index("</sensor>", start)
    sensor = text[start:end].replace("<far>10.0</far>", "<far>0.3</far>")
    sensor = sensor.replace("<max_depth>10.0</max_depth>", "<max_depth>0.3</max_depth>")
    assert "<far>0.3</far>" in sensor
    return text[:start] + sensor + text[end:]


@pytest.mark.slow
@pytest.mark.parametrize("source", ["live", "bag"])
def test_simulated_car_whose_depth_far_clip_hides_the_scene(source: str, tmp_path: Any) -> None:
    """A depth camera with a 0.3 m far clip in the office: every pixel is no return."""
    from visnav.bag.recorder import BagRecorder
    from visnav.doctor import doctor_bag
    from visnav.sim.simulator import RobotSpawn, Simulator

    with (
        Context(transport="local") as ctx,
        Simulator("office", [RobotSpawn(source=_far_clip_car())], context=ctx) as sim,
    ):
        if source == "live":
            observer = LiveObserver(ctx)
            sim.run(0.6)
            report = diagnose(observer.observation(), fixed_frame="odom")
        else:
            recorder = BagRecorder(ctx, None, tmp_path / "bag", use_sim_time=True)
            recorder.start()
            sim.run(0.6)
            bag = recorder.stop()
    if source == "bag":
        report = doctor_bag(bag, fixed_frame="odom")
    (depth,) = report.find("images.depth_invalid", "/depth_camera/depth/image_raw")
    assert depth.severity is Severity.ERROR
    assert depth.evidence["nan_fraction"] == 1.0
    assert depth.evidence["declared_clip_far_m"] == 0.3
    assert "0.3 m" in depth.fix
