"""ROS 1 types: MD5 sums and bytes checked against real ROS 1 (genpy in the system python)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.bridge.errors import BridgeError, TcprosError, UnconvertibleTypeError
from visnav.bridge.master_api import master_uri_from_env
from visnav.bridge.typemap import cdr_to_ros1, ros1_name, ros1_to_cdr, ros1_type, ros2_name
from visnav.msgs import CameraInfo, Header
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import deserialize, serialize
from visnav.msgs.time import ns_to_time

SYSTEM_PYTHON = Path("/usr/bin/python3")

# every type a visnav node publishes or subscribes to
USED_TYPES = [
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/CameraInfo",
    "sensor_msgs/msg/PointCloud2",
    "sensor_msgs/msg/LaserScan",
    "sensor_msgs/msg/Imu",
    "sensor_msgs/msg/JointState",
    "nav_msgs/msg/Odometry",
    "nav_msgs/msg/Path",
    "nav_msgs/msg/OccupancyGrid",
    "nav_msgs/msg/MapMetaData",
    "geometry_msgs/msg/Twist",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/TransformStamped",
    "tf2_msgs/msg/TFMessage",
    "rosgraph_msgs/msg/Clock",
    "std_msgs/msg/String",
    "std_msgs/msg/Header",
    "actionlib_msgs/msg/GoalStatusArray",
    "trajectory_msgs/msg/MultiDOFJointTrajectory",
]

_GENPY_MD5 = """
import importlib, json, sys
out = {}
for name in json.loads(sys.argv[1]):
    pkg, _, cls = name.split("/")
    try:
        mod = importlib.import_module(pkg + ".msg")
    except ImportError:
        continue
    out[name] = getattr(mod, cls)._md5sum
print(json.dumps(out))
"""


def _system_python(code: str, *args: str) -> str:
    if not SYSTEM_PYTHON.exists():
        pytest.skip("no system python3 with ROS 1 (apt install python3-rospy)")
    proc = subprocess.run(
        [str(SYSTEM_PYTHON), "-c", code, *args],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )
    if proc.returncode != 0:
        if "No module named 'genpy'" in proc.stderr or "No module named" in proc.stderr:
            pytest.skip(f"ROS 1 python packages missing: {proc.stderr.strip()[-200:]}")
        pytest.fail(proc.stderr)
    return proc.stdout


def test_names() -> None:
    assert ros1_name("sensor_msgs/msg/Image") == "sensor_msgs/Image"
    assert ros2_name("sensor_msgs/Image") == "sensor_msgs/msg/Image"
    assert ros1_type("sensor_msgs/Image") == ros1_type("sensor_msgs/msg/Image")


def test_md5_sums_equal_real_ros1() -> None:
    real = json.loads(_system_python(_GENPY_MD5, json.dumps(USED_TYPES)))
    if len(real) < 10:
        pytest.skip(f"only {sorted(real)} have ROS 1 python messages here")
    for name, md5 in real.items():
        assert ros1_type(name).md5sum == md5, name


_GENPY_BYTES = """
import sys, json
from sensor_msgs.msg import CameraInfo
m = CameraInfo()
m.deserialize(open(sys.argv[1], "rb").read())
reply = CameraInfo()
reply.header.seq = 7
reply.header.stamp.secs, reply.header.stamp.nsecs = 12, 345
reply.header.frame_id = "cam_optical"
reply.width, reply.height = 64, 48
reply.K = [1, 0, 2, 0, 3, 4, 0, 0, 1]
reply.distortion_model = "plumb_bob"
reply.D = [0.1, 0.2, 0.0, 0.0, 0.0]
import io
buf = io.BytesIO(); reply.serialize(buf)
open(sys.argv[2], "wb").write(buf.getvalue())
print(json.dumps({"K": list(m.K), "frame": m.header.frame_id, "secs": m.header.stamp.secs,
                  "nsecs": m.header.stamp.nsecs, "D": list(m.D), "w": m.width}))
