"""Tests of visnav.msgs.pointcloud: PointCloud2 <-> numpy with sensor_msgs_py semantics.

A slow reference writer (``struct.pack`` per point and field) builds clouds of
random layouts; the fast numpy readers and writers are checked against it.
"""

from __future__ import annotations

import struct
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.msgs import (
    Header,
    MessageError,
    PointCloud2,
    PointField,
    Time,
    deserialize,
    serialize,
)
from visnav.msgs.pointcloud import (
    POINTFIELD_DTYPES,
    cloud_to_structured,
    cloud_to_xyz,
    dtype_to_fields,
    fields_to_dtype,
    pack_rgb,
    structured_to_cloud,
    unpack_rgb,
    xyz_to_cloud,
)

STRUCT_CODE = {1: "b", 2: "B", 3: "h", 4: "H", 5: "i", 6: "I", 7: "f", 8: "d"}
NATIVE_BIG = sys.byteorder == "big"


@dataclass
class Layout:
    names: list[str]
    datatypes: list[int]
    counts: list[int]
    offsets: list[int]
    point_step: int
    height: int
    width: int
    row_pad: int
    big: bool

    @property
    def row_step(self) -> int:
        return self.width * self.point_step + self.row_pad

    def fields(self) -> list[PointField]:
        return [
            PointField(name=n, offset=o, datatype=d, count=c)
            for n, o, d, c in zip(
                self.names, self.offsets, self.datatypes, self.counts, strict=True
            )
        ]


@st.composite
def layouts(draw: st.DrawFn) -> Layout:
    pool = ["x", "y", "z", "intensity", "ring", "t", "rgb", "normal"]
    names = draw(st.lists(st.sampled_from(pool), min_size=1, max_size=5, unique=True))
    datatypes = [draw(st.integers(1, 8)) for _ in names]
    counts = [1 if n in "xyz" else draw(st.integers(1, 3)) for n in names]
    offsets = []
    offset = 0
    for dt, count in zip(datatypes, counts, strict=True):
        offset += draw(st.integers(0, 3))  # gap before the field (unaligned on purpose)
        offsets.append(offset)
        offset += POINTFIELD_DTYPES[dt].itemsize * count
    point_step = offset + draw(st.integers(0, 8))
    order = draw(st.permutations(range(len(names))))  # PointField order need not follow offsets
    return Layout(
        names=[names[i] for i in order],
        datatypes=[datatypes[i] for i in order],
        counts=[counts[i] for i in order],
        offsets=[offsets[i] for i in order],
        point_step=point_step,
        height=draw(st.integers(0, 4)),
        width=draw(st.integers(0, 5)),
        row_pad=draw(st.integers(0, 7)),
        big=draw(st.booleans()),
    )


def random_values(layout: Layout, seed: int) -> dict[str, np.ndarray]:
    """Per field, (N,) or (N, count) values; floats get NaNs about one time in five."""
    rng = np.random.default_rng(seed)
    n = layout.height * layout.width
    out = {}
    for name, dt, count in zip(layout.names, layout.datatypes, layout.counts, strict=True):
        dtype = POINTFIELD_DTYPES[dt]
        shape = (n,) if count == 1 else (n, count)
        if dtype.kind == "f":
            values = rng.normal(0.0, 100.0, shape).astype(dtype)
            values[rng.random(shape) < 0.2] = np.nan
        else:
            info = np.iinfo(dtype)
            values = rng.integers(info.min, int(info.max) + 1, shape, dtype=dtype)
        out[name] = values
    return out


def reference_cloud(
    layout: Layout, values: dict[str, np.ndarray], *, seed: int, garbage: bool = True
) -> PointCloud2:
    """Slow reference writer: struct.pack every value; padding is random garbage or zero."""
    size = layout.row_step * layout.height
    rng = np.random.default_rng(seed + 1)
    data = (
        bytearray(rng.integers(0, 256, size, dtype=np.uint8).tobytes())
        if garbage
        else (bytearray(size))
    )
    prefix = ">" if layout.big else "<"
    for r in range(layout.height):
        for c in range(layout.width):
            i = r * layout.width + c
            base = r * layout.row_step + c * layout.point_step
            for name, off, dt, count in zip(
                layout.names, layout.offsets, layout.datatypes, layout.counts, strict=True
            ):
                v = np.atleast_1d(values[name][i]).tolist()
                struct.pack_into(prefix + STRUCT_CODE[dt] * count, data, base + off, *v)
    return PointCloud2(
        header=Header(stamp=Time(sec=3, nanosec=4), frame_id="lidar"),
        height=layout.height,
        width=layout.width,
        fields=layout.fields(),
        is_bigendian=layout.big,
        point_step=layout.point_step,
        row_step=layout.row_step,
        data=np.frombuffer(bytes(data), np.uint8),
        is_dense=False,
    )


