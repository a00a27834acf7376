"""``sensor_msgs/PointCloud2`` <-> numpy, with sensor_msgs_py ``point_cloud2`` semantics.

A cloud's ``fields`` become a numpy structured dtype: each ``PointField`` is a
named field at its ``offset`` (a sub-array of ``count`` elements when
``count > 1``) and the dtype's itemsize is ``point_step``, so padded layouts
(PCL's 16-byte ``PointXYZ``, 32-byte ``PointXYZRGB``) survive a round trip.

Layout written by :func:`xyz_to_cloud` (the layout ``PointCloud2Modifier::
setPointCloud2FieldsByString("xyz", "rgb")`` produces and depth_image_proc
publishes, byte-compatible with PCL's ``PointXYZ`` / ``PointXYZRGB``):

=========  ======  =======  ==========================================
field      offset  type     note
=========  ======  =======  ==========================================
x, y, z    0,4,8   FLOAT32  bytes 12..15 are zero padding
rgb        16      FLOAT32  with colours only: bits 0x00RRGGBB; 20..31 pad
=========  ======  =======  ==========================================

``point_step`` is 16 without colours and 32 with them (sensor_msgs_py's
``create_cloud_xyz32`` packs 12-byte points instead; both read the same).

Invalid points are those with NaN in any of x, y, z (or, in a cloud without
x/y/z, in any of its floating-point fields). ``skip_nans=True`` drops them;
organized clouds (``height > 1``) keep every point with ``skip_nans=False``.

Differences from sensor_msgs_py: ``row_step`` padding and ``count > 1`` are
honoured, the message is never modified (sensor_msgs_py byte-swaps
``cloud.data`` in place), ``skip_nans`` checks x/y/z only and does not trust
``is_dense``, and inconsistent messages raise :class:`MessageError` instead of
failing an ``assert`` or reading garbage.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.msgs.errors import MessageError
from visnav.msgs.types import Header, PointCloud2, PointField, Time

__all__ = [
    "POINTFIELD_DTYPES",
    "cloud_to_structured",
    "cloud_to_xyz",
    "dtype_to_fields",
    "fields_to_dtype",
    "pack_rgb",
    "structured_to_cloud",
    "unpack_rgb",
    "xyz_to_cloud",
]

POINTFIELD_DTYPES: dict[int, np.dtype[Any]] = {
    PointField.INT8: np.dtype(np.int8),
    PointField.UINT8: np.dtype(np.uint8),
    PointField.INT16: np.dtype(np.int16),
    PointField.UINT16: np.dtype(np.uint16),
    PointField.INT32: np.dtype(np.int32),
    PointField.UINT32: np.dtype(np.uint32),
    PointField.FLOAT32: np.dtype(np.float32),
    PointField.FLOAT64: np.dtype(np.float64),
}
"""``PointField.datatype`` constant -> numpy dtype (native byte order)."""

_DATATYPE_OF: dict[tuple[str, int], int] = {
    (dt.kind, dt.itemsize): code for code, dt in POINTFIELD_DTYPES.items()
}
_XYZ = ("x", "y", "z")
# depth_image_proc / PCL layouts (see the module docstring).
_XYZ_DTYPE = np.dtype(
    {"names": ["x", "y", "z"], "formats": ["<f4"] * 3, "offsets": [0, 4, 8], "itemsize": 16}
)
_XYZRGB_DTYPE = np.dtype(
    {
        "names": ["x", "y", "z", "rgb"],
        "formats": ["<f4"] * 4,
        "offsets": [0, 4, 8, 16],
        "itemsize": 32,
    }
)


def _default_header() -> Header:
    return Header(stamp=Time(sec=0, nanosec=0), frame_id="")


def fields_to_dtype(
    fields: list[PointField], point_step: int, *, is_bigendian: bool = False
) -> np.dtype[Any]:
    """Return the structured numpy dtype of one point described by ``fields``.

    Args:
        fields: the cloud's ``PointField`` list. An empty name becomes
            ``unnamed_field_<i>`` (as sensor_msgs_py); ``count`` 0 is read as 1.
        point_step: bytes per point; the dtype's itemsize.
        is_bigendian: byte order of multi-byte fields.

    Returns:
        A structured dtype with the fields' names, types and offsets.

    Raises:
        MessageError: unknown datatype, duplicate name, a negative ``point_step``, or
            a field reaching past ``point_step``.
    """
    if int(point_step) < 0:
        text = f"PointCloud2.point_step is {point_step}: expected a size >= 0 (uint32 in ROS)"
        raise MessageError(text)
    names: list[str] = []
    formats: list[Any] = []
    offsets: list[int] = []
    for i, field in enumerate(fields):
        name = field.name or f"unnamed_field_{i}"
        base = POINTFIELD_DTYPES.get(int(field.datatype))
        if base is None:
            text = (
                f"PointCloud2.fields[{i}] ({name!r}).datatype is {field.datatype}: expected "
                "1..8 (INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64)"
            )
            raise MessageError(text)
        if name in names:
            text = f"PointCloud2.fields has two fields named {name!r}: names must be unique"
            raise MessageError(text)
        count = max(int(field.count), 1)
        offset = int(field.offset)
        end = offset + base.itemsize * count
        if offset < 0 or end > point_step:
            text = (
                f"PointCloud2.point_step is {point_step}: smaller than field {name!r} "
                f"(offset {offset} + {count} x {base.itemsize} bytes = {end}); "
                f"point_step must be at least {end}"
            )
            raise MessageError(text)
        dt = base.newbyteorder(">" if is_bigendian else "<")
        names.append(name)
        formats.append((dt, (count,)) if count > 1 else dt)
        offsets.append(offset)
    return np.dtype(
        {"names": names, "formats": formats, "offsets": offsets, "itemsize": int(point_step)}
    )


def dtype_to_fields(dtype: np.dtype[Any]) -> list[PointField]:
    """Return the ``PointField`` list describing a structured dtype.

    Args:
        dtype: a structured dtype whose fields are int8..int32, uint8..uint32,
            float32 or float64, optionally sub-arrays (``count`` = their size).

    Returns:
        One ``PointField`` per dtype field, in dtype order.

    Raises:
        MessageError: not structured, or a field type PointField cannot hold.
    """
    if dtype.names is None or not dtype.names:
        text = f"dtype {dtype} has no named fields: expected a structured dtype like [('x', 'f4')]"
        raise MessageError(text)
    out: list[PointField] = []
    for name in dtype.names:
        field_dtype, offset = dtype.fields[name][:2]  # type: ignore[index]
        count = 1
        if field_dtype.subdtype is not None:
            field_dtype, shape = field_dtype.subdtype
            count = int(np.prod(shape))
        code = _DATATYPE_OF.get((field_dtype.kind, field_dtype.itemsize))
        if code is None or field_dtype.names is not None:
            text = (
                f"field {name!r} has dtype {field_dtype}: PointField holds only int8..int32, "
                "uint8..uint32, float32 and float64; convert it with astype first"
            )
            raise MessageError(text)
        out.append(PointField(name=name, offset=int(offset), datatype=code, count=count))
    return out


def _data_bytes(data: Any) -> NDArray[np.uint8]:
    if isinstance(data, np.ndarray):
        if data.dtype != np.uint8:
            text = f"PointCloud2.data has dtype {data.dtype}: expected a uint8 array (or bytes)"
            raise MessageError(text)
        return np.ascontiguousarray(data).reshape(-1)
    if isinstance(data, (bytes, bytearray, memoryview)):
        return np.frombuffer(data, dtype=np.uint8)
    try:
        return np.asarray(data, dtype=np.uint8).reshape(-1)
    except (TypeError, ValueError, OverflowError) as exc:
        text = f"PointCloud2.data is a {type(data).__name__}: expected uint8 array or bytes"
        raise MessageError(text) from exc


def _checked_buffer(msg: PointCloud2) -> NDArray[np.uint8]:
    """Validate a cloud's sizes and return its data as flat uint8."""
    height, width = int(msg.height), int(msg.width)
    point_step, row_step = int(msg.point_step), int(msg.row_step)
    sizes = {"height": height, "width": width, "point_step": point_step, "row_step": row_step}
    for name, value in sizes.items():
        if value < 0:
            text = f"PointCloud2.{name} is {value}: expected a size >= 0 (uint32 in ROS)"
            raise MessageError(text)
    if row_step < width * point_step:
        text = (
            f"PointCloud2.row_step is {row_step}: expected at least width * point_step = "
            f"{width} * {point_step} = {width * point_step}"
        )
        raise MessageError(text)
    buf = _data_bytes(msg.data)
    if buf.size != row_step * height:
        text = (
            f"PointCloud2.data has {buf.size} bytes: expected row_step * height = "
            f"{row_step} * {height} = {row_step * height}; "
            "the message is truncated or its height/row_step are wrong"
        )
        raise MessageError(text)
    return buf


