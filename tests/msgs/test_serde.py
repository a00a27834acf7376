"""CDR round trips of every exported message class, type lookup, and Time/Duration <-> ns."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import visnav.msgs
from visnav.msgs import (
    Duration,
    Header,
    Image,
    MessageError,
    Time,
    UnknownMessageTypeError,
    deserialize,
    duration_to_ns,
    get_message_class,
    message_definition,
    msg_type_name,
    ns_to_duration,
    ns_to_sec,
    ns_to_time,
    sec_to_ns,
    serialize,
    time_to_ns,
    typestore,
)
from visnav.msgs.serde import CdrSerializer

MESSAGE_CLASSES = sorted(
    (
        getattr(visnav.msgs, name)
        for name in visnav.msgs.__all__
        if isinstance(getattr(visnav.msgs, name), type)
        and hasattr(getattr(visnav.msgs, name), "__msgtype__")
    ),
    key=lambda cls: cls.__msgtype__,
)

NUMPY_TYPES = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


def base_value(type_name: str, rng: np.random.Generator | None) -> Any:
    """Default (rng None) or random value of a ROS base type, as rosbags represents it."""
    if type_name == "string":
        return "" if rng is None else "".join(rng.choice(list("abc/_xyz"), rng.integers(0, 6)))
    dtype = np.dtype(NUMPY_TYPES[type_name])
    if dtype.kind == "b":
        return False if rng is None else bool(rng.integers(0, 2))
    if dtype.kind == "f":
        return 0.0 if rng is None else float(dtype.type(rng.normal(0, 1e3)))
    if rng is None:
        return 0
    info = np.iinfo(dtype)
    return int(rng.integers(info.min, info.max, endpoint=True))


def build(type_name: str, rng: np.random.Generator | None = None) -> Any:
    """Build a message from the type store's field definitions: defaults or random values."""
    store = typestore()
    cls = store.types[type_name]
    kwargs = {}
    for name, (node, arg) in store.fielddefs[type_name][1]:
        kind = node.name
        if kind == "BASE":
            kwargs[name] = base_value(arg[0], rng)
        elif kind == "NAME":
            kwargs[name] = build(arg, rng)
        else:  # ARRAY (fixed size) or SEQUENCE (variable; bounded ones have a size too)
            (sub_node, sub_arg), size = arg
            if kind == "SEQUENCE":
                size = 0 if rng is None else int(rng.integers(0, 4))
            if sub_node.name == "NAME":
                kwargs[name] = [build(sub_arg, rng) for _ in range(size)]
            elif sub_arg[0] == "string":
                kwargs[name] = [base_value("string", rng) for _ in range(size)]
            else:
                dtype = NUMPY_TYPES[sub_arg[0]]
                values = [base_value(sub_arg[0], rng) for _ in range(size)]
                kwargs[name] = np.array(values, dtype=dtype)
    return cls(**kwargs)


