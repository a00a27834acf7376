"""Topic faults: expected topics, namespace slips, dangling endpoints, QoS, types, undecodable."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from visnav.cli.main import main
from visnav.doctor import LiveObserver, diagnose
from visnav.doctor.checks.topics import namespace_variants
from visnav.graph import Context, Node, QoSProfile, ReliabilityPolicy
from visnav.graph.keys import liveliness_token
from visnav.msgs import Image, PointCloud2

SCRIPTS = Path(__file__).parent / "scripts"
PC2 = "sensor_msgs/msg/PointCloud2"


def test_namespace_variants() -> None:
    names = {"/drone/camera/depth/points", "/camera/depth/points2", "/x/points"}
    assert namespace_variants("/camera/depth/points", names) == ["/drone/camera/depth/points"]
    assert namespace_variants("/drone/camera/depth/points", {"/camera/depth/points"}) == [
        "/camera/depth/points"
    ]
    assert namespace_variants("/points", {"/points"}) == []


def test_expected_topic_missing(dr: Any, clean_events: Any) -> None:
    report = dr.run(
        clean_events, expect={"topics": {"/scan": {"type": "sensor_msgs/msg/LaserScan"}}}
    )
    f = dr.one(report, "topics.expected_missing", subject="/scan", severity=dr.S.ERROR)
    assert f.evidence["expected_type"] == "sensor_msgs/msg/LaserScan"
    optional = dr.run(clean_events, expect={"topics": {"/scan": {"optional": True}}})
    dr.one(optional, "topics.expected_missing", subject="/scan", severity=dr.S.WARNING)


def test_expected_topic_published_under_a_namespace(dr: Any, clean_events: Any) -> None:
    events = [
        e._replace(topic="/drone" + e.topic) if e.topic.startswith("/camera") else e
        for e in clean_events
    ]
    report = dr.run(events, expect={"topics": {"/camera/image_raw": {}}})
    f = dr.one(report, "topics.expected_missing", subject="/camera/image_raw")
    assert f.evidence["exists_under_other_namespace"] == ["/drone/camera/image_raw"]
    assert "(but /drone/camera/image_raw is)" in f.title


def test_expected_type(dr: Any, clean_events: Any) -> None:
    report = dr.run(
        clean_events, expect={"topics": {"/odom": {"type": "geometry_msgs/msg/PoseStamped"}}}
    )
    f = dr.one(report, "topics.expected_type", subject="/odom")
    assert f.evidence["observed_types"] == ["nav_msgs/msg/Odometry"]


def _observe(ctx: Context) -> Any:
    observer = LiveObserver(ctx)
    ctx.spin_some()
    return diagnose(observer.observation())


def test_subscriber_on_absolute_name_while_namespaced_topic_exists() -> None:
    with Context(transport="local") as ctx:
        cam = Node("camera_driver", namespace="/drone", context=ctx)
        cam.create_publisher(PointCloud2, "camera/depth/points", 10)
        mapper = Node("mapper", context=ctx)
        mapper.create_subscription(PointCloud2, "/camera/depth/points", lambda m: None, 10)
        report = _observe(ctx)
    (f,) = report.find("topics.namespace_mismatch")
    assert (
        f.title
        == "subscriber waiting on /camera/depth/points while /drone/camera/depth/points exists"
    )
    assert f.evidence["subscribers"] == ["/mapper"]
    assert f.evidence["publishers"] == ["/drone/camera_driver"]
    assert "remap /camera/depth/points:=/drone/camera/depth/points on /mapper" in f.fix
    assert not report.find("topics.no_publisher")
    assert report.has_errors


def test_namespaced_subscriber_resolving_a_relative_name() -> None:
    with Context(transport="local") as ctx:
        cam = Node("camera_driver", context=ctx)
        cam.create_publisher(PointCloud2, "/camera/depth/points", 10)
        mapper = Node("mapper", namespace="/drone", context=ctx)
        mapper.create_subscription(PointCloud2, "camera/depth/points", lambda m: None, 10)
        report = _observe(ctx)
    (f,) = report.find("topics.namespace_mismatch")
    assert (
        f.title
        == "subscriber waiting on /drone/camera/depth/points while /camera/depth/points exists"
    )
    assert f.evidence["subscriber_namespaces"] == ["/drone"]
    assert "resolved the relative name 'camera/depth/points'" in f.fix


def test_subscription_without_publisher(dr: Any, clean_events: Any) -> None:
    sub = dr.endpoint("subscription", "/odom_filtred", "nav_msgs/msg/Odometry", "ekf", entity=40)
    report = dr.run(clean_events, graph=dr.car_graph(sub))
    f = dr.one(report, "topics.no_publisher", subject="/odom_filtred", severity=dr.S.WARNING)
    assert f.evidence["subscribers"] == ["/ekf"]
    dr.none_of(report, "topics.namespace_mismatch")


def test_publishers_without_subscribers_are_info(dr: Any, clean_events: Any) -> None:
    sub = dr.endpoint("subscription", "/odom", "nav_msgs/msg/Odometry", "ekf", entity=40)
    report = dr.run(clean_events, graph=dr.car_graph(sub))
    f = dr.one(report, "topics.no_subscriber", severity=dr.S.INFO)
    assert "/camera/image_raw" in f.evidence["topics"]
    assert "/odom" not in f.evidence["topics"]
    assert "/tf" not in f.evidence["topics"]


def test_qos_incompatible_live() -> None:
    with Context(transport="local") as ctx:
        cam = Node("camera_driver", context=ctx)
        cam.create_publisher(
            Image, "/image", QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
        )
        view = Node("viewer", context=ctx)
        view.create_subscription(Image, "/image", lambda m: None, 10)
        report = _observe(ctx)
    (f,) = report.find("topics.qos_incompatible")
    assert f.evidence["publisher_qos"] == "best_effort/volatile/keep_last(5)"
    assert f.evidence["subscriber_qos"] == "reliable/volatile/keep_last(10)"
    assert f.evidence["publisher"] == "/camera_driver"
    assert f.evidence["subscriber"] == "/viewer"
    assert "qos_profile_sensor_data" in f.fix


def test_type_mismatch(dr: Any) -> None:
    g = dr.graph(
        dr.endpoint("publisher", "/pose", "geometry_msgs/msg/PoseStamped", "localizer"),
        dr.endpoint("subscription", "/pose", "nav_msgs/msg/Odometry", "planner", entity=2),
    )
    report = dr.run(dr.stream(duration_s=0.2), graph=g)
    f = dr.one(report, "topics.type_mismatch", subject="/pose")
    assert f.evidence["endpoints_by_type"] == {
        "geometry_msgs/msg/PoseStamped": ["publisher /localizer"],
        "nav_msgs/msg/Odometry": ["subscription /planner"],
    }


def test_undecodable_type_live() -> None:
    with Context(transport="local") as ctx:
        key = liveliness_token(
            ctx.domain, "abc", 7, 8, "MP", "/", "lidar_driver",
            topic="/lidar/packets", type_name="velodyne_msgs/msg/VelodyneScan",
            type_hash="TypeHashNotSupported", qos=(1, 2, 10),
        )  # fmt: skip
        ctx.graph.put(key)
        report = _observe(ctx)
    (f,) = report.find("topics.undecodable")
    assert f.evidence == {"topic": "/lidar/packets", "type": "velodyne_msgs/msg/VelodyneScan"}
    assert not report.find("rates.no_messages")


@pytest.fixture
def drone_graph(start_script: Callable[..., subprocess.Popen[str]]) -> subprocess.Popen[str]:
    return start_script(SCRIPTS / "drone_graph.py", "30")


def test_cross_process_graph_through_the_cli(
    drone_graph: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["doctor", "--duration", "1.0", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 1
    by_check = {f["check"]: f for f in out["findings"]}
    ns = by_check["topics.namespace_mismatch"]
    assert ns["title"] == (
        "subscriber waiting on /camera/depth/points while /drone/camera/depth/points exists"
    )
    qos = by_check["topics.qos_incompatible"]
    assert qos["evidence"]["subscriber"] == "/viewer"
    assert out["summary"]["nodes"] == 3
    clouds = [t for t in out["findings"] if t["subject"] == "/drone/camera/depth/points"]
    assert not [c for c in clouds if c["check"] == "rates.no_messages"]
