"""The ``amcl`` node on a graph: map, TF and scans in; map -> odom, amcl_pose, status out."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import visnav
from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.mapping.amcl_node import AmclNode
from visnav.mapping.map_io import MapMetadata, OccupancyMap, save_map
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import (
    Header,
    LaserScan,
    OccupancyGrid,
    PoseWithCovarianceStamped,
    Quaternion,
    String,
    TFMessage,
    Transform,
    TransformStamped,
    Vector3,
)
from visnav.node_registry import resolve_node_class
from visnav.tf.ros import StaticTransformBroadcaster, TransformBroadcaster

LATCHED = qos_profile_latched
ANGLES = np.linspace(-0.76, 0.76, 160)


def _tf(parent: str, child: str, x: float, y: float, yaw: float, ns: int) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=ns_to_time(ns), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=y, z=0.0),
            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        ),
    )


def _drive(
    amcl_world: SimpleNamespace, domain: int, initial: tuple[float, float, float]
) -> tuple[AmclNode, list[TFMessage], list[PoseWithCovarianceStamped], list[String]]:
    w = amcl_world
    grid = w.office_grid()
    meta = MapMetadata(image=Path("x"), resolution=w.RES, origin=w.ORIGIN)
    truth = w.square_drive(40)
    with Context(domain) as ctx:
        src = Node("feeder", context=ctx)
        src.create_publisher(OccupancyGrid, "/map", LATCHED).publish(
            OccupancyMap(grid, meta).to_msg()
        )
        scan_pub = src.create_publisher(LaserScan, "/scan", 5)
        tf = TransformBroadcaster(src)
        StaticTransformBroadcaster(src).send_transform(
            _tf("base_footprint", "laser", 0.0, 0.0, 0.0, 0)
        )
        x, y, yaw = initial
        node = AmclNode(
            context=ctx,
            parameter_overrides={
                "set_initial_pose": True, "initial_pose.x": x, "initial_pose.y": y,
                "initial_pose.yaw": yaw, "update_min_d": 0.1, "update_min_a": 0.1,
            },
        )  # fmt: skip
        tfs: list[TFMessage] = []
        poses: list[PoseWithCovarianceStamped] = []
        status: list[String] = []
        sink = Node("sink", context=ctx)
        sink.create_subscription(TFMessage, "/tf", tfs.append, 50)
        sink.create_subscription(PoseWithCovarianceStamped, "/amcl_pose", poses.append, LATCHED)
        sink.create_subscription(String, "/amcl/status", status.append, LATCHED)
        ctx.spin_some()
        for k, p in enumerate(truth):
            ns = (k + 1) * 100_000_000
            tf.send_transform(_tf("odom", "base_footprint", *p, ns))  # odom = truth here
            ctx.spin_some()
            ranges = w.raycast(grid, p, ANGLES).astype(np.float32)
            scan_pub.publish(
                LaserScan(
                    header=Header(stamp=ns_to_time(ns), frame_id="laser"),
                    angle_min=-0.76, angle_max=0.76, angle_increment=float(ANGLES[1] - ANGLES[0]),
                    time_increment=0.0, scan_time=0.1, range_min=0.1, range_max=10.0,
                    ranges=ranges, intensities=np.zeros(0, dtype=np.float32),
                )
            )  # fmt: skip
            ctx.spin_some()
        ctx.spin_some()
    return node, tfs, poses, status


def _map_odom(tfs: list[TFMessage]) -> list[TransformStamped]:
    return [t for m in tfs for t in m.transforms if t.header.frame_id == "map"]


@pytest.mark.slow
@pytest.mark.ci
def test_amcl_node_localises_and_publishes(amcl_world: SimpleNamespace, domain: int) -> None:
    assert resolve_node_class("amcl") is AmclNode
    start = amcl_world.square_drive(1)[0]
    node, tfs, poses, status = _drive(amcl_world, domain, (start[0] + 0.1, start[1], start[2]))
    assert node.updates > 3
    published = _map_odom(tfs)
    assert published, [s.data for s in status]
    last = published[-1]
    assert last.child_frame_id == "odom"
    # odom is the truth here, so map -> odom should be near the identity
    assert math.hypot(last.transform.translation.x, last.transform.translation.y) < 0.08
    stamp = last.header.stamp.sec + last.header.stamp.nanosec * 1e-9
    assert stamp == pytest.approx(4.0 + 1.0, abs=1e-6)  # last scan + transform_tolerance
    assert poses[-1].header.frame_id == "map"
    assert status[-1].data.startswith("localized")


@pytest.mark.slow
@pytest.mark.ci
def test_amcl_node_outside_the_map_gives_no_map_to_odom(
    amcl_world: SimpleNamespace, domain: int
) -> None:
    _, tfs, _, status = _drive(amcl_world, domain, (60.0, 60.0, 0.0))
    assert _map_odom(tfs) == []
    assert status[-1].data.startswith("not_converged: cannot localise")
    assert "outside the map" in status[-1].data


@pytest.mark.slow
@pytest.mark.ci
def test_car_with_a_map_of_elsewhere_does_not_drive(tmp_path: Path, domain: int) -> None:
    """`--map` of a map the spawn lies far outside: amcl refuses, the car stays put."""

    grid = np.zeros((60, 80), dtype=np.int8)
    grid[0, :] = grid[-1, :] = 100
    meta = MapMetadata(image=Path("x"), resolution=0.05, origin=(40.0, 30.0, 0.0))
    yaml_path, _ = save_map(OccupancyMap(grid, meta).to_msg(), tmp_path / "elsewhere")
    launch = Path(visnav.__file__).parent / "scenarios" / "launch" / "car.launch.yaml"
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "launch", str(launch), "seed:=0",
         "slam:=false", "ideal_sensors:=false", "use_map:=true", f"map:={yaml_path}",
         "duration:=3.0", f"out:={out}"],
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert "not_converged: cannot localise: the initial pose (-6.00, -1.50) is outside" in (
        proc.stderr + proc.stdout
    ), proc.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["localization"]["source"] == "amcl"
    assert summary["goals_reached"] == 0
    assert summary["odometry"]["distance_m"] < 0.01  # the navigator never drove
