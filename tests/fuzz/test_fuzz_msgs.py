"""Fuzz CDR deserialization and the Image / PointCloud2 <-> numpy conversions.

Only :class:`~visnav.errors.VisnavError` (here :class:`~visnav.msgs.MessageError`)
may escape; everything that decodes must also convert without a crash.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from visnav.msgs import CameraInfo, Image, PointCloud2, PointField, make
from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.msgs.pointcloud import (
    cloud_to_structured,
    cloud_to_xyz,
    structured_to_cloud,
    xyz_to_cloud,
)
from visnav.msgs.serde import deserialize, msg_type_name, serialize

from .conftest import FUZZ, mutated, only_visnav_errors

ENCODINGS = [
    "rgb8", "bgr8", "rgba8", "bgra8", "mono8", "mono16", "16UC1", "32FC1", "8UC3", "16SC2",
    "64FC1", "bayer_rggb8", "yuv422", "uyvy", "yuyv", "8UC0", "", "jpeg", "32FC9", "8UC513",
]  # fmt: skip

TYPES = [
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/PointCloud2",
    "sensor_msgs/msg/CameraInfo",
    "nav_msgs/msg/Odometry",
    "tf2_msgs/msg/TFMessage",
    "std_msgs/msg/String",
    "rosgraph_msgs/msg/Clock",
]


def _image_seed() -> bytes:
    return serialize(numpy_to_image(np.arange(12, dtype=np.uint8).reshape(2, 2, 3), "rgb8"))


def _cloud_seed() -> bytes:
    return serialize(xyz_to_cloud(np.arange(9, dtype=np.float32).reshape(3, 3)))


def _info_seed() -> bytes:
    return serialize(make(CameraInfo, height=4, width=6, distortion_model="plumb_bob"))


SEEDS = [_image_seed(), _cloud_seed(), _info_seed()]


def _convert(msg: Any) -> None:
    """Use what decoded, as a subscriber would."""
    if isinstance(msg, Image):
        only_visnav_errors(image_to_numpy, msg)
    elif isinstance(msg, PointCloud2):
        only_visnav_errors(cloud_to_structured, msg)
        only_visnav_errors(cloud_to_xyz, msg)


@FUZZ
@given(data=st.binary(max_size=256), type_name=st.sampled_from(TYPES))
def test_random_bytes_deserialize(data: bytes, type_name: str) -> None:
    msg = only_visnav_errors(deserialize, data, type_name)
    if msg is not None:
        assert msg_type_name(msg) == type_name
        _convert(msg)


@FUZZ
@given(st.data())
def test_mutated_cdr_deserialize(data: st.DataObject) -> None:
    k = data.draw(st.integers(0, len(SEEDS) - 1))
    blob = data.draw(mutated(SEEDS[k]))
    type_name = ["sensor_msgs/msg/Image", "sensor_msgs/msg/PointCloud2", TYPES[2]][k]
    msg = only_visnav_errors(deserialize, blob, type_name)
    if msg is not None:
        _convert(msg)


@FUZZ
@given(
    height=st.integers(-2, 8),
    width=st.integers(-2, 8),
    step=st.integers(-4, 40),
    encoding=st.one_of(st.sampled_from(ENCODINGS), st.text(max_size=8)),
    big=st.integers(-1, 300),
    data=st.binary(max_size=200),
)
def test_image_fields_to_numpy(
    height: int, width: int, step: int, encoding: str, big: int, data: bytes
) -> None:
    msg = make(Image, encoding=encoding)
    msg.height, msg.width, msg.step, msg.is_bigendian = height, width, step, big
    msg.data = np.frombuffer(data, dtype=np.uint8)
    out = only_visnav_errors(image_to_numpy, msg)
    if out is not None:
        assert out.shape[0] == height
        assert out.shape[1] == width


@FUZZ
@given(
    shape=st.lists(st.integers(0, 5), min_size=1, max_size=4),
    dtype=st.sampled_from(["u1", "i1", "u2", "<i2", ">u2", "f4", ">f4", "f8", "i4", "u4", "?"]),
    encoding=st.sampled_from(ENCODINGS),
    step=st.one_of(st.none(), st.integers(-3, 64)),
)
def test_numpy_to_image(shape: list[int], dtype: str, encoding: str, step: int | None) -> None:
    array = np.zeros(shape, dtype=np.dtype(dtype))
    msg = only_visnav_errors(numpy_to_image, array, encoding, step=step)
    if msg is not None:
        assert msg.encoding == encoding
        only_visnav_errors(image_to_numpy, msg)


fields_st = st.lists(
    st.builds(
        lambda name, offset, datatype, count: make(
            PointField, name=name, offset=offset, datatype=datatype, count=count
        ),
        name=st.sampled_from(["x", "y", "z", "rgb", "intensity", "", "x"]),
        offset=st.integers(-2, 20),
        datatype=st.integers(-1, 10),
        count=st.integers(-1, 4),
    ),
    max_size=5,
)


@FUZZ
@given(
    fields=fields_st,
    height=st.integers(-1, 4),
    width=st.integers(-1, 6),
    point_step=st.integers(-1, 32),
    row_step=st.integers(-1, 200),
    big=st.booleans(),
    dense=st.booleans(),
    data=st.binary(max_size=300),
)
def test_pointcloud_fields_to_numpy(
    fields: list[Any],
    height: int,
    width: int,
    point_step: int,
    row_step: int,
    big: bool,
    dense: bool,
    data: bytes,
) -> None:
    msg = make(PointCloud2, fields=fields, is_bigendian=big, is_dense=dense)
    msg.height, msg.width, msg.point_step, msg.row_step = height, width, point_step, row_step
    msg.data = np.frombuffer(data, dtype=np.uint8)
    only_visnav_errors(cloud_to_structured, msg, skip_nans=dense)
    xyz = only_visnav_errors(cloud_to_xyz, msg)
    if xyz is not None:
        assert xyz.ndim == 2
        assert xyz.shape[1] == 3


@FUZZ
@given(
    n=st.integers(0, 6),
    cols=st.integers(1, 5),
    dtype=st.sampled_from(["f4", "f8", "i4", "u1", "f2"]),
    rgb=st.booleans(),
)
def test_arrays_to_cloud(n: int, cols: int, dtype: str, rgb: bool) -> None:
    points = np.zeros((n, cols), dtype=np.dtype(dtype))
    colours = np.zeros((n, 3), dtype=np.uint8) if rgb else None
    msg = only_visnav_errors(xyz_to_cloud, points, rgb=colours)
    if msg is not None:
        assert only_visnav_errors(cloud_to_xyz, msg, skip_nans=False) is not None
    structured = np.zeros(n, dtype=[("x", dtype), ("y", dtype), ("z", dtype)][:cols])
    msg = only_visnav_errors(structured_to_cloud, structured)
    if msg is not None:
        only_visnav_errors(cloud_to_structured, msg)