def invalid_rows(layout: Layout, values: dict[str, np.ndarray]) -> np.ndarray:
    """Reference NaN rule: NaN in x/y/z, or in any float field if the cloud has no x/y/z."""
    n = layout.height * layout.width
    names = [k for k in "xyz" if k in values] or list(values)
    bad = np.zeros(n, bool)
    for name in names:
        v = values[name]
        if v.dtype.kind == "f":
            bad |= np.isnan(v) if v.ndim == 1 else np.isnan(v).any(axis=1)
    return bad


def assert_values(points: np.ndarray, values: dict[str, np.ndarray], names: list[str]) -> None:
    assert list(points.dtype.names or ()) == names
    for name in names:
        got = points[name]
        assert got.dtype == values[name].dtype
        assert got.dtype.isnative
        np.testing.assert_array_equal(got, values[name])


# ---------------------------------------------------------------- property tests


@settings(max_examples=150, deadline=None)
@given(layout=layouts(), seed=st.integers(0, 2**31), data=st.data())
def test_read_random_layouts_against_reference(layout: Layout, seed: int, data: Any) -> None:
    values = random_values(layout, seed)
    msg = reference_cloud(layout, values, seed=seed)
    before = msg.data.tobytes()

    points = cloud_to_structured(msg)
    assert points.shape == (layout.height * layout.width,)
    assert points.dtype.itemsize == layout.point_step
    assert_values(points, values, layout.names)

    keep = data.draw(st.lists(st.sampled_from(layout.names), min_size=1, unique=True))
    assert_values(cloud_to_structured(msg, field_names=keep), values, keep)

    bad = invalid_rows(layout, values)
    kept = cloud_to_structured(msg, skip_nans=True)
    assert_values(kept, {k: v[~bad] for k, v in values.items()}, layout.names)

    if {"x", "y", "z"} <= set(layout.names):
        xyz = np.stack([values[k].astype(np.float32) for k in "xyz"], axis=1)
        np.testing.assert_array_equal(cloud_to_xyz(msg, skip_nans=False), xyz)
        np.testing.assert_array_equal(cloud_to_xyz(msg), xyz[~np.isnan(xyz).any(axis=1)])

    assert msg.data.tobytes() == before  # reading never modifies the message


@settings(max_examples=150, deadline=None)
@given(layout=layouts(), seed=st.integers(0, 2**31))
def test_write_random_layouts_round_trip(layout: Layout, seed: int) -> None:
    values = random_values(layout, seed)
    points = cloud_to_structured(reference_cloud(layout, values, seed=seed))
    if layout.height > 1:
        points = points.reshape(layout.height, layout.width)  # organized input

    msg = structured_to_cloud(points, header=Header(stamp=Time(sec=1, nanosec=2), frame_id="f"))
    height = layout.height if layout.height > 1 else 1
    width = layout.width if layout.height > 1 else layout.height * layout.width
    assert (msg.height, msg.width) == (height, width)
    assert msg.point_step == layout.point_step
    assert msg.row_step == width * layout.point_step
    assert msg.is_bigendian is False
    assert msg.header.frame_id == "f"
    got_fields = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    assert got_fields == [(f.name, f.offset, f.datatype, f.count) for f in layout.fields()]
    assert msg.is_dense == (not invalid_rows(layout, values).any())

    # byte-exact against the reference writer: little endian, zero padding, no row padding
    plain = Layout(**{**layout.__dict__, "big": False, "row_pad": 0})
    plain.height, plain.width = height, width
    assert (
        msg.data.tobytes()
        == reference_cloud(plain, values, seed=seed, garbage=False).data.tobytes()
    )

    back = cloud_to_structured(deserialize(serialize(msg), "sensor_msgs/msg/PointCloud2"))
    assert_values(back, values, layout.names)


# ---------------------------------------------------------------- xyz / rgb


