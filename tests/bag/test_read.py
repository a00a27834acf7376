"""Reading bags as ROS writes them (built with the rosbags writers), and conversion."""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from visnav.bag import BagReader, BagWriter, bag_info, convert_bag, read_bag
from visnav.msgs import CameraInfo, Image, String, serialize
from visnav.msgs.serde import typestore

NOETIC = get_typestore(Stores.ROS1_NOETIC)


def _noetic_camera_info(i: int) -> Any:
    T = NOETIC.types
    return T["sensor_msgs/msg/CameraInfo"](
        header=T["std_msgs/msg/Header"](
            seq=i, stamp=T["builtin_interfaces/msg/Time"](sec=i, nanosec=5), frame_id="cam"
        ),
        height=4,
        width=6,
        distortion_model="plumb_bob",
        D=np.array([0.1, float(i)]),
        K=np.arange(9, dtype=np.float64) + i,
        R=np.eye(3).ravel(),
        P=np.zeros(12),
        binning_x=0,
        binning_y=0,
        roi=T["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        ),
    )


@pytest.fixture
def ros1_bag(tmp_path: Path) -> Path:
    """A ROS 1 bag as rosbag writes it: Noetic definitions, Header.seq, a latched topic."""
    path = tmp_path / "ros1.bag"
    writer = Writer1(path)
    writer.set_compression(Writer1.CompressionFormat.LZ4)
    with writer:
        ci = writer.add_connection(
            "/camera_info", "sensor_msgs/msg/CameraInfo", typestore=NOETIC, callerid="/cam"
        )
        s = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=NOETIC, latching=1)
        for i in range(4):
            t = 1_000_000_000 * (i + 1)
            writer.write(ci, t, NOETIC.serialize_ros1(_noetic_camera_info(i), ci.msgtype))
            writer.write(s, t + 1, NOETIC.serialize_ros1(String(data=f"s{i}"), s.msgtype))
    return path


def test_reads_ros1_bag_into_visnav_messages(ros1_bag: Path) -> None:
    with BagReader(ros1_bag) as reader:
        assert reader.is_ros1
        assert reader.complete
        assert reader.topics["/camera_info"].native
        assert reader.topics["/chatter"].qos[0].durability.name == "TRANSIENT_LOCAL"
        got = list(reader.messages())
    assert [m.topic for m in got] == ["/camera_info", "/chatter"] * 4
    ci = got[2].msg
    assert isinstance(ci, CameraInfo)
    assert (ci.header.stamp.sec, ci.header.stamp.nanosec, ci.header.frame_id) == (1, 5, "cam")
    assert list(ci.k) == list(range(1, 10))
    assert list(ci.d) == [0.1, 1.0]
    assert got[3].msg == String(data="s1")
    assert got[3].t_ns == 2_000_000_001


@pytest.mark.parametrize("storage", [StoragePlugin.SQLITE3, StoragePlugin.MCAP])
def test_reads_rosbag2_written_by_rosbags(tmp_path: Path, storage: StoragePlugin) -> None:
    path = tmp_path / "bag"
    store = typestore()
    img = Image.__msgtype__
    with Writer2(path, version=9, storage_plugin=storage) as writer:
        conn = writer.add_connection("/image", img, typestore=store)
        for i in range(3):
            msg = _image(i)
            writer.write(conn, 10 + i, bytes(store.serialize_cdr(msg, img)))
    got = list(read_bag(path))
    assert [m.t_ns for m in got] == [10, 11, 12]
    assert all(isinstance(m.msg, Image) for m in got)
    assert [int(m.msg.data[0]) for m in got] == [0, 1, 2]


def _image(i: int) -> Any:
    from visnav.msgs import Header, make, ns_to_time

    return make(
        Image,
        header=Header(stamp=ns_to_time(i), frame_id="c"),
        height=1,
        width=2,
        encoding="mono8",
        step=2,
        data=np.array([i, 7], np.uint8),
    )