"""


def test_bytes_cross_real_ros1_both_ways(tmp_path: Path) -> None:
    info = CameraInfo(
        header=Header(stamp=ns_to_time(3_000_000_017), frame_id="camera_optical"),
        height=480,
        width=640,
        distortion_model="plumb_bob",
        d=np.array([0.01, -0.02, 0.0, 0.0, 0.0]),
        k=np.array([525.0, 0, 319.5, 0, 525.0, 239.5, 0, 0, 1]),
        r=np.eye(3).ravel(),
        p=np.array([525.0, 0, 319.5, 0, 0, 525.0, 239.5, 0, 0, 0, 1, 0]),
        binning_x=0,
        binning_y=0,
        roi=_roi(),
    )
    rtype = ros1_type("sensor_msgs/msg/CameraInfo")
    (tmp_path / "out.bin").write_bytes(cdr_to_ros1(serialize(info), rtype))
    got = json.loads(
        _system_python(_GENPY_BYTES, str(tmp_path / "out.bin"), str(tmp_path / "in.bin"))
    )
    assert got["K"] == [525.0, 0, 319.5, 0, 525.0, 239.5, 0, 0, 1]
    assert got["frame"] == "camera_optical"
    assert (got["secs"], got["nsecs"], got["w"]) == (3, 17, 640)
    back = deserialize(ros1_to_cdr((tmp_path / "in.bin").read_bytes(), rtype), rtype.ros2_name)
    assert back.header.frame_id == "cam_optical"
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == (12, 345)
    assert list(back.k) == [1, 0, 2, 0, 3, 4, 0, 0, 1]
    assert list(back.d) == pytest.approx([0.1, 0.2, 0, 0, 0])


def _roi() -> object:
    from visnav.msgs.serde import get_message_class

    return get_message_class("sensor_msgs/msg/RegionOfInterest")(
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )


@pytest.mark.parametrize(
    ("name", "words"),
    [
        ("visualization_msgs/msg/Marker", "different fields in ROS 1 Noetic"),
        ("rcl_interfaces/msg/Log", "exists only in ROS 2"),
        ("my_msgs/msg/Thing", "not one visnav knows"),
    ],
)
def test_unconvertible_types_are_named(name: str, words: str) -> None:
    with pytest.raises(UnconvertibleTypeError, match=words) as info:
        ros1_type(name)
    assert ros1_name(name) in str(info.value)


def test_truncated_ros1_bytes_raise_tcpros_error() -> None:
    rtype = ros1_type("sensor_msgs/msg/CameraInfo")
    with pytest.raises(TcprosError, match="do not decode as ROS 1 sensor_msgs/CameraInfo"):
        ros1_to_cdr(b"\x01\x00", rtype)


@pytest.mark.parametrize(
    "name",
    [
        "sensor_msgs/msg/CameraInfo",
        "tf2_msgs/msg/TFMessage",
        "nav_msgs/msg/Odometry",
        "sensor_msgs/msg/PointCloud2",
        "std_msgs/msg/String",
    ],
)
@settings(max_examples=150, deadline=None)
@given(data=st.binary(max_size=300))
def test_fuzz_peer_bytes_only_tcpros_error(name: str, data: bytes) -> None:
    rtype = ros1_type(name)
    try:
        cdr = ros1_to_cdr(data, rtype)
    except TcprosError:
        return
    try:
        deserialize(cdr, rtype.ros2_name)
    except MessageError:
        return


@settings(max_examples=200)
@given(st.text(max_size=60))
def test_fuzz_master_uri(value: str) -> None:
    try:
        uri = master_uri_from_env({"ROS_MASTER_URI": value})
    except BridgeError as exc:
        text = str(exc)
    else:
        text = uri
    assert text.startswith("http://") or "ROS_MASTER_URI" in text


_GENPY_DEFAULTS = """
import importlib, io, json, sys
import genpy
out = {}
for name in json.loads(sys.argv[1]):
    pkg, _, cls = name.split("/")
    try:
        msg = getattr(importlib.import_module(pkg + ".msg"), cls)()
    except ImportError:
        continue
    if hasattr(msg, "header"):
        msg.header.seq = 0  # visnav sends seq per topic; compare with 0 on both sides
        msg.header.stamp = genpy.Time(12, 345)
        msg.header.frame_id = "frame_a"
    buf = io.BytesIO()
    msg.serialize(buf)
    out[name] = buf.getvalue().hex()
print(json.dumps(out))
"""


def test_every_used_type_round_trips_real_ros1_bytes() -> None:
    real = json.loads(_system_python(_GENPY_DEFAULTS, json.dumps(USED_TYPES)))
    if len(real) < 10:
        pytest.skip(f"only {sorted(real)} have ROS 1 python messages here")
    for name, hexdata in real.items():
        rtype = ros1_type(name)
        raw = bytes.fromhex(hexdata)
        msg = deserialize(ros1_to_cdr(raw, rtype), rtype.ros2_name)
        assert bytes(cdr_to_ros1(serialize(msg), rtype)) == raw, name