@settings(max_examples=100, deadline=None)
@given(
    shape=st.one_of(st.tuples(st.integers(0, 30)), st.tuples(st.integers(1, 5), st.integers(1, 6))),
    with_rgb=st.booleans(),
    nan_rate=st.sampled_from([0.0, 0.3, 1.0]),
    seed=st.integers(0, 2**31),
)
def test_xyz_cloud_round_trip(
    shape: tuple[int, ...], with_rgb: bool, nan_rate: float, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    pts = rng.normal(0, 10, (*shape, 3)).astype(np.float32)
    pts[rng.random(pts.shape) < nan_rate] = np.nan
    rgb = rng.integers(0, 256, pts.shape, dtype=np.uint8) if with_rgb else None
    msg = xyz_to_cloud(pts, rgb=rgb)
    n = int(np.prod(shape))
    flat = pts.reshape(n, 3)
    valid = ~np.isnan(flat).any(axis=1)
    organized = len(shape) == 2
    assert (msg.height, msg.width) == (shape if organized else (1, shape[0]))
    assert msg.point_step == (32 if with_rgb else 16)
    assert msg.is_dense == bool(valid.all())
    records = msg.data.reshape(n, msg.point_step)
    assert records[:, :12].tobytes() == flat.astype("<f4").tobytes()
    assert not records[:, 12:16].any()
    if rgb is not None:
        assert records[:, 16:19].tobytes() == rgb.reshape(n, 3)[:, ::-1].tobytes()
        assert not records[:, 19:].any()
        np.testing.assert_array_equal(
            unpack_rgb(cloud_to_structured(msg, skip_nans=True)["rgb"]), rgb.reshape(n, 3)[valid]
        )
    np.testing.assert_array_equal(cloud_to_xyz(msg, skip_nans=False), flat)
    kept = cloud_to_xyz(msg)
    assert kept.flags.c_contiguous
    np.testing.assert_array_equal(kept, flat[valid])
    # the generic (structured) path agrees with the fast path
    structured = cloud_to_structured(msg, skip_nans=True)
    np.testing.assert_array_equal(np.stack([structured[k] for k in "xyz"], axis=-1), flat[valid])


def test_xyz_to_cloud_layout_matches_depth_image_proc() -> None:
    pts = np.array([[1, 2, 3], [4, 5, 6]], np.float64)
    msg = xyz_to_cloud(pts)
    assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
        ("x", 0, PointField.FLOAT32, 1),
        ("y", 4, PointField.FLOAT32, 1),
        ("z", 8, PointField.FLOAT32, 1),
    ]
    assert (msg.point_step, msg.row_step, msg.height, msg.width) == (16, 32, 1, 2)
    assert msg.is_dense is True
    raw = msg.data.reshape(2, 16)
    assert raw[:, 12:].tolist() == [[0] * 4] * 2  # padding is zero
    np.testing.assert_array_equal(raw[:, :12].copy().view("<f4"), pts.astype(np.float32))


def test_xyz_rgb_layout_and_packing() -> None:
    pts = np.zeros((3, 3), np.float32)
    rgb = np.array([[255, 0, 0], [0, 255, 0], [1, 2, 3]], np.uint8)
    msg = xyz_to_cloud(pts, rgb=rgb)
    assert [(f.name, f.offset, f.datatype) for f in msg.fields][3] == (
        "rgb",
        16,
        PointField.FLOAT32,
    )
    assert msg.point_step == 32
    words = msg.data.reshape(3, 32)[:, 16:20].copy().view("<u4").reshape(-1)
    assert [hex(w) for w in words] == ["0xff0000", "0xff00", "0x10203"]
    assert msg.data.reshape(3, 32)[:, 20:].max() == 0
    points = cloud_to_structured(msg)
    np.testing.assert_array_equal(unpack_rgb(points["rgb"]), rgb)
    np.testing.assert_array_equal(unpack_rgb(points["rgb"].view(np.uint32)), rgb)


def test_pack_unpack_rgb_ignores_alpha_byte() -> None:
    words = np.array([0xFF102030, 0x00405060], np.uint32)
    np.testing.assert_array_equal(unpack_rgb(words), [[0x10, 0x20, 0x30], [0x40, 0x50, 0x60]])
    np.testing.assert_array_equal(unpack_rgb(words.view(np.float32)), unpack_rgb(words))
    rgb = np.random.default_rng(0).integers(0, 256, (4, 5, 3), dtype=np.uint8)
    packed = pack_rgb(rgb)
    assert packed.shape == (4, 5)
    assert packed.dtype == np.float32
    np.testing.assert_array_equal(unpack_rgb(packed), rgb)