def _invalid_mask(points: NDArray[Any], names: tuple[str, ...]) -> NDArray[np.bool_]:
    """Return True for points with NaN in any of ``names``."""
    bad = np.zeros(points.shape, dtype=bool)
    for name in names:
        values = points[name]
        if values.dtype.kind != "f":
            continue
        nan = np.isnan(values)
        bad |= nan.any(axis=tuple(range(points.ndim, nan.ndim)))  # count > 1: any element
    return bad


def _validity_fields(dtype: np.dtype[Any]) -> tuple[str, ...]:
    names = dtype.names or ()
    xyz = tuple(n for n in _XYZ if n in names)
    return xyz or tuple(names)


def cloud_to_structured(
    msg: PointCloud2, *, field_names: list[str] | None = None, skip_nans: bool = False
) -> NDArray[Any]:
    """Return a cloud's points as a 1-D structured array (sensor_msgs_py ``read_points``).

    Args:
        msg: the ``sensor_msgs/PointCloud2``.
        field_names: fields to keep (default all); the result keeps the cloud's
            offsets and itemsize, so it is still a view where possible.
        skip_nans: drop points with NaN in x, y or z (any float field if the
            cloud has no x/y/z).

    Returns:
        A structured array of ``width * height`` points (row-major for
        organized clouds) in native byte order. Without row padding, byte swap
        or NaN skipping it is a view on ``msg.data`` (read-only if that is).

    Raises:
        MessageError: sizes inconsistent, field layout invalid, or an unknown
            field requested.
    """
    dtype = fields_to_dtype(msg.fields, int(msg.point_step), is_bigendian=bool(msg.is_bigendian))
    buf = _checked_buffer(msg)
    height, width = int(msg.height), int(msg.width)
    row_step, count = int(msg.row_step), int(msg.height) * int(msg.width)
    if count == 0:
        points: NDArray[Any] = np.zeros(0, dtype=dtype)
    elif row_step == width * dtype.itemsize:
        points = np.ndarray((count,), dtype=dtype, buffer=buf)
    else:
        rows: NDArray[Any] = np.ndarray(
            (height, width), dtype=dtype, buffer=buf, strides=(row_step, dtype.itemsize)
        )
        points = rows.reshape(-1)
    all_names = dtype.names or ()
    if field_names is not None:
        missing = [n for n in field_names if n not in all_names]
        if missing:
            text = (
                f"field_names asks for {missing}: the cloud has fields {list(all_names)}; "
                "pick from those"
            )
            raise MessageError(text)
    if skip_nans:  # compress: several times faster than boolean indexing of records
        points = points.compress(~_invalid_mask(points, _validity_fields(dtype)))
    if field_names is not None:
        points = points[list(field_names)]
    native = points.dtype.newbyteorder("=")
    if native != points.dtype:  # not dtype.isnative: numpy misreports sub-array fields
        points = points.astype(native)
    return points


