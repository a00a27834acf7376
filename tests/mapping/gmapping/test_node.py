"""The ``slam_gmapping`` node on a graph: scans and TF in; map, map -> odom, dynamic_map out."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.mapping.gmapping import GmappingError
from visnav.mapping.gmapping.node import SlamGmappingNode, laser_geometry
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import (
    Header,
    LaserScan,
    MapMetaData,
    OccupancyGrid,
    Quaternion,
    TFMessage,
    Transform,
    TransformStamped,
    Vector3,
)
from visnav.node_registry import resolve_node_class
from visnav.tf.ros import StaticTransformBroadcaster, TransformBroadcaster

GMAPPING_PARAMS = {  # ROBOTIS' turtlebot3_slam/config/gmapping_params.yaml, as written
    "map_update_interval": 2.0, "maxUrange": 3.0, "sigma": 0.05, "kernelSize": 1, "lstep": 0.05,
    "astep": 0.05, "iterations": 5, "lsigma": 0.075, "ogain": 3.0, "lskip": 0, "minimumScore": 50,
    "srr": 0.1, "srt": 0.2, "str": 0.1, "stt": 0.2, "linearUpdate": 1.0, "angularUpdate": 0.2,
    "temporalUpdate": 0.5, "resampleThreshold": 0.5, "particles": 100, "xmin": -10.0,
    "ymin": -10.0, "xmax": 10.0, "ymax": 10.0, "delta": 0.05, "llsamplerange": 0.01,
    "llsamplestep": 0.01, "lasamplerange": 0.005, "lasamplestep": 0.005,
}  # fmt: skip


def _tf(
    parent: str, child: str, pose: Any, ns: int, *, z: float = 0.0, roll: float = 0.0
) -> TransformStamped:
    x, y, yaw = (float(v) for v in pose)
    q = Rotation.from_euler("xyz", [roll, 0.0, yaw]).as_quat()
    return TransformStamped(
        header=Header(stamp=ns_to_time(ns), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=y, z=z),
            rotation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])),
        ),
    )


def _scan(d: SimpleNamespace, i: int, ns: int, frame: str = "base_scan") -> LaserScan:
    n = len(d.angles)
    return LaserScan(
        header=Header(stamp=ns_to_time(ns), frame_id=frame),
        angle_min=d.angle_min, angle_max=d.angle_min + (n - 1) * d.angle_increment,
        angle_increment=d.angle_increment, time_increment=0.0, scan_time=0.2,
        range_min=d.range_min, range_max=d.range_max,
        ranges=d.ranges[i].astype(np.float32), intensities=np.zeros(0, dtype=np.float32),
    )  # fmt: skip


def _stamp(ns_msg: Any) -> int:
    return int(ns_msg.sec) * 1_000_000_000 + int(ns_msg.nanosec)


def test_parameters_are_gmappings_names_and_defaults() -> None:
    assert resolve_node_class("slam_gmapping") is SlamGmappingNode
    with Context(transport="local") as ctx:
        node = SlamGmappingNode(context=ctx)
        got = dict(node.parameters)
        assert {k: got[k] for k in ("particles", "delta", "sigma", "kernelSize", "lstep")} == {
            "particles": 30, "delta": 0.05, "sigma": 0.05, "kernelSize": 1, "lstep": 0.05,
        }  # fmt: skip
        assert (got["srr"], got["srt"], got["str"], got["stt"]) == (0.1, 0.2, 0.1, 0.2)
        assert (got["linearUpdate"], got["angularUpdate"], got["temporalUpdate"]) == (
            1.0,
            0.5,
            -1.0,
        )
        assert (got["map_update_interval"], got["occ_thresh"], got["throttle_scans"]) == (
            5.0,
            0.25,
            1,
        )
        assert (got["base_frame"], got["odom_frame"], got["map_frame"]) == (
            "base_link",
            "odom",
            "map",
        )
        tb3 = SlamGmappingNode(
            "turtlebot3_slam_gmapping", context=ctx, parameter_overrides=GMAPPING_PARAMS
        )
        assert tb3.filter_params.particles == 100
        assert tb3.filter_params.minimumScore == 50.0
        assert tb3.params.map_update_interval == 2.0


def test_upside_down_laser_mirrors_its_beams_and_a_tilted_one_is_refused(
    tb3_drive: SimpleNamespace,
) -> None:
    scan = _scan(tb3_drive, 0, 0)
    upright = np.eye(4)
    flipped = np.eye(4)
    flipped[:3, :3] = Rotation.from_euler("x", math.pi).as_matrix()
    a = laser_geometry(upright, scan).angles
    b = laser_geometry(flipped, scan).angles
    np.testing.assert_allclose(np.sin(b), -np.sin(a), atol=1e-12)  # beam i goes the other way
    np.testing.assert_allclose(np.cos(b), np.cos(a), atol=1e-12)
    default_max = tb3_drive.range_max - 0.01  # slam_gmapping's maxRange when not set
    assert laser_geometry(upright, scan).max_range == pytest.approx(default_max)
    assert laser_geometry(upright, scan, max_range=3.0, usable_range=2.0).usable_range == 2.0
    tilted = np.eye(4)
    tilted[:3, :3] = Rotation.from_euler("y", 0.2).as_matrix()
    with pytest.raises(GmappingError, match="tilted"):
        laser_geometry(tilted, scan)


@pytest.mark.slow
@pytest.mark.ci
def test_node_maps_the_drive_and_publishes_like_slam_gmapping(tb3_drive: SimpleNamespace) -> None:
    d = tb3_drive
    odo = d.odometry(d.truth, 0)
    overrides = {
        "base_frame": "base_footprint", "particles": 15, "maxUrange": 3.0, "minimumScore": 50.0,
        "linearUpdate": 0.3, "angularUpdate": 0.2, "temporalUpdate": 0.5,
        "map_update_interval": 1.0, "xmin": -5.0, "ymin": -5.0, "xmax": 5.0, "ymax": 5.0,
        "transform_publish_period": 0.05,
    }  # fmt: skip
    float64 = get_message_class("std_msgs/msg/Float64")
    with Context(transport="local") as ctx:
        src = Node("feeder", context=ctx)
        scan_pub = src.create_publisher(LaserScan, "/scan", 5)
        tf = TransformBroadcaster(src)
        t = d.T_base_laser
        StaticTransformBroadcaster(src).send_transform(
            _tf("base_footprint", "base_scan", (t[0, 3], t[1, 3], 0.0), 0, z=float(t[2, 3]))
        )
        node = SlamGmappingNode(context=ctx, parameter_overrides=overrides)
        maps: list[OccupancyGrid] = []
        metas: list[MapMetaData] = []
        entropies: list[Any] = []
        tfs: list[TFMessage] = []
        sink = Node("sink", context=ctx)
        sink.create_subscription(OccupancyGrid, "/map", maps.append, qos_profile_latched)
        sink.create_subscription(MapMetaData, "/map_metadata", metas.append, qos_profile_latched)
        sink.create_subscription(
            float64, "/slam_gmapping/entropy", entropies.append, qos_profile_latched
        )
        sink.create_subscription(TFMessage, "/tf", tfs.append, 1000)
        ctx.spin_some()
        for i in range(120):
            ns = round(d.stamps[i] * 1e9) + 1_000_000_000
            tf.send_transform(_tf("odom", "base_footprint", odo[i], ns))
            ctx.spin_some()
            scan_pub.publish(_scan(d, i, ns))
            ctx.spin_some()
        assert ctx.spin_until(
            lambda: any(tr.header.frame_id == "map" for m in tfs for tr in m.transforms), 5.0
        )
        assert node.scans_processed > 10
        assert node.map_updates >= 2
        assert maps
        assert metas
        assert entropies
        grid = maps[-1]
        assert grid.header.frame_id == "map"
        assert (grid.info.width, grid.info.height) == (metas[-1].width, metas[-1].height)
        assert grid.info.resolution == pytest.approx(0.05)
        data = np.asarray(grid.data)
        assert set(np.unique(data)) <= {-1, 0, 100}
        assert (data == 100).sum() > 200
        assert (data == 0).sum() > 2000
        assert entropies[-1].data >= 0.0
        # map -> odom carries the correction: map -> base is the truth, odometry drifted
        mo = [tr for m in tfs for tr in m.transforms if tr.header.frame_id == "map"][-1]
        assert mo.child_frame_id == "odom"
        x, y, yaw = node.map_to_odom
        c, s = math.cos(yaw), math.sin(yaw)
        ox, oy, _ = odo[119]
        est = (x + c * ox - s * oy, y + s * ox + c * oy)
        assert math.hypot(est[0] - d.truth[119, 0], est[1] - d.truth[119, 1]) < 0.05
        assert math.hypot(ox - d.truth[119, 0], oy - d.truth[119, 1]) > 0.05
        # dynamic_map answers with the published map
        get_map = get_service_type("nav_msgs/srv/GetMap")
        client = sink.create_client(get_map, "/dynamic_map")
        future = client.call_async(get_map.Request())
        assert ctx.spin_until(future.done, 5.0)
        reply = future.result().map
        assert (reply.info.width, reply.info.height) == (grid.info.width, grid.info.height)
        np.testing.assert_array_equal(np.asarray(reply.data), data)