def test_organized_cloud_keeps_every_point_in_order() -> None:
    pts = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    pts[0, 1] = np.nan
    msg = xyz_to_cloud(pts, header=Header(stamp=Time(sec=0, nanosec=0), frame_id="cam"))
    assert (msg.height, msg.width, msg.row_step) == (2, 3, 48)
    assert msg.is_dense is False
    all_points = cloud_to_xyz(msg, skip_nans=False)
    np.testing.assert_array_equal(all_points, pts.reshape(-1, 3))
    assert cloud_to_structured(msg).shape == (6,)
    assert cloud_to_structured(msg, skip_nans=True).shape == (5,)
    kept = cloud_to_xyz(msg)
    np.testing.assert_array_equal(kept, np.delete(pts.reshape(-1, 3), 1, axis=0))


def test_cloud_to_xyz_fast_path_is_a_view() -> None:
    msg = xyz_to_cloud(np.ones((4, 3)))
    xyz = cloud_to_xyz(msg, skip_nans=False)
    assert np.shares_memory(xyz, msg.data)
    assert xyz.dtype == np.float32
    assert xyz.shape == (4, 3)
    assert not np.shares_memory(cloud_to_xyz(msg), msg.data)


def test_cloud_to_xyz_slow_paths_agree_with_fast() -> None:
    pts = np.random.default_rng(1).normal(size=(7, 3))
    fast = cloud_to_xyz(xyz_to_cloud(pts), skip_nans=False)
    f64 = np.zeros(7, dtype=[("z", "f8"), ("y", "f8"), ("x", "f8")])
    f64["x"], f64["y"], f64["z"] = pts.T
    np.testing.assert_allclose(cloud_to_xyz(structured_to_cloud(f64)), fast)
    big = np.zeros(7, dtype=[("x", ">f4"), ("y", ">f4"), ("z", ">f4")])
    big["x"], big["y"], big["z"] = pts.T
    msg = structured_to_cloud(big)  # written little endian ...
    swapped = PointCloud2(  # ... so re-encode by hand as big endian with padded rows
        header=msg.header,
        height=1,
        width=7,
        fields=msg.fields,
        is_bigendian=True,
        point_step=12,
        row_step=12 * 7 + 5,
        data=np.concatenate([big.view(np.uint8), np.zeros(5, np.uint8)]),
        is_dense=True,
    )
    np.testing.assert_array_equal(cloud_to_xyz(swapped), fast)