def structured_to_cloud(
    array: ArrayLike, *, header: Header | None = None, is_dense: bool | None = None
) -> PointCloud2:
    """Return a cloud holding a copy of a structured array (fields from its dtype).

    Args:
        array: a 1-D structured array (unorganized cloud, ``height`` 1) or 2-D
            (organized, ``height, width``). Field offsets and itemsize are kept
            as ``offset`` / ``point_step``; padding bytes are written as zero.
        header: the message header (default: zero stamp, empty frame_id).
        is_dense: the ``is_dense`` flag; default computed (no NaN in x/y/z).

    Returns:
        The ``sensor_msgs/PointCloud2``, little endian, ``data`` a new uint8 array.

    Raises:
        MessageError: not a 1-D/2-D structured array or a field type PointField
            cannot hold.
    """
    arr = np.asarray(array)
    if arr.dtype.names is None:
        text = (
            f"array has dtype {arr.dtype} and shape {arr.shape}: expected a structured array "
            "(dtype with named fields); for (N, 3) points use xyz_to_cloud"
        )
        raise MessageError(text)
    if arr.ndim not in (1, 2):
        text = f"array has shape {arr.shape}: expected (N,) or organized (height, width)"
        raise MessageError(text)
    fields = dtype_to_fields(arr.dtype)
    little = arr.dtype.newbyteorder("<")
    out: NDArray[Any] = np.zeros(arr.shape, dtype=little)
    for name in little.names or ():
        out[name] = arr[name]
    height, width = (1, arr.shape[0]) if arr.ndim == 1 else arr.shape
    if is_dense is None:
        is_dense = not bool(_invalid_mask(arr, _validity_fields(arr.dtype)).any())
    return PointCloud2(
        header=header if header is not None else _default_header(),
        height=int(height),
        width=int(width),
        fields=fields,
        is_bigendian=False,
        point_step=little.itemsize,
        row_step=little.itemsize * int(width),
        data=out.reshape(-1).view(np.uint8),
        is_dense=bool(is_dense),
    )


