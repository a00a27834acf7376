"""Recording from a real graph and reading back the same messages, every format/compression."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from visnav.bag import BagReader, BagRecorder, bag_info, read_bag
from visnav.graph import Context, Node, QoSProfile, ReliabilityPolicy
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import Clock, String, ns_to_time

TOPICS = ["/image", "/camera_info", "/tf", "/chatter"]


@pytest.mark.parametrize(
    ("fmt", "compression"),
    [
        ("mcap", "none"),
        ("mcap", "zstd"),
        ("mcap", "lz4"),
        ("ros1", "none"),
        ("ros1", "lz4"),
        ("ros1", "bz2"),
    ],
)
def test_record_round_trip(
    tmp_path: Path, local_ctx: Context, bagdata: Any, fmt: str, compression: str
) -> None:
    node = Node("talker", context=local_ctx)
    pubs = {t: node.create_publisher(bagdata.TYPES[t], t, 10) for t in TOPICS}
    rec = BagRecorder(local_ctx, TOPICS, tmp_path / "bag", fmt=fmt, compression=compression)
    rec.start()
    sent: list[tuple[str, Any]] = []
    for i in range(5):
        for t in TOPICS:
            msg = bagdata.sample(t, i)
            pubs[t].publish(msg)
            sent.append((t, msg))
        local_ctx.spin_some()
    path = rec.stop()
    assert path == (tmp_path / "bag.bag" if fmt == "ros1" else tmp_path / "bag")
    assert {t: r.count for t, r in rec.topics.items()} == dict.fromkeys(TOPICS, 5)
    got = list(read_bag(path))
    assert len(got) == len(sent)
    for topic in TOPICS:
        want = [bagdata.as_dict(m) for t, m in sent if t == topic]
        have = [g for g in got if g.topic == topic]
        assert [bagdata.as_dict(g.msg) for g in have] == want
        assert all(type(g.msg) is bagdata.TYPES[topic] for g in have)
        assert [g.type_name for g in have] == [bagdata.TYPES[topic].__msgtype__] * 5
    times = [g.t_ns for g in got]
    assert times == sorted(times)
    assert abs(times[0] - time.time_ns()) < 60e9  # receive time (wall clock)
    info = bag_info(path)
    assert info.complete
    assert info.storage == fmt
    assert info.compression == compression


def test_recorded_bag_opens_in_independent_readers(
    tmp_path: Path, local_ctx: Context, bagdata: Any
) -> None:
    """The MCAP opens in rosbags' own reader and in Foxglove's ROS 2 decoder (mcap_ros2)."""
    node = Node("talker", context=local_ctx)
    pubs = {t: node.create_publisher(bagdata.TYPES[t], t, 10) for t in TOPICS}
    rec = BagRecorder(local_ctx, TOPICS, tmp_path / "bag", compression="zstd")
    rec.start()
    for i in range(3):
        for t in TOPICS:
            pubs[t].publish(bagdata.sample(t, i))
        local_ctx.spin_some()
    path = rec.stop()

    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as reader:
        assert reader.message_count == 12
        conn = next(c for c in reader.connections if c.topic == "/camera_info")
        raw = next(r for c, _, r in reader.messages([conn]))
        msg: Any = reader.deserialize(raw, conn.msgtype)
        assert list(msg.k) == list(range(9))
        assert conn.ext.offered_qos_profiles[0].depth == 10

    mcap_ros2 = pytest.importorskip("mcap_ros2.decoder")
    from mcap.reader import make_reader

    mcap_file = path / "bag_0.mcap"
    with mcap_file.open("rb") as f:
        reader2 = make_reader(f, decoder_factories=[mcap_ros2.DecoderFactory()])
        summary = reader2.get_summary()
        assert summary is not None
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        decoded = {ch.topic: m for _, ch, _, m in reader2.iter_decoded_messages()}
    assert decoded["/chatter"].data == "hello 2"
    assert decoded["/tf"].transforms[0].child_frame_id == "base"
    assert bytes(decoded["/image"].data) == bytes(bagdata.sample("/image", 2).data)

    meta = (path / "metadata.yaml").read_text()
    assert "version: 5" in meta
    assert "storage_identifier: mcap" in meta
    assert "relative_file_paths" in meta


def test_ros1_bag_has_noetic_definitions(tmp_path: Path, local_ctx: Context, bagdata: Any) -> None:
    """ROS 1 output uses ROS 1's definitions/MD5s (Header with seq) where Noetic has the type."""
    node = Node("talker", context=local_ctx)
    pubs = {t: node.create_publisher(bagdata.TYPES[t], t, 10) for t in TOPICS}
    rec = BagRecorder(local_ctx, TOPICS, tmp_path / "out", fmt="ros1")
    rec.start()
    for t in TOPICS:
        pubs[t].publish(bagdata.sample(t, 0))
    local_ctx.spin_some()
    path = rec.stop()

    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    noetic = get_typestore(Stores.ROS1_NOETIC)
    with Reader(path) as reader:
        conns = {c.topic: c for c in reader.connections}
        assert conns["/camera_info"].digest == "c9a58c1b0b154e0e6da7578cb991d214"
        assert conns["/image"].digest == "060021388200f6f0f447d0fcd9c64743"
        assert conns["/tf"].digest == "94810edda583a504dfda3829e70d7eec"
        assert "uint32 seq" in conns["/tf"].msgdef.data
        raw = next(r for c, _, r in reader.messages([conns["/camera_info"]]))
        ci: Any = noetic.deserialize_ros1(raw, "sensor_msgs/msg/CameraInfo")
        assert ci.header.seq == 0
        assert ci.header.frame_id == "cam"
        assert list(ci.K) == list(range(9))