def assert_same(a: Any, b: Any, path: str = "msg") -> None:
    """Deep equality of messages (numpy arrays by value, NaN equal to NaN)."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), path
        for field in dataclasses.fields(a):
            assert_same(getattr(a, field.name), getattr(b, field.name), f"{path}.{field.name}")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray), path
        np.testing.assert_array_equal(a, b, err_msg=path)
        assert a.dtype == b.dtype, path
    elif isinstance(a, list):
        assert isinstance(b, list), path
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, float):
        assert a == b or (math.isnan(a) and math.isnan(b)), path
    else:
        assert a == b, path


def test_every_exported_type_is_found() -> None:
    names = {cls.__msgtype__ for cls in MESSAGE_CLASSES}
    assert len(names) == len(MESSAGE_CLASSES) >= 35
    assert {"sensor_msgs/msg/Image", "sensor_msgs/msg/PointCloud2", "tf2_msgs/msg/TFMessage"} <= (
        names
    )


@pytest.mark.parametrize("cls", MESSAGE_CLASSES, ids=lambda cls: cls.__msgtype__)
def test_cdr_round_trip_defaults(cls: type[Any]) -> None:
    msg = build(cls.__msgtype__)
    assert isinstance(msg, cls)
    assert msg_type_name(msg) == cls.__msgtype__
    data = serialize(msg)
    assert data[:4] == b"\x00\x01\x00\x00"  # CDR little endian encapsulation
    back = deserialize(data, cls.__msgtype__)
    assert_same(msg, back)
    assert serialize(back) == data


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("cls", MESSAGE_CLASSES, ids=lambda cls: cls.__msgtype__)
def test_cdr_round_trip_random_values(cls: type[Any], seed: int) -> None:
    msg = build(cls.__msgtype__, np.random.default_rng(seed))
    data = serialize(msg)
    back = deserialize(data, cls.__msgtype__)
    assert_same(msg, back)
    assert serialize(back) == data


def test_type_lookup() -> None:
    assert get_message_class("sensor_msgs/msg/Image") is Image
    assert get_message_class("sensor_msgs/Image") is Image  # ROS 1 spelling
    with pytest.raises(UnknownMessageTypeError, match="did you mean sensor_msgs/msg/Image"):
        get_message_class("sensor_msgs/msg/Imag")
    with pytest.raises(MessageError, match="not a ROS message"):
        msg_type_name(3)
    assert "uint32 height" in message_definition("sensor_msgs/msg/Image")


def test_deserialize_garbage_raises_message_error() -> None:
    with pytest.raises(MessageError, match="cannot deserialize 6 bytes as sensor_msgs/msg/Image"):
        deserialize(b"\x00\x01\x00\x00\x01\x02", "sensor_msgs/msg/Image")


# ---------------------------------------------------------------- Time / Duration


@pytest.mark.parametrize(
    ("ns", "sec", "nanosec"),
    [
        (0, 0, 0),
        (1, 0, 1),
        (1_500_000_000, 1, 500_000_000),
        (-1, -1, 999_999_999),
        (-1_000_000_000, -1, 0),
        (-1_500_000_000, -2, 500_000_000),
        ((2**31 - 1) * 10**9 + 999_999_999, 2**31 - 1, 999_999_999),
        (-(2**31) * 10**9, -(2**31), 0),
    ],
)
def test_ns_to_time_normalises(ns: int, sec: int, nanosec: int) -> None:
    stamp = ns_to_time(ns)
    assert (stamp.sec, stamp.nanosec) == (sec, nanosec)
    assert time_to_ns(stamp) == ns
    duration = ns_to_duration(ns)
    assert (duration.sec, duration.nanosec) == (sec, nanosec)
    assert duration_to_ns(duration) == ns


@given(st.integers(-(2**31) * 10**9, 2**31 * 10**9 - 1))
def test_time_ns_round_trip(ns: int) -> None:
    stamp = ns_to_time(ns)
    assert 0 <= stamp.nanosec < 10**9
    assert time_to_ns(stamp) == ns
    assert time_to_ns(deserialize(serialize(stamp), "builtin_interfaces/msg/Time")) == ns
    assert duration_to_ns(ns_to_duration(ns)) == ns


@pytest.mark.parametrize("ns", [2**31 * 10**9, -(2**31) * 10**9 - 1])
def test_time_out_of_int32_range_raises(ns: int) -> None:
    with pytest.raises(MessageError, match="int32"):
        ns_to_time(ns)
    with pytest.raises(MessageError, match="int32"):
        ns_to_duration(ns)


@pytest.mark.parametrize("nanosec", [-1, 10**9])
def test_unnormalised_nanosec_raises(nanosec: int) -> None:
    with pytest.raises(MessageError, match=r"nanosec is .*expected 0 <= nanosec < 1000000000"):
        time_to_ns(Time(sec=1, nanosec=nanosec))
    with pytest.raises(MessageError, match=r"Duration\.nanosec"):
        duration_to_ns(Duration(sec=1, nanosec=nanosec))


def test_seconds_helpers() -> None:
    assert sec_to_ns(1.5) == 1_500_000_000
    assert sec_to_ns(-0.25) == -250_000_000
    assert sec_to_ns(1e-9) == 1
    assert ns_to_sec(2_500_000_000) == 2.5
    assert isinstance(sec_to_ns(0.1), int)


def _diagnostics(values: list[str]) -> Any:
    array = get_message_class("diagnostic_msgs/msg/DiagnosticArray")
    status = get_message_class("diagnostic_msgs/msg/DiagnosticStatus")
    key_value = get_message_class("diagnostic_msgs/msg/KeyValue")
    statuses = [
        status(
            level=0,
            name="car/left_wheel",
            message="plane",
            hardware_id="world/ground",
            values=[key_value(key="x", value=v)],
        )
        for v in values
    ]
    return array(header=Header(stamp=ns_to_time(0), frame_id="world"), status=statuses)


def test_reused_serializer_buffer_carries_no_stale_bytes() -> None:
    # the same size, the first string one byte shorter: the first message's bytes used to
    # stay where the second expects a terminator ("Missing string terminator")
    cdr = CdrSerializer("diagnostic_msgs/msg/DiagnosticArray")
    first = _diagnostics(["-6.16", "-6.2", "0"])
    second = _diagnostics(["-6.2", "-6.16", "0"])
    assert bytes(cdr.serialize(first)) == serialize(first)
    assert len(serialize(first)) == len(serialize(second))  # the buffer is reused
    data = bytes(cdr.serialize(second))
    assert data == serialize(second)
    assert (
        deserialize(data, "diagnostic_msgs/msg/DiagnosticArray").status[0].values[0].value == "-6.2"
    )


@given(st.lists(st.lists(st.text(max_size=6), min_size=1, max_size=3), min_size=2, max_size=6))
def test_reused_serializer_equals_fresh_serialization(batches: list[list[str]]) -> None:
    cdr = CdrSerializer("diagnostic_msgs/msg/DiagnosticArray")
    for values in batches:
        msg = _diagnostics(values)
        assert bytes(cdr.serialize(msg)) == serialize(msg)


def test_declared_defaults_as_rclpy_gives_them() -> None:
    from visnav.msgs import Pose, Quaternion
    from visnav.msgs.construct import default_message, make, message_from_dict

    # geometry_msgs/Quaternion.msg declares w = 1: rclpy's Quaternion() is the identity
    assert make(Quaternion).w == 1.0
    assert make(Pose).orientation.w == 1.0
    assert default_message("geometry_msgs/msg/PoseStamped").pose.orientation.w == 1.0
    given = message_from_dict("geometry_msgs/msg/Pose", {"orientation": {"z": 1.0, "w": 0.0}})
    assert (given.orientation.z, given.orientation.w) == (1.0, 0.0)