def _checked_rgb(rgb: ArrayLike) -> NDArray[np.uint8]:
    arr = np.asarray(rgb)
    if arr.dtype != np.uint8 or arr.ndim < 1 or arr.shape[-1] != 3:
        text = (
            f"rgb has dtype {arr.dtype} and shape {arr.shape}: expected uint8 (..., 3) in 0..255; "
            "for 0..1 floats use (rgb * 255).round().astype(np.uint8)"
        )
        raise MessageError(text)
    return arr


def pack_rgb(rgb: ArrayLike) -> NDArray[np.float32]:
    """Pack (..., 3) uint8 colours into ROS ``rgb`` floats (bits 0x00RRGGBB as float32).

    Raises:
        MessageError: not uint8 with a last axis of 3.
    """
    arr = _checked_rgb(rgb)
    c = arr.astype(np.uint32)
    packed = (c[..., 0] << 16) | (c[..., 1] << 8) | c[..., 2]
    return packed.view(np.float32)


def unpack_rgb(values: ArrayLike) -> NDArray[np.uint8]:
    """Unpack ROS ``rgb``/``rgba`` field values into (..., 3) uint8 colours.

    Args:
        values: float32 values (bits reinterpreted) or uint32/int32 integers,
            colour in bits 0x00RRGGBB (the top byte, alpha, is ignored).

    Returns:
        Shape ``values.shape + (3,)``, channels R, G, B.

    Raises:
        MessageError: a dtype that is not a 4-byte float or integer.
    """
    arr = np.asarray(values)
    if arr.dtype.kind not in "fiu" or arr.dtype.itemsize != 4:
        text = (
            f"values have dtype {arr.dtype}: expected the float32 (or uint32) 'rgb' field "
            "of a cloud"
        )
        raise MessageError(text)
    bits = arr.astype(arr.dtype.newbyteorder("="), copy=False).view(np.uint32)
    out = np.empty((*arr.shape, 3), dtype=np.uint8)
    out[..., 0] = (bits >> 16) & 0xFF
    out[..., 1] = (bits >> 8) & 0xFF
    out[..., 2] = bits & 0xFF
    return out