def test_record_all_discovers_topics_that_appear_later(tmp_path: Path, local_ctx: Context) -> None:
    rec = BagRecorder(local_ctx, None, tmp_path / "bag")
    rec.start()
    node = Node("late", context=local_ctx)
    hidden = node.create_publisher(String, "/_hidden", 10)
    local_ctx.spin_until(lambda: False, 0.15)  # discovery poll runs every 0.1 s
    pub = node.create_publisher(String, "/late", 10)
    assert local_ctx.spin_until(lambda: "/late" in rec.topics, 2.0)
    for i in range(3):
        pub.publish(String(data=str(i)))
        hidden.publish(String(data="no"))
    local_ctx.spin_some()
    path = rec.stop()
    assert [m.msg.data for m in read_bag(path)] == ["0", "1", "2"]


def test_record_stores_offered_qos_and_latched_history(tmp_path: Path, local_ctx: Context) -> None:
    node = Node("talker", context=local_ctx)
    latched = node.create_publisher(String, "/latched", qos_profile_latched)
    sensor = node.create_publisher(
        String, "/sensor", QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    )
    latched.publish(String(data="before the recorder"))
    rec = BagRecorder(local_ctx, ["/latched", "sensor"], tmp_path / "bag")
    rec.start()
    sensor.publish(String(data="s"))
    local_ctx.spin_some()
    path = rec.stop()
    with BagReader(path) as reader:
        q_latched = reader.topics["/latched"].qos[0]
        q_sensor = reader.topics["/sensor"].qos[0]
        data = {m.topic: m.msg.data for m in reader.messages()}
    assert q_latched.durability.name == "TRANSIENT_LOCAL"
    assert q_latched.depth == 1
    assert q_sensor.reliability.name == "BEST_EFFORT"
    assert data == {"/latched": "before the recorder", "/sensor": "s"}


def test_record_with_sim_time_stamps_clock_time(tmp_path: Path, local_ctx: Context) -> None:
    node = Node("sim", context=local_ctx)
    clock = node.create_publisher(Clock, "/clock", 10)
    pub = node.create_publisher(String, "/chatter", 10)
    rec = BagRecorder(local_ctx, ["/chatter"], tmp_path / "bag", use_sim_time=True)
    rec.start()
    for i in range(3):
        clock.publish(Clock(clock=ns_to_time(5_000_000_000 + i * 100_000_000)))
        local_ctx.spin_some()
        pub.publish(String(data=str(i)))
        local_ctx.spin_some()
    path = rec.stop()
    assert [m.t_ns for m in read_bag(path)] == [5_000_000_000, 5_100_000_000, 5_200_000_000]


def test_record_across_processes_over_zenoh(tmp_path: Path, domain: int, bagdata: Any) -> None:
    """Publisher and recorder in two contexts: messages arrive over Zenoh, then are recorded."""
    from visnav.graph.introspect import wait_for_discovery

    with Context(domain) as pub_ctx, Context(domain) as rec_ctx:
        node = Node("talker", context=pub_ctx)
        pub = node.create_publisher(bagdata.TYPES["/image"], "/image", 10)
        rec = BagRecorder(rec_ctx, ["/image"], tmp_path / "bag")
        rec.start()
        wait_for_discovery(rec_ctx, timeout_s=2.0)
        assert rec_ctx.spin_until(lambda: "/image" in rec.topics, 3.0)
        deadline = time.monotonic() + 3.0
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.2)
        for i in range(5):
            pub.publish(bagdata.sample("/image", i))
        assert rec_ctx.spin_until(lambda: rec.message_count >= 5, 3.0)
        path = rec.stop()
    got = [bagdata.as_dict(m.msg) for m in read_bag(path)]
    assert got == [bagdata.as_dict(bagdata.sample("/image", i)) for i in range(5)]


def test_recorder_flushes_periodically(tmp_path: Path, local_ctx: Context) -> None:
    """Without stop(), what was published more than a flush period ago is in the file."""
    node = Node("talker", context=local_ctx)
    pub = node.create_publisher(String, "/chatter", 10)
    rec = BagRecorder(local_ctx, ["/chatter"], tmp_path / "bag", flush_period_s=0.2)
    rec.start()
    for i in range(4):
        pub.publish(String(data=str(i)))
    local_ctx.spin_until(lambda: False, 0.35)
    with BagReader(tmp_path / "bag") as reader:
        assert not reader.complete
        assert [m.msg.data for m in reader.messages()] == ["0", "1", "2", "3"]
    rec.stop()
    assert BagReader(tmp_path / "bag").complete
