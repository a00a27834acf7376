"""Foxglove parameter names and values <-> visnav's, and the binary encoders."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.bridge.foxglove import FoxgloveError
from visnav.bridge.foxglove.params import from_json_value, split_name, to_json_parameter
from visnav.bridge.foxglove.protocol import (
    encode_message_data,
    encode_service_response,
    encode_time,
    json_text,
)


def test_split_name_at_the_first_dot() -> None:
    assert split_name("/amcl.initial_pose.x") == ("/amcl", "initial_pose.x")
    assert split_name("move_base.planner_frequency") == ("/move_base", "planner_frequency")
    for bad in ("/amcl", ".x", "/amcl."):
        with pytest.raises(FoxgloveError, match=r"<node>\.<parameter>"):
            split_name(bad)


def test_values_keep_their_type_through_json() -> None:
    assert to_json_parameter("/n.f", 2.0) == {"name": "/n.f", "value": 2.0, "type": "float64"}
    assert to_json_parameter("/n.a", [1.0, 2.5])["type"] == "float64_array"
    assert to_json_parameter("/n.i", [1, 2]) == {"name": "/n.i", "value": [1, 2]}
    assert to_json_parameter("/n.b", b"\xff") == {
        "name": "/n.b",
        "value": "/w==",
        "type": "byte_array",
    }
    assert from_json_value("/n.f", 2, "float64") == 2.0
    assert isinstance(from_json_value("/n.f", 2, "float64"), float)
    assert from_json_value("/n.b", "/w==", "byte_array") == b"\xff"
    assert from_json_value("/n.s", ["a", "b"], None) == ["a", "b"]
    with pytest.raises(FoxgloveError, match="does not match its type"):
        from_json_value("/n.f", "fast", "float64")
    with pytest.raises(FoxgloveError, match="not a parameter value"):
        from_json_value("/n.x", {"a": 1}, None)
    with pytest.raises(FoxgloveError, match="not a parameter value"):
        from_json_value("/n.x", [1, "a"], None)


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_double_round_trip(value: float) -> None:
    p = to_json_parameter("/n.d", value)
    assert from_json_value(p["name"], p["value"], p["type"]) == value


def test_binary_layouts() -> None:
    frame = encode_message_data(7, 123, b"abc")
    assert frame[:1] == b"\x01"
    assert struct.unpack_from("<IQ", frame, 1) == (7, 123)
    assert frame[13:] == b"abc"
    assert encode_time(5) == b"\x02" + struct.pack("<Q", 5)
    resp = encode_service_response(1, 2, "cdr", b"xy")
    assert resp == b"\x03" + struct.pack("<III", 1, 2, 3) + b"cdrxy"
    assert json_text({"v": float("nan"), "w": [float("inf")]}) == '{"v":null,"w":[null]}'