def xyz_to_cloud(
    points: ArrayLike, *, header: Header | None = None, rgb: ArrayLike | None = None
) -> PointCloud2:
    """Return a cloud of x, y, z float32 points, optionally with packed ``rgb``.

    The layout is the one depth_image_proc / PCL use (see the module docstring):
    ``point_step`` 16 (x, y, z, pad) or 32 with ``rgb`` at offset 16.

    Args:
        points: (N, 3) points (``height`` 1), or (H, W, 3) for an organized
            cloud; any real dtype, stored as float32.
        header: the message header (default: zero stamp, empty frame_id).
        rgb: uint8 colours with the same shape as ``points``.

    Returns:
        The ``sensor_msgs/PointCloud2``; ``is_dense`` is whether no point has NaN.

    Raises:
        MessageError: wrong shapes or dtypes.
    """
    pts = np.asarray(points)
    if pts.ndim not in (2, 3) or pts.shape[-1] != 3 or pts.dtype.kind not in "fiu":
        text = (
            f"points have dtype {pts.dtype} and shape {pts.shape}: expected real numbers "
            "shaped (N, 3), or (H, W, 3) for an organized cloud"
        )
        raise MessageError(text)
    colours = None
    if rgb is not None:
        colours = _checked_rgb(rgb)
        if colours.shape != pts.shape:
            text = f"rgb has shape {colours.shape}: expected the points' shape {pts.shape}"
            raise MessageError(text)
    dtype = _XYZ_DTYPE if colours is None else _XYZRGB_DTYPE
    height, width = (1, pts.shape[0]) if pts.ndim == 2 else pts.shape[:2]
    count = int(height) * int(width)
    step = dtype.itemsize
    # Write straight into the message bytes (one allocation, no temporaries).
    data = np.zeros(count * step, dtype=np.uint8)
    records = data.reshape(count, step)
    records[:, :12].view("<f4")[...] = pts.reshape(count, 3)
    if colours is not None:  # little-endian 0x00RRGGBB: bytes B, G, R, 0
        records[:, 16:19] = colours.reshape(count, 3)[:, ::-1]
    return PointCloud2(
        header=header if header is not None else _default_header(),
        height=int(height),
        width=int(width),
        fields=dtype_to_fields(dtype),
        is_bigendian=False,
        point_step=step,
        row_step=step * int(width),
        data=data,
        is_dense=not (pts.dtype.kind == "f" and bool(np.isnan(pts).any())),
    )


def cloud_to_xyz(msg: PointCloud2, *, skip_nans: bool = True) -> NDArray[np.float32]:
    """Return a cloud's x, y, z as an (N, 3) float32 array.

    Fast path: x, y, z are consecutive float32 in machine byte order without
    row padding (the usual layout), read as one strided view.

    Args:
        msg: the ``sensor_msgs/PointCloud2``.
        skip_nans: drop points with NaN in x, y or z (default True).

    Returns:
        (N, 3) float32, N = ``width * height`` unless NaNs were skipped. With
        ``skip_nans=False`` on the fast path this is a strided view sharing
        memory with ``msg.data``; otherwise a new contiguous array.

    Raises:
        MessageError: no x, y or z field (or one with ``count > 1``), or an
            inconsistent message.
    """
    dtype = fields_to_dtype(msg.fields, int(msg.point_step), is_bigendian=bool(msg.is_bigendian))
    names = dtype.names or ()
    missing = [n for n in _XYZ if n not in names]
    if missing:
        text = f"PointCloud2 has no field {missing[0]!r}: it has {list(names)}; expected x, y, z"
        raise MessageError(text)
    for name in _XYZ:
        if dtype.fields[name][0].subdtype is not None:  # type: ignore[index]
            text = f"PointCloud2 field {name!r} has count > 1: expected one value per point"
            raise MessageError(text)
    buf = _checked_buffer(msg)
    count = int(msg.width) * int(msg.height)
    fx, fy, fz = (dtype.fields[n] for n in _XYZ)  # type: ignore[index]
    f32 = np.dtype(np.float32)
    fast = (
        all(f[0] == f32 for f in (fx, fy, fz))
        and fy[1] == fx[1] + 4
        and fz[1] == fx[1] + 8
        and int(msg.row_step) == int(msg.width) * dtype.itemsize
        and count > 0
    )
    if not fast:
        structured = cloud_to_structured(msg, field_names=list(_XYZ), skip_nans=skip_nans)
        xyz = np.empty((structured.shape[0], 3), dtype=np.float32)
        for i, name in enumerate(_XYZ):
            xyz[:, i] = structured[name]
        return xyz
    step, offset = dtype.itemsize, int(fx[1])
    view: NDArray[np.float32] = np.ndarray(
        (count, 3), dtype=f32, buffer=buf, offset=offset, strides=(step, 4)
    )
    if not skip_nans:
        return view
    valid = ~(np.isnan(view[:, 0]) | np.isnan(view[:, 1]) | np.isnan(view[:, 2]))
    # Selecting whole records then one contiguous copy beats indexing the strided view.
    records = np.ndarray((count,), dtype=np.dtype((np.void, step)), buffer=buf).compress(valid)
    if records.size == 0:
        return np.empty((0, 3), dtype=np.float32)
    kept: NDArray[np.float32] = np.ndarray(
        (records.size, 3), dtype=f32, buffer=records, offset=offset, strides=(step, 4)
    )
    return np.ascontiguousarray(kept)
