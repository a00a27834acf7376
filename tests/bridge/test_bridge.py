"""The bridge between a visnav graph and a ROS 1 graph (visnav's master and ROS 1 node as peer)."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.bridge.bridge import BridgeOptions, Ros1Bridge, topic_selected
from visnav.bridge.master import Ros1Master
from visnav.bridge.master_api import MasterClient
from visnav.bridge.ros1_node import Ros1Node
from visnav.bridge.typemap import cdr_to_ros1, ros1_to_cdr, ros1_type
from visnav.graph import Context, Node, Subscription
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import Clock, String, Twist, Vector3
from visnav.msgs.serde import deserialize, get_message_class, serialize
from visnav.msgs.time import ns_to_time
from visnav.node_registry import resolve_node_class

STRING = ros1_type("std_msgs/msg/String")
TWIST = ros1_type("geometry_msgs/msg/Twist")


class _Graphs:
    def __init__(self) -> None:
        self.master = Ros1Master(0)
        self.master.start()
        self.ctx = Context(transport="local")
        self.ros1_bridge = Ros1Node("visnav_bridge", master_uri=self.master.uri, host="127.0.0.1")
        self.ros1_bridge.start()
        self.node = Node("ros1_bridge", context=self.ctx)
        self.peer = Ros1Node("peer", master_uri=self.master.uri, host="127.0.0.1")
        self.peer.start()
        self.bridge: Ros1Bridge | None = None

    def start(self, **options: Any) -> Ros1Bridge:
        self.bridge = Ros1Bridge(
            self.node, self.ros1_bridge, BridgeOptions(scan_period_s=0.05, **options)
        )
        return self.bridge

    def spin_until(self, pred: Callable[[], bool], timeout_s: float = 5.0) -> bool:
        return self.ctx.spin_until(pred, timeout_s)

    def close(self) -> None:
        if self.bridge is not None:
            self.bridge.close()
        self.peer.close()
        self.ros1_bridge.close()
        self.ctx.shutdown()
        self.master.close()


@pytest.fixture
def graphs() -> Iterator[_Graphs]:
    g = _Graphs()
    yield g
    g.close()


def test_visnav_topic_reaches_ros1(graphs: _Graphs) -> None:
    talker = Node("talker", context=graphs.ctx)
    pub = talker.create_publisher(String, "/chatter", 10)
    bridge = graphs.start()
    assert graphs.spin_until(lambda: bridge.out_topics() == ["/chatter"])
    types = MasterClient(graphs.master.uri, "/t").topic_types()
    assert types["/chatter"] == "std_msgs/String"
    got: list[bytes] = []
    graphs.peer.subscribe("/chatter", STRING, got.append)
    n = [0]

    def more() -> bool:
        n[0] += 1
        pub.publish(String(data=f"hi {n[0]}"))
        return len(got) >= 3

    assert graphs.spin_until(more)
    text = deserialize(ros1_to_cdr(got[-1], STRING), "std_msgs/msg/String").data
    assert text.startswith("hi ")


def test_ros1_topic_reaches_visnav_without_loop(graphs: _Graphs) -> None:
    listener = Node("listener", context=graphs.ctx)
    got: list[Any] = []
    listener.create_subscription(Twist, "/cmd_vel", got.append, 10)
    # a visnav publisher on the same topic too: bridged out, but the bridge's own
    # messages from ROS 1 must not go back out
    listener.create_publisher(Twist, "/cmd_vel", 10)
    bridge = graphs.start()
    graphs.peer.advertise("/cmd_vel", TWIST)
    assert graphs.spin_until(lambda: bridge.in_topics() == ["/cmd_vel"])
    echoed: list[bytes] = []
    graphs.peer.subscribe("/cmd_vel", TWIST, echoed.append)
    twist = Twist(linear=Vector3(x=0.5, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.1))
    raw = cdr_to_ros1(serialize(twist), TWIST)

    def sent() -> bool:
        graphs.peer.publish("/cmd_vel", raw)
        return len(got) >= 3

    assert graphs.spin_until(lambda: graphs.ros1_bridge.publisher_uris("/cmd_vel") != [])
    assert graphs.spin_until(sent)
    assert got[-1].linear.x == 0.5
    assert not TWIST.header_first
    graphs.ctx.spin(duration_s=0.3)
    assert echoed == []  # nothing came back out through the bridge


def test_patterns_and_unconvertible_types(
    graphs: _Graphs, caplog: pytest.LogCaptureFixture
) -> None:
    talker = Node("talker", context=graphs.ctx)
    talker.create_publisher(String, "/keep/a", 10)
    talker.create_publisher(String, "/keep/skip", 10)
    talker.create_publisher(String, "/other", 10)
    marker = get_message_class("visualization_msgs/msg/Marker")
    talker.create_publisher(marker, "/keep/marker", 10)
    with caplog.at_level(logging.WARNING):
        bridge = graphs.start(topics=("/keep/*",), exclude=("*/skip",))
        assert graphs.spin_until(lambda: bridge.out_topics() == ["/keep/a"])
        graphs.ctx.spin(duration_s=0.2)
    warnings = [r.getMessage() for r in caplog.records if "/keep/marker" in r.getMessage()]
    assert len(warnings) == 1
    assert "visualization_msgs/Marker" in warnings[0]


def test_topic_selected() -> None:
    assert topic_selected("/a/b", (), ())
    assert not topic_selected("/a/b", ("/c*",), ())
    assert not topic_selected("/a/b", (), ("/a/*",))


def test_latched_clock_and_description_set_ros1_conventions(graphs: _Graphs) -> None:
    sim = Node("sim", context=graphs.ctx)
    latched = qos_profile_latched
    desc = sim.create_publisher(String, "/robot_description", latched)
    desc.publish(String(data="<robot name='car'/>"))
    clock = sim.create_publisher(Clock, "/clock", 1)
    bridge = graphs.start()
    client = MasterClient(graphs.master.uri, "/t")

    def params() -> bool:
        clock.publish(Clock(clock=ns_to_time(1)))
        try:
            return client.get_param("/robot_description") == "<robot name='car'/>" and bool(
                client.get_param("/use_sim_time")
            )
        except Exception:  # noqa: BLE001 - not set yet
            return False

    assert graphs.spin_until(params)
    assert "/robot_description" in bridge.out_topics()
    got: list[bytes] = []
    graphs.peer.subscribe("/robot_description", STRING, got.append)  # latched: arrives late
    assert graphs.spin_until(lambda: len(got) == 1)


def test_launch_node_serves_a_master() -> None:
    cls = resolve_node_class("ros1_bridge")
    with Context(transport="local") as ctx:
        node = cls(
            context=ctx,
            parameter_overrides={"serve_master_port": _free_port(), "topics": ["/x"]},
        )
        try:
            client = MasterClient(node.master.uri, "/t")
            assert client.call("lookupNode", "/visnav_bridge") == node.ros1.uri
            assert node.bridge.options.topics == ("/x",)
        finally:
            node.destroy_node()


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_burst_keeps_order_and_newest(graphs: _Graphs) -> None:
    """A burst faster than the socket: the oldest are dropped (roscpp queue), order kept."""
    talker = Node("talker", context=graphs.ctx)
    pub = talker.create_publisher(String, "/burst", 100)
    bridge = graphs.start()
    got: list[bytes] = []
    graphs.peer.subscribe("/burst", STRING, got.append)
    assert graphs.spin_until(lambda: "/burst" in bridge.out_topics())
    assert graphs.spin_until(lambda: graphs.ros1_bridge.subscriber_count("/burst") == 1)
    graphs.ctx.spin(duration_s=0.2)  # the bridge's visnav subscription follows demand
    for i in range(100):
        pub.publish(String(data=str(i)))
        graphs.ctx.spin_some()

    def values() -> list[int]:
        return [int(deserialize(ros1_to_cdr(g, STRING), STRING.ros2_name).data) for g in got]

    assert graphs.spin_until(lambda: bool(got) and values()[-1] == 99)
    time.sleep(0.05)
    seen = values()
    assert seen == sorted(set(seen))
    assert len(seen) >= 10  # at least the queue's worth arrives


def test_header_seq_numbered_as_rospy(graphs: _Graphs) -> None:
    from visnav.msgs import Header, PoseStamped

    stamped = ros1_type("geometry_msgs/msg/PoseStamped")
    assert stamped.header_first
    talker = Node("talker", context=graphs.ctx)
    pub = talker.create_publisher(PoseStamped, "/pose", 10)
    bridge = graphs.start()
    assert graphs.spin_until(lambda: "/pose" in bridge.out_topics())
    got: list[bytes] = []
    graphs.peer.subscribe("/pose", stamped, lambda b: got.append(bytes(b)))
    pose = get_message_class("geometry_msgs/msg/Pose")
    point = get_message_class("geometry_msgs/msg/Point")(x=1.0, y=2.0, z=3.0)
    quat = get_message_class("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0)
    msg = PoseStamped(
        header=Header(stamp=ns_to_time(5), frame_id="map"),
        pose=pose(position=point, orientation=quat),
    )

    def more() -> bool:
        pub.publish(msg)
        return len(got) >= 3

    assert graphs.spin_until(more)
    seqs = [int.from_bytes(g[:4], "little") for g in got]
    assert seqs == sorted(seqs)
    assert seqs[0] >= 1
    assert len(set(seqs)) == len(seqs)
    back = deserialize(ros1_to_cdr(got[-1], stamped), stamped.ros2_name)
    assert back.header.frame_id == "map"
    assert back.pose.position.y == 2.0


def test_latched_ros1_map_reaches_late_visnav_publisher(graphs: _Graphs) -> None:
    from visnav.msgs import Header, OccupancyGrid

    listener = Node("listener", context=graphs.ctx)
    got: list[Any] = []
    latched = qos_profile_latched
    listener.create_subscription(OccupancyGrid, "/map", got.append, latched)
    bridge = graphs.start()
    assert graphs.spin_until(lambda: bridge.in_topics() == ["/map"])
    graphs.ctx.spin(duration_s=0.2)
    # no ROS 1 publisher yet: the bridge publishes nothing on the visnav side
    assert [e.node_name for e in graphs.ctx.graph.endpoints("/map") if e.kind == "publisher"] == []
    grid_t = ros1_type("nav_msgs/msg/OccupancyGrid")
    meta = get_message_class("nav_msgs/msg/MapMetaData")
    pose = get_message_class("geometry_msgs/msg/Pose")
    point = get_message_class("geometry_msgs/msg/Point")(x=0.0, y=0.0, z=0.0)
    quat = get_message_class("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0)
    grid = OccupancyGrid(
        header=Header(stamp=ns_to_time(0), frame_id="map"),
        info=meta(
            map_load_time=ns_to_time(0),
            resolution=0.05,
            width=2,
            height=2,
            origin=pose(position=point, orientation=quat),
        ),
        data=np.array([0, 100, -1, 0], dtype=np.int8),
    )
    graphs.peer.advertise("/map", grid_t, latch=True)
    graphs.peer.publish("/map", cdr_to_ros1(serialize(grid), grid_t))  # once, before connecting
    assert graphs.spin_until(lambda: len(got) == 1)
    assert list(got[0].data) == [0, 100, -1, 0]
    pubs = [e.node_name for e in graphs.ctx.graph.endpoints("/map") if e.kind == "publisher"]
    assert pubs == ["ros1_bridge"]


def test_master_gone_is_logged_once_and_bridge_keeps_scanning(
    graphs: _Graphs, caplog: pytest.LogCaptureFixture
) -> None:
    bridge = graphs.start()
    graphs.master.close()
    talker = Node("talker", context=graphs.ctx)
    talker.create_publisher(String, "/late", 10)
    with caplog.at_level(logging.ERROR):
        graphs.ctx.spin(duration_s=0.6)  # about 12 scans
    errors = [r.getMessage() for r in caplog.records if "no ROS 1 master" in r.getMessage()]
    assert len(errors) == 1
    assert graphs.master.uri in errors[0]
    assert bridge.out_topics() == []


@settings(max_examples=40, deadline=None)
@given(
    frame_id=st.text(max_size=9),
    encoding=st.sampled_from(["rgb8", "mono8", "bgra8", "16UC1"]),
    size=st.integers(0, 37),
    remote=st.booleans(),
)
def test_image_bytes_sent_as_they_are_equal_the_full_conversion(
    frame_id: str, encoding: str, size: int, remote: bool
) -> None:
    from visnav.bridge.bridge import _Out
    from visnav.msgs import Header, Image

    rtype = ros1_type("sensor_msgs/msg/Image")
    assert rtype.byte_tail == "data"
    pixels = np.arange(size, dtype=np.uint8)
    msg = Image(
        header=Header(stamp=ns_to_time(123_456_789), frame_id=frame_id),
        height=1,
        width=size,
        encoding=encoding,
        is_bigendian=0,
        step=size,
        data=pixels,
    )
    out = _Out("/img", rtype, latch=False)
    head, tail = Ros1Bridge._to_ros1(out, msg, copy=not remote)
    assert tail is not None
    assert bytes(head) + bytes(tail) == bytes(cdr_to_ros1(serialize(msg), rtype))
    pixels[:] = 7 if size else pixels  # a local publisher reusing its array after publish
    assert bytes(tail) == (bytes([7] * size) if remote else bytes(range(size)))


def test_byte_tail_types_and_fallbacks() -> None:
    from visnav.bridge.bridge import _Out
    from visnav.msgs import Header, MapMetaData, OccupancyGrid, Point, Pose, Quaternion

    assert ros1_type("sensor_msgs/msg/CompressedImage").byte_tail == "data"
    assert ros1_type("nav_msgs/msg/OccupancyGrid").byte_tail == "data"
    assert ros1_type("sensor_msgs/msg/PointCloud2").byte_tail is None  # is_dense comes after
    assert STRING.byte_tail is None
    grid_t = ros1_type("nav_msgs/msg/OccupancyGrid")
    grid = OccupancyGrid(
        header=Header(stamp=ns_to_time(5), frame_id="map"),
        info=MapMetaData(
            map_load_time=ns_to_time(0),
            resolution=0.05,
            width=3,
            height=2,
            origin=Pose(
                position=Point(x=1.0, y=2.0, z=0.0),
                orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        ),
        data=np.array([-1, 0, 100, 50, -1, 0], dtype=np.int8),
    )
    full = bytes(cdr_to_ros1(serialize(grid), grid_t))
    head, tail = Ros1Bridge._to_ros1(_Out("/map", grid_t, latch=True), grid, copy=False)
    assert tail is not None
    assert bytes(head) + bytes(tail) == full
    grid.data = np.array([-1, 5, 0, 9, 1, 2, 3, 4, 5, 6, 7, 8], dtype=np.int8)[::2]  # strided
    full = bytes(cdr_to_ros1(serialize(grid), grid_t))
    payload, none = Ros1Bridge._to_ros1(_Out("/map", grid_t, latch=True), grid, copy=False)
    assert none is None
    assert bytes(payload) == full


def test_flood_from_another_process_is_paced_by_the_ros1_subscriber(
    domain: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A visnav publisher floods images: the bridge converts about what ROS 1 takes."""
    from visnav.msgs import Header, Image

    image = ros1_type("sensor_msgs/msg/Image")
    master = Ros1Master(0)
    master.start()
    ros1 = Ros1Node("visnav_bridge", master_uri=master.uri, host="127.0.0.1")
    ros1.start()
    peer = Ros1Node("peer", master_uri=master.uri, host="127.0.0.1")
    peer.start()
    converted: list[int] = []
    real_convert = Ros1Bridge._convert

    def counting_convert(self: Ros1Bridge, out: Any, data: Any) -> Any:
        converted.append(1)
        return real_convert(self, out, data)

    monkeypatch.setattr(Ros1Bridge, "_convert", counting_convert)
    pauses: list[int] = []
    real_pause = Subscription.pause

    def counting_pause(self: Subscription[Any]) -> None:
        pauses.append(1)
        real_pause(self)

    monkeypatch.setattr(Subscription, "pause", counting_pause)
    with Context(domain) as bctx, Context(domain) as pctx:
        bridge = Ros1Bridge(
            Node("ros1_bridge", context=bctx), ros1, BridgeOptions(scan_period_s=0.05)
        )
        pub = Node("camera", context=pctx).create_publisher(Image, "/img", 2)
        got: list[int] = []

        def slow_reader(raw: bytearray) -> None:
            msg = deserialize(ros1_to_cdr(raw, image), image.ros2_name)
            got.append(int(msg.header.stamp.nanosec))
            time.sleep(0.02)  # a ROS 1 subscriber that takes 50 images/s

        peer.subscribe("/img", image, slow_reader)
        sent = [0]
        frames = [np.full(640 * 480 * 3, v, np.uint8) for v in (0, 1)]

        def publish() -> None:
            sent[0] += 1
            pub.publish(
                Image(
                    header=Header(stamp=ns_to_time(sent[0]), frame_id="cam"),
                    height=480,
                    width=640,
                    encoding="rgb8",
                    is_bigendian=0,
                    step=640 * 3,
                    data=frames[sent[0] % 2],
                )
            )

        def flowing() -> bool:
            publish()
            return len(got) >= 3

        assert bctx.spin_until(flowing, 15.0)
        zpub = pub._zpub
        assert zpub is not None
        before_sent, before_got, before_conv = sent[0], len(got), len(converted)
        before_skipped, before_pauses = zpub.skipped, len(pauses)
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:  # flood: many times what the reader takes
            publish()
            bctx.spin_some()
        bctx.spin(duration_s=0.5)
        flood, taken, conv = (
            sent[0] - before_sent,
            len(got) - before_got,
            len(converted) - before_conv,
        )
        sub = bridge._out["/img"].sub
        assert sub is not None
        assert sub.paced
        assert flood > 5 * taken  # it was a flood
        # converted: what was sent (the reader's, and what fits in the sockets' buffers)
        assert conv <= taken + 20
        assert sub.dropped > flood // 2  # dropped inside Zenoh, counted from the sequence
        # most were never sent: the publisher heard that the bridge's subscription paused
        assert zpub.skipped - before_skipped > flood // 2
        # a pause lets PACE_AHEAD - PACE_RESUME messages through, not one
        assert len(pauses) - before_pauses <= conv // 2 + 2
        assert got == sorted(got)
        bridge.close()
    peer.close()
    ros1.close()
    master.close()