def test_structured_to_cloud_is_dense_override_and_default_header() -> None:
    arr = np.zeros(2, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    arr["x"][0] = np.nan
    assert structured_to_cloud(arr).is_dense is False
    msg = structured_to_cloud(arr, is_dense=True)
    assert msg.is_dense is True
    assert msg.header.frame_id == ""
    no_xyz = np.zeros(2, dtype=[("intensity", "f4")])
    no_xyz["intensity"][1] = np.nan
    assert structured_to_cloud(no_xyz).is_dense is False


def test_count_field_and_unnamed_field() -> None:
    msg = PointCloud2(
        header=Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
        height=1,
        width=2,
        fields=[
            PointField(name="", offset=0, datatype=PointField.UINT16, count=3),
            PointField(name="w", offset=6, datatype=PointField.INT8, count=0),
        ],
        is_bigendian=False,
        point_step=8,
        row_step=16,
        data=np.array([1, 0, 2, 0, 3, 0, 255, 9, 4, 0, 5, 0, 6, 0, 1, 9], np.uint8),
        is_dense=True,
    )
    points = cloud_to_structured(msg)
    assert points.dtype.names == ("unnamed_field_0", "w")
    assert points["unnamed_field_0"].tolist() == [[1, 2, 3], [4, 5, 6]]
    assert points["w"].tolist() == [-1, 1]  # count 0 read as 1


def test_read_is_zero_copy_for_native_unpadded_clouds() -> None:
    msg = xyz_to_cloud(np.ones((3, 3)))
    msg.is_bigendian = NATIVE_BIG
    points = cloud_to_structured(msg)
    assert np.shares_memory(points, msg.data)


def test_empty_cloud() -> None:
    msg = xyz_to_cloud(np.zeros((0, 3)))
    assert (msg.width, msg.data.size, msg.is_dense) == (0, 0, True)
    assert cloud_to_xyz(msg).shape == (0, 3)
    assert cloud_to_structured(msg).shape == (0,)
    default = PointCloud2(
        header=Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
        height=0,
        width=0,
        fields=[],
        is_bigendian=False,
        point_step=0,
        row_step=0,
        data=np.zeros(0, np.uint8),
        is_dense=False,
    )
    assert cloud_to_structured(default).shape == (0,)


def test_dtype_fields_helpers_round_trip() -> None:
    fields = [
        PointField(name="x", offset=0, datatype=PointField.FLOAT32, count=1),
        PointField(name="n", offset=4, datatype=PointField.FLOAT64, count=3),
        PointField(name="ring", offset=28, datatype=PointField.UINT16, count=1),
    ]
    dtype = fields_to_dtype(fields, 32)
    assert dtype.itemsize == 32
    assert dtype_to_fields(dtype) == fields
    assert fields_to_dtype(fields, 32, is_bigendian=True)["n"].base == np.dtype(">f8")


# ---------------------------------------------------------------- errors


def make(**overrides: Any) -> PointCloud2:
    fields: dict[str, Any] = {
        "header": Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
        "height": 2,
        "width": 3,
        "fields": [
            PointField(name="x", offset=0, datatype=PointField.FLOAT32, count=1),
            PointField(name="y", offset=4, datatype=PointField.FLOAT32, count=1),
            PointField(name="z", offset=8, datatype=PointField.FLOAT32, count=1),
        ],
        "is_bigendian": False,
        "point_step": 16,
        "row_step": 48,
        "data": np.zeros(96, np.uint8),
        "is_dense": True,
    }
    fields.update(overrides)
    return PointCloud2(**fields)


def test_error_data_length() -> None:
    with pytest.raises(MessageError, match=r"data has 95 bytes: expected row_step \* height .*96"):
        cloud_to_structured(make(data=np.zeros(95, np.uint8)))
    with pytest.raises(MessageError, match="data has 97 bytes"):
        cloud_to_xyz(make(data=np.zeros(97, np.uint8)))


def test_error_row_step_too_small() -> None:
    with pytest.raises(MessageError, match=r"row_step is 40: expected at least .* = 48"):
        cloud_to_structured(make(row_step=40, data=np.zeros(80, np.uint8)))


def test_error_point_step_smaller_than_fields() -> None:
    with pytest.raises(MessageError, match=r"point_step is 10: smaller than field 'z'.*= 12"):
        cloud_to_structured(make(point_step=10, row_step=30, data=np.zeros(60, np.uint8)))


def test_error_unknown_datatype() -> None:
    bad = [PointField(name="x", offset=0, datatype=9, count=1)]
    with pytest.raises(MessageError, match=r"fields\[0\] \('x'\).datatype is 9: expected 1..8"):
        cloud_to_structured(make(fields=bad))


def test_error_duplicate_field() -> None:
    dup = [PointField(name="x", offset=o, datatype=PointField.FLOAT32, count=1) for o in (0, 4)]
    with pytest.raises(MessageError, match="two fields named 'x'"):
        cloud_to_structured(make(fields=dup))


def test_error_missing_xyz() -> None:
    no_z = make().fields[:2]
    with pytest.raises(MessageError, match=r"no field 'z': it has \['x', 'y'\]"):
        cloud_to_xyz(make(fields=no_z))


def test_error_unknown_field_name() -> None:
    with pytest.raises(MessageError, match=r"field_names asks for \['rgb'\]"):
        cloud_to_structured(make(), field_names=["x", "rgb"])


def test_error_wrong_array_shapes() -> None:
    with pytest.raises(MessageError, match=r"shape \(4, 2\): expected real numbers"):
        xyz_to_cloud(np.zeros((4, 2)))
    with pytest.raises(MessageError, match="shape"):
        xyz_to_cloud(np.zeros(3))
    with pytest.raises(MessageError, match=r"rgb has shape \(3, 3\): expected the points' shape"):
        xyz_to_cloud(np.zeros((4, 3)), rgb=np.zeros((3, 3), np.uint8))
    with pytest.raises(MessageError, match="rgb has dtype float64"):
        xyz_to_cloud(np.zeros((4, 3)), rgb=np.zeros((4, 3)))
    with pytest.raises(MessageError, match="expected a structured array"):
        structured_to_cloud(np.zeros((4, 3), np.float32))
    with pytest.raises(MessageError, match=r"expected \(N,\) or organized"):
        structured_to_cloud(np.zeros((2, 2, 2), dtype=[("x", "f4")]))
    with pytest.raises(MessageError, match="field 'i' has dtype int64"):
        structured_to_cloud(np.zeros(2, dtype=[("x", "f4"), ("i", "i8")]))
    with pytest.raises(MessageError, match="values have dtype float64"):
        unpack_rgb(np.zeros(3))
