"""The byte-level CDR -> ROS 1 rewrite of byte-tail types equals the full conversion."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.bridge.bridge import Ros1Bridge, _Out
from visnav.bridge.bytetail import head_plan, split_cdr_to_ros1
from visnav.bridge.errors import TcprosError
from visnav.bridge.typemap import cdr_to_ros1, ros1_type
from visnav.graph import SerializedMessage
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import deserialize, serialize, typestore

BYTE_TAIL_TYPES = [
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/CompressedImage",
    "nav_msgs/msg/OccupancyGrid",
    "std_msgs/msg/UInt8MultiArray",
    "std_msgs/msg/Int8MultiArray",
]
# no float before the tail: random bytes there never hold a float32 signalling NaN
NO_FLOAT_TYPES = [t for t in BYTE_TAIL_TYPES if t != "nav_msgs/msg/OccupancyGrid"]

_INTS = {
    "uint8": (0, 2**8 - 1, np.uint8),
    "int8": (-(2**7), 2**7 - 1, np.int8),
    "uint16": (0, 2**16 - 1, np.uint16),
    "int16": (-(2**15), 2**15 - 1, np.int16),
    "uint32": (0, 2**32 - 1, np.uint32),
    "int32": (-(2**31), 2**31 - 1, np.int32),
    "uint64": (0, 2**64 - 1, np.uint64),
    "int64": (-(2**63), 2**63 - 1, np.int64),
}


def _draw(data: st.DataObject, type_name: str) -> Any:
    """An arbitrary message of ``type_name`` drawn field by field from its definition."""
    store = typestore()
    kwargs: dict[str, Any] = {}
    fields: list[tuple[str, Any]] = store.fielddefs[type_name][1]
    for name, (node, arg) in fields:
        if node.name == "NAME":
            kwargs[name] = _draw(data, arg)
        elif node.name == "BASE":
            kwargs[name] = _value(data, arg[0])
        else:
            assert node.name == "SEQUENCE", (type_name, name)
            (sub_node, sub_arg), _bound = arg
            if sub_node.name == "NAME":
                count = data.draw(st.integers(0, 3))
                kwargs[name] = [_draw(data, sub_arg) for _ in range(count)]
            else:
                lo, hi, dtype = _INTS[sub_arg[0]]
                values = data.draw(st.lists(st.integers(lo, hi), max_size=40))
                kwargs[name] = np.array(values, dtype=dtype)
    return store.types[type_name](**kwargs)


def _value(data: st.DataObject, kind: str) -> Any:
    if kind == "string":
        return data.draw(st.text(max_size=12))
    if kind == "float32":
        return data.draw(st.floats(width=32))
    if kind == "float64":
        return data.draw(st.floats())
    lo, hi, _ = _INTS[kind]
    return data.draw(st.integers(lo, hi))


def _full(cdr: bytes, type_name: str) -> bytes:
    """What the bridge sent before the fast path: deserialize, then convert."""
    rtype = ros1_type(type_name)
    head, tail = Ros1Bridge._to_ros1(
        _Out("/t", rtype, False), deserialize(cdr, type_name), copy=True
    )
    return bytes(head) + (b"" if tail is None else bytes(tail))


@pytest.mark.parametrize("type_name", BYTE_TAIL_TYPES)
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_fast_path_equals_the_full_conversion(type_name: str, data: st.DataObject) -> None:
    msg = _draw(data, type_name)
    cdr = bytes(serialize(msg))
    rtype = ros1_type(type_name)
    plan = head_plan(rtype)
    assert plan is not None
    head, tail = split_cdr_to_ros1(cdr, plan)
    fast = bytes(head) + bytes(tail)
    assert fast == bytes(cdr_to_ros1(cdr, rtype))
    assert fast == _full(cdr, type_name)
    assert tail.obj is cdr  # the tail is a view on the received bytes, not a copy


@pytest.mark.parametrize("type_name", NO_FLOAT_TYPES)
@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_damaged_bytes_are_refused_or_converted_like_the_full_path(
    type_name: str, data: st.DataObject
) -> None:
    cdr = bytearray(serialize(_draw(data, type_name)))
    for _ in range(data.draw(st.integers(1, 3))):
        how = data.draw(st.sampled_from(["set", "cut", "add"]))
        if how == "set" and len(cdr) > 4:
            cdr[data.draw(st.integers(4, len(cdr) - 1))] = data.draw(st.integers(0, 255))
        elif how == "cut":
            del cdr[data.draw(st.integers(0, len(cdr))) :]
        else:
            cdr += data.draw(st.binary(min_size=1, max_size=6))
    raw = bytes(cdr)
    plan = head_plan(ros1_type(type_name))
    assert plan is not None
    try:
        expected: bytes | None = _full(raw, type_name)
    except (MessageError, TcprosError):
        expected = None
    if raw[:2] != b"\x00\x01":  # big endian or garbage: the bridge takes the full path
        with pytest.raises(TcprosError):
            split_cdr_to_ros1(raw, plan)
        return
    if expected is None:
        with pytest.raises(TcprosError):
            split_cdr_to_ros1(raw, plan)
    else:
        head, tail = split_cdr_to_ros1(raw, plan)
        assert bytes(head) + bytes(tail) == expected


@pytest.mark.parametrize("type_name", BYTE_TAIL_TYPES)
@settings(max_examples=100, deadline=None)
@given(raw=st.binary(max_size=120))
def test_fuzz_only_tcpros_errors_escape(type_name: str, raw: bytes) -> None:
    plan = head_plan(ros1_type(type_name))
    assert plan is not None
    try:
        split_cdr_to_ros1(b"\x00\x01\x00\x00" + raw, plan)
    except TcprosError as exc:
        text = str(exc)
    else:
        return
    assert type_name in text


def test_signalling_nan_keeps_its_bits() -> None:
    """The one documented difference: a float32 sNaN is carried as sent (ros1_bridge does)."""
    from visnav.msgs import Header, MapMetaData, OccupancyGrid, Point, Pose, Quaternion
    from visnav.msgs.time import ns_to_time

    grid = OccupancyGrid(
        header=Header(stamp=ns_to_time(0), frame_id=""),
        info=MapMetaData(
            map_load_time=ns_to_time(0),
            resolution=0.0,
            width=2,
            height=1,
            origin=Pose(
                position=Point(x=0.0, y=0.0, z=0.0),
                orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        ),
        data=np.zeros(2, dtype=np.int8),
    )
    cdr = bytearray(serialize(grid))
    # info.resolution: after the header (stamp 8, frame_id "" 4+1, pad 3) and map_load_time 8
    offset = 4 + 16 + 8
    assert cdr[offset : offset + 4] == b"\0\0\0\0"
    cdr[offset : offset + 4] = (0x7F800001).to_bytes(4, "little")
    plan = head_plan(ros1_type("nav_msgs/msg/OccupancyGrid"))
    assert plan is not None
    head, _tail = split_cdr_to_ros1(bytes(cdr), plan)
    ros1_offset = 4 + 8 + 4 + 8  # seq, stamp, frame_id length, map_load_time
    assert head[ros1_offset : ros1_offset + 4] == (0x7F800001).to_bytes(4, "little")
    full = _full(bytes(cdr), "nav_msgs/msg/OccupancyGrid")
    assert full[ros1_offset : ros1_offset + 4] == (0x7FC00001).to_bytes(4, "little")


def test_plans_only_for_byte_tail_types() -> None:
    for name in BYTE_TAIL_TYPES:
        assert head_plan(ros1_type(name)) is not None, name
    for name in ("sensor_msgs/msg/PointCloud2", "std_msgs/msg/String", "nav_msgs/msg/Odometry"):
        assert head_plan(ros1_type(name)) is None, name


def test_bridge_forwards_a_raw_image_without_deserializing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from visnav.msgs import Header, Image
    from visnav.msgs.time import ns_to_time

    rtype = ros1_type("sensor_msgs/msg/Image")
    msg = Image(
        header=Header(stamp=ns_to_time(42), frame_id="cam"),
        height=2,
        width=3,
        encoding="rgb8",
        is_bigendian=0,
        step=9,
        data=np.arange(18, dtype=np.uint8),
    )
    cdr = bytes(serialize(msg))
    out = _Out("/img", rtype, latch=False)

    def no_deserialize(self: SerializedMessage) -> Any:
        raise AssertionError("the fast path deserialized")

    monkeypatch.setattr(SerializedMessage, "deserialize", no_deserialize)
    bridge = Ros1Bridge.__new__(Ros1Bridge)  # _convert uses no other state on success
    made = bridge._convert(out, SerializedMessage(cdr, rtype.ros2_name))
    assert made is not None
    head, tail = made
    assert tail is not None
    assert bytes(head) + bytes(tail) == bytes(cdr_to_ros1(cdr, rtype))
    assert tail.obj is cdr