def test_reads_humble_sqlite3_without_definitions(tmp_path: Path) -> None:
    """Humble's sqlite3 storage keeps no message definitions: visnav's type store fills in."""
    path = tmp_path / "humble"
    path.mkdir()
    db = sqlite3.connect(path / "humble_0.db3")
    db.executescript(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,"
        " serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);"
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,"
        " timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
    )
    db.execute("INSERT INTO topics VALUES (1, '/chatter', 'std_msgs/msg/String', 'cdr', '')")
    for i in range(3):
        db.execute(
            "INSERT INTO messages(topic_id, timestamp, data) VALUES (1, ?, ?)",
            (100 + i, serialize(String(data=f"h{i}"))),
        )
    db.commit()
    db.close()
    (path / "metadata.yaml").write_text(
        """rosbag2_bagfile_information:
  version: 5
  storage_identifier: sqlite3
  duration:
    nanoseconds: 2
  starting_time:
    nanoseconds_since_epoch: 100
  message_count: 3
  topics_with_message_count:
    - topic_metadata:
        name: /chatter
        type: std_msgs/msg/String
        serialization_format: cdr
        offered_qos_profiles: ""
      message_count: 3
  compression_format: ""
  compression_mode: ""
  relative_file_paths:
    - humble_0.db3
  files:
    - path: humble_0.db3
      starting_time:
        nanoseconds_since_epoch: 100
      duration:
        nanoseconds: 2
      message_count: 3
"""
    )
    assert [m.msg.data for m in read_bag(path)] == ["h0", "h1", "h2"]
    info = bag_info(path)
    assert info.storage == "sqlite3"
    assert info.topic("/chatter").count == 3


def test_bare_storage_files_and_dir_without_metadata(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "b") as w:
        t = w.add_topic("/chatter", "std_msgs/msg/String")
        w.write(t, 5, serialize(String(data="x")))
    mcap = tmp_path / "b" / "b_0.mcap"
    assert [m.msg.data for m in read_bag(mcap)] == ["x"]
    (tmp_path / "b" / "metadata.yaml").unlink()
    assert [m.msg.data for m in read_bag(tmp_path / "b")] == ["x"]


def test_foreign_types_come_out_as_rosbags_objects(tmp_path: Path) -> None:
    """A custom type visnav does not know is read with the bag's own definition."""
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg("int32 a\nstring b", "my_pkg/msg/Custom"))
    path = tmp_path / "custom"
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/custom", "my_pkg/msg/Custom", typestore=store)
        cls = store.types["my_pkg/msg/Custom"]
        writer.write(conn, 1, bytes(store.serialize_cdr(cls(a=3, b="x"), "my_pkg/msg/Custom")))
    with BagReader(path) as reader:
        assert not reader.topics["/custom"].native
        (msg,) = list(reader.messages())
    assert (msg.msg.a, msg.msg.b) == (3, "x")
    out = convert_bag(path, tmp_path / "copy", fmt="mcap")
    assert [m.msg.b for m in read_bag(out.path)] == ["x"]
    res = convert_bag(path, tmp_path / "copy1", fmt="ros1")
    assert res.message_count == 0
    assert "/custom" in res.skipped


def test_convert_chain_keeps_messages(tmp_path: Path, ros1_bag: Path, bagdata: Any) -> None:
    """ROS 1 -> MCAP -> SQLite 3 -> ROS 1 (lz4) -> MCAP (zstd): same messages and times."""
    want = [(m.topic, m.t_ns, bagdata.as_dict(m.msg)) for m in read_bag(ros1_bag)]
    src = ros1_bag
    for i, (fmt, comp) in enumerate(
        [("mcap", "none"), ("sqlite3", "none"), ("ros1", "lz4"), ("mcap", "zstd")]
    ):
        res = convert_bag(src, tmp_path / f"step{i}", fmt=fmt, compression=comp)
        assert res.message_count == 8
        assert bag_info(res.path).storage == fmt
        have = [(m.topic, m.t_ns, bagdata.as_dict(m.msg)) for m in read_bag(res.path)]
        assert have == want
        src = res.path
    with BagReader(src) as reader:  # the latched topic stays latched through every format
        assert reader.topics["/chatter"].qos[0].durability.name == "TRANSIENT_LOCAL"


def test_convert_topic_filter(tmp_path: Path, ros1_bag: Path) -> None:
    res = convert_bag(ros1_bag, tmp_path / "only", topics=["/chatter"])
    assert res.topics == ("/chatter",)
    assert [m.topic for m in read_bag(res.path)] == ["/chatter"] * 4


def test_read_time_window(ros1_bag: Path) -> None:
    got = list(read_bag(ros1_bag, ["/chatter"], start_ns=2_000_000_000, stop_ns=4_000_000_000))
    assert [m.msg.data for m in got] == ["s1", "s2"]
