"""message_filters on the real graph (in-process transport): Subscriber -> synchronizers."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from visnav import message_filters
from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, Header, Point, Pose, PoseStamped, Quaternion, Time
from visnav.perception.camera_info_yaml import camera_info_from_matrices


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _imu(sec: int, nanosec: int) -> PoseStamped:
    """A stamped message (the synchronizers only look at header.stamp)."""
    pose = Pose(
        position=Point(x=0.0, y=0.0, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    )
    return PoseStamped(
        header=Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id="imu"), pose=pose
    )


def test_subscribers_into_approximate_time(ctx: Context) -> None:
    node = Node("sync_test", namespace="/robot", context=ctx)
    pub_a = node.create_publisher(PoseStamped, "a", 10)
    pub_b = node.create_publisher(PoseStamped, "b", 10)
    sub_a = message_filters.Subscriber(node, PoseStamped, "a")
    sub_b = message_filters.Subscriber(node, PoseStamped, "b")
    assert sub_a.get_topic() == "/robot/a"
    sync = message_filters.ApproximateTime([sub_a, sub_b], 10)
    pairs: list[tuple[int, int]] = []
    sync.register_callback(
        lambda x, y: pairs.append((x.header.stamp.nanosec, y.header.stamp.nanosec))
    )
    for ms_a, ms_b in [(0, 2), (100, 103), (200, 199), (300, 301)]:
        pub_a.publish(_imu(1, ms_a * 1_000_000))
        pub_b.publish(_imu(1, ms_b * 1_000_000))
    ctx.spin_until(lambda: len(pairs) >= 3, 2.0)
    assert pairs == [(0, 2_000_000), (100_000_000, 103_000_000), (200_000_000, 199_000_000)]


def test_subscriber_into_cache_and_exact_sync(ctx: Context) -> None:
    node = Node("cache_test", context=ctx)
    pub = node.create_publisher(PoseStamped, "imu", 10)
    info_pub = node.create_publisher(CameraInfo, "info", 10)
    imu_sub = message_filters.Subscriber(node, PoseStamped, "imu")
    cache = message_filters.Cache(imu_sub, cache_size=3)
    got: list[Any] = []
    info_sub = message_filters.Subscriber(node, CameraInfo, "info")
    exact = message_filters.TimeSynchronizer([imu_sub, info_sub], 5)
    exact.register_callback(lambda a, b: got.append((a, b)))
    for k in range(5):
        pub.publish(_imu(k, 0))
    header = Header(stamp=Time(sec=4, nanosec=0), frame_id="cam")
    info = camera_info_from_matrices(
        (4, 3),
        "plumb_bob",
        [0.0] * 5,
        [1, 0, 2, 0, 1, 1.5, 0, 0, 1],
        [1, 0, 0, 0, 1, 0, 0, 0, 1],
        [1, 0, 2, 0, 0, 1, 1.5, 0, 0, 0, 1, 0],
        header=header,
    )
    info_pub.publish(info)
    ctx.spin_until(lambda: len(got) == 1 and len(cache) == 3, 2.0)
    assert cache.get_oldest_time() == 2_000_000_000
    assert cache.get_elem_before_time(3_500_000_000).header.stamp.sec == 3
    assert got[0][1] is info
    imu_sub.unregister()
    pub.publish(_imu(9, 0))
    ctx.spin_some()
    assert cache.get_latest_time() == 4_000_000_000
