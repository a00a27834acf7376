"""depth_image_proc's ``point_cloud_xyz``, ``point_cloud_xyzrgb`` and ``convert_metric``.

Depth images follow REP 118: ``32FC1`` in metres (NaN / inf = no return) or
``16UC1`` in millimetres (0 = no return). Each pixel (u, v) of a rectified depth
image becomes the point::

    x = (u - cx) * depth * unit / fx,  y = (v - cy) * depth * unit / fy,  z = depth * unit

with ``fx, fy, cx, cy`` from the camera model (``P``, adjusted for ROI and
binning) and ``unit`` 0.001 for millimetres, 1 for metres, all in float32 as
depth_image_proc computes it. ``(u - cx) * unit / fx`` and ``(v - cy) * unit / fy``
are per-column / per-row tables, so a cloud is one broadcast multiply. Invalid
depths give NaN points unless ``invalid_depth`` (metres, depth_image_proc's
parameter; 0 = off) replaces them. Clouds are organized (``height`` x ``width``),
``is_dense`` False, stamped and framed like the depth image, with
depth_image_proc's layout (x, y, z at 0, 4, 8 in a 16-byte point; ``rgb`` at 16
in a 32-byte point).

Differences from depth_image_proc, on purpose: a depth image whose size does not
match its camera_info raises :class:`DepthImageError` (depth_image_proc reads
whatever is there); ``point_cloud_xyzrgb`` with a colour image of another size
resizes it and publishes (the ROS 1 behaviour; ROS 2's node resizes, logs an
error and drops the frame); colour encodings other than rgb8, rgba8, bgr8, bgra8
and mono8 are rejected (depth_image_proc tries cv_bridge's conversion to rgb8).
"""

from __future__ import annotations

import logging
from typing import Any, overload

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.msgs.pointcloud import dtype_to_fields, pack_rgb
from visnav.msgs.types import CameraInfo, Header, Image, PointCloud2, Time
from visnav.perception.camera_model import PinholeCameraModel
from visnav.perception.errors import DepthImageError

__all__ = [
    "PointCloudXyz",
    "PointCloudXyzrgb",
    "convert_metric",
    "depth_ray_tables",
    "depth_to_points",
    "point_cloud_xyz",
    "point_cloud_xyzrgb",
]

_LOG = logging.getLogger(__name__)

_MM = np.float32(0.001)
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
_XYZ_FIELDS = dtype_to_fields(_XYZ_DTYPE)
_XYZRGB_FIELDS = dtype_to_fields(_XYZRGB_DTYPE)
_DEPTH_ENCODINGS = {"16UC1": np.dtype(np.uint16), "32FC1": np.dtype(np.float32)}
# encoding -> (R, G, B) channel indices
_COLOUR_CHANNELS = {
    "rgb8": (0, 1, 2),
    "rgba8": (0, 1, 2),
    "bgr8": (2, 1, 0),
    "bgra8": (2, 1, 0),
    "mono8": (0, 0, 0),
}

RayTables = tuple[NDArray[np.float32], NDArray[np.float32]]


def depth_ray_tables(model: PinholeCameraModel, *, unit: float = 1.0) -> RayTables:
    """Return depth_image_proc's per-column and per-row factors for a camera.

    Args:
        model: the camera (its ``fx``, ``fy``, ``cx``, ``cy``, raw image size).
        unit: metres per depth unit: 1.0 for 32FC1, 0.001 for 16UC1.

    Returns:
        ``(rx, ry)`` float32, shapes (W,) and (H,): ``rx[u] = (u - cx) * unit / fx``,
        ``ry[v] = (v - cy) * unit / fy``; a point is ``(d * rx[u], d * ry[v], d * unit)``.
    """
    width, height = model.raw_image_size
    unit32 = np.float32(unit)
    constant_x = np.float32(float(unit32) / model.fx)
    constant_y = np.float32(float(unit32) / model.fy)
    rx = (np.arange(width, dtype=np.float32) - np.float32(model.cx)) * constant_x
    ry = (np.arange(height, dtype=np.float32) - np.float32(model.cy)) * constant_y
    return rx.astype(np.float32, copy=False), ry.astype(np.float32, copy=False)


def _as_model(camera: PinholeCameraModel | CameraInfo) -> PinholeCameraModel:
    if isinstance(camera, PinholeCameraModel):
        return camera
    return PinholeCameraModel.from_camera_info(camera)


def _check_depth(depth: NDArray[Any], model: PinholeCameraModel, name: str) -> None:
    if depth.dtype not in (np.dtype(np.uint16), np.dtype(np.float32)) or depth.ndim != 2:
        text = (
            f"{name} has dtype {depth.dtype} and shape {depth.shape}: expected (H, W) float32 "
            "metres (32FC1) or uint16 millimetres (16UC1)"
        )
        raise DepthImageError(text)
    width, height = model.raw_image_size
    if depth.shape != (height, width):
        text = (
            f"{name} is {depth.shape[1]} x {depth.shape[0]} (width x height) but its camera_info "
            f"describes {width} x {height} images (width {model.width}, height {model.height}, "
            f"roi {model.raw_roi}, binning {model.binning_x}x{model.binning_y}); "
            "pair the depth image with the camera_info of the same camera"
        )
        raise DepthImageError(text)


def _fill_points(
    depth: NDArray[Any], tables: RayTables, invalid_depth: float, out: NDArray[np.float32]
) -> None:
    """Write x, y, z of every pixel into ``out[..., 0:3]`` (a (H, W, >= 3) float32 view)."""
    rx, ry = tables
    if depth.dtype == np.uint16:
        invalid = depth == 0
        d = depth.astype(np.float32)
        if invalid_depth != 0.0:
            # depth_image_proc's DepthTraits<uint16_t>::fromMeters rounds to the nearest mm.
            d[invalid] = np.float32(int(np.float32(invalid_depth) * np.float32(1000.0) + 0.5))
        else:
            d[invalid] = np.nan
        np.multiply(d, _MM, out=out[..., 2])
    else:
        invalid = ~np.isfinite(depth)
        fill = np.float32(invalid_depth) if invalid_depth != 0.0 else np.float32(np.nan)
        d = np.where(invalid, fill, depth) if invalid.any() else depth
        out[..., 2] = d
    np.multiply(d, rx, out=out[..., 0])
    np.multiply(d, ry[:, None], out=out[..., 1])


def depth_to_points(
    depth: NDArray[Any],
    camera: PinholeCameraModel | CameraInfo,
    *,
    invalid_depth: float = 0.0,
    tables: RayTables | None = None,
) -> NDArray[np.float32]:
    """Back-project a rectified depth image into an organized (H, W, 3) float32 point array.

    Args:
        depth: (H, W) float32 metres or uint16 millimetres; 0, NaN and inf are invalid.
        camera: the depth camera's model (or its CameraInfo).
        invalid_depth: metres to use for invalid pixels; 0 (default) makes them NaN points.
        tables: precomputed :func:`depth_ray_tables` for this camera and unit.

    Returns:
        (H, W, 3) float32 x, y, z in the camera's optical frame.

    Raises:
        DepthImageError: wrong dtype, or a size that does not match the camera.
    """
    model = _as_model(camera)
    arr = np.asarray(depth)
    _check_depth(arr, model, "depth")
    if tables is None:
        tables = depth_ray_tables(model, unit=0.001 if arr.dtype == np.uint16 else 1.0)
    out = np.empty((*arr.shape, 3), dtype=np.float32)
    _fill_points(arr, tables, float(invalid_depth), out)
    return out


def _copy_header(header: Header) -> Header:
    stamp = header.stamp
    return Header(
        stamp=Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec)), frame_id=header.frame_id
    )


def _depth_array(msg: Image) -> NDArray[Any]:
    if msg.encoding not in _DEPTH_ENCODINGS:
        text = (
            f"depth Image.encoding is {msg.encoding!r}: expected 16UC1 (millimetres) or 32FC1 "
            "(metres); a colour image on a depth topic is a wiring mistake"
        )
        raise DepthImageError(text)
    return image_to_numpy(msg)


class _CloudBase:
    """Shared camera-model and ray-table cache of the point cloud converters."""

    def __init__(self, *, invalid_depth: float = 0.0) -> None:
        self.invalid_depth = float(invalid_depth)
        self._model = PinholeCameraModel()
        self._tables: dict[str, RayTables] = {}

    @property
    def model(self) -> PinholeCameraModel:
        """The camera model built from the last camera_info."""
        return self._model

    def _update(self, info: CameraInfo) -> None:
        if self._model.from_camera_info(info):
            self._tables.clear()

    def _tables_for(self, dtype: np.dtype[Any]) -> RayTables:
        key = dtype.str
        tables = self._tables.get(key)
        if tables is None:
            unit = 0.001 if dtype == np.uint16 else 1.0
            tables = self._tables[key] = depth_ray_tables(self._model, unit=unit)
        return tables


class PointCloudXyz(_CloudBase):
    """depth_image_proc's ``point_cloud_xyz``: a depth image + camera_info -> PointCloud2.

    The camera model and the ray tables are kept between calls and rebuilt only
    when the camera_info's calibration or ROI changes.

    Args:
        invalid_depth: metres to use for invalid pixels; 0 (default) gives NaN points.
    """

    def points(self, depth: NDArray[Any], info: CameraInfo) -> NDArray[np.float32]:
        """Return the (H, W, 3) float32 points of a depth array (see :func:`depth_to_points`)."""
        self._update(info)
        arr = np.asarray(depth)
        _check_depth(arr, self._model, "depth")
        out = np.empty((*arr.shape, 3), dtype=np.float32)
        _fill_points(arr, self._tables_for(arr.dtype), self.invalid_depth, out)
        return out

    def convert(self, depth_msg: Image, info_msg: CameraInfo) -> PointCloud2:
        """Return the organized cloud of a 16UC1 / 32FC1 depth image.

        Raises:
            DepthImageError: a non-depth encoding or a size that does not match the camera.
            CameraModelError: an unusable camera_info.
        """
        depth = _depth_array(depth_msg)
        self._update(info_msg)
        _check_depth(depth, self._model, f"depth image ({depth_msg.header.frame_id!r})")
        height, width = depth.shape
        buf = np.zeros((height, width, 4), dtype=np.float32)
        _fill_points(depth, self._tables_for(depth.dtype), self.invalid_depth, buf)
        return _cloud(buf, _XYZ_FIELDS, 16, depth_msg.header)


def _cloud(buf: NDArray[np.float32], fields: Any, point_step: int, header: Header) -> PointCloud2:
    height, width = buf.shape[:2]
    return PointCloud2(
        header=_copy_header(header),
        height=int(height),
        width=int(width),
        fields=list(fields),
        is_bigendian=False,
        point_step=point_step,
        row_step=point_step * int(width),
        data=buf.reshape(-1).view(np.uint8),
        is_dense=False,
    )


def _colour_rgb(rgb_msg: Image) -> NDArray[np.uint8]:
    channels = _COLOUR_CHANNELS.get(rgb_msg.encoding)
    if channels is None:
        text = (
            f"colour Image.encoding is {rgb_msg.encoding!r}: expected one of "
            f"{', '.join(_COLOUR_CHANNELS)} (debayer bayer_* images with image_proc first)"
        )
        raise DepthImageError(text)
    arr = image_to_numpy(rgb_msg)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    out: NDArray[np.uint8] = np.ascontiguousarray(arr[:, :, list(channels)])
    return out


def _scaled_info(info: CameraInfo, width: int, height: int, ratio: float) -> CameraInfo:
    """Return a copy of ``info`` for an image scaled by ``ratio`` (depth_image_proc's resize)."""
    k = np.array(info.k, dtype=np.float64)
    p = np.array(info.p, dtype=np.float64)
    for i in (0, 2, 4, 5):
        k[i] *= ratio
    for i in (0, 2, 5, 6):
        p[i] *= ratio
    return CameraInfo(
        header=_copy_header(info.header),
        height=height,
        width=width,
        distortion_model=info.distortion_model,
        d=np.array(info.d, dtype=np.float64),
        k=k,
        r=np.array(info.r, dtype=np.float64),
        p=p,
        binning_x=info.binning_x,
        binning_y=info.binning_y,
        roi=info.roi,
    )


class PointCloudXyzrgb(_CloudBase):
    """depth_image_proc's ``point_cloud_xyzrgb``: registered depth + colour -> coloured cloud.

    The depth image must be registered to the colour camera; ``info_msg`` is the
    colour camera's camera_info. If the colour image has another size, the depth
    image is taken as a scaled version of it: the colour rows that match the
    depth's aspect ratio are resized to the depth size and the camera_info's K and P
    are scaled by ``depth.width / rgb.width``, as depth_image_proc does.

    Args:
        invalid_depth: metres to use for invalid pixels; 0 (default) gives NaN points.
    """

    def convert(self, depth_msg: Image, rgb_msg: Image, info_msg: CameraInfo) -> PointCloud2:
        """Return the organized x, y, z, rgb cloud (depth image's header).

        Raises:
            DepthImageError: a non-depth or unsupported colour encoding, sizes that
                cannot be matched, or a depth size that does not match the camera.
            CameraModelError: an unusable camera_info.
        """
        depth = _depth_array(depth_msg)
        colour = _colour_rgb(rgb_msg)
        if depth_msg.header.frame_id != rgb_msg.header.frame_id:
            _LOG.warning(
                "depth image frame id %r does not match the colour image frame id %r",
                depth_msg.header.frame_id,
                rgb_msg.header.frame_id,
            )
        info = info_msg
        d_h, d_w = depth.shape
        c_h, c_w = colour.shape[:2]
        if (d_h, d_w) != (c_h, c_w):
            if min(d_h, d_w, c_h, c_w) == 0:
                text = f"invalid image sizes: depth {d_w} x {d_h}, colour {c_w} x {c_h}"
                raise DepthImageError(text)
            crop_rows = d_h * c_w // d_w
            if crop_rows == 0 or crop_rows > c_h:
                text = (
                    f"depth {d_w} x {d_h} and colour {c_w} x {c_h} have incompatible aspect "
                    "ratios: the depth image is not a scaled version of the colour image; "
                    "register the depth image to the colour camera first"
                )
                raise DepthImageError(text)
            ratio = float(np.float32(d_w) / np.float32(c_w))
            info = _scaled_info(info_msg, d_w, d_h, ratio)
            colour = np.asarray(cv2.resize(colour[:crop_rows], (d_w, d_h)), dtype=np.uint8)
        self._update(info)
        _check_depth(depth, self._model, f"depth image ({depth_msg.header.frame_id!r})")
        buf = np.zeros((d_h, d_w, 8), dtype=np.float32)
        _fill_points(depth, self._tables_for(depth.dtype), self.invalid_depth, buf)
        buf[..., 4] = pack_rgb(colour)
        return _cloud(buf, _XYZRGB_FIELDS, 32, depth_msg.header)


def point_cloud_xyz(
    depth_msg: Image, info_msg: CameraInfo, *, invalid_depth: float = 0.0
) -> PointCloud2:
    """One-shot :class:`PointCloudXyz` (keep a :class:`PointCloudXyz` for streams)."""
    return PointCloudXyz(invalid_depth=invalid_depth).convert(depth_msg, info_msg)


def point_cloud_xyzrgb(
    depth_msg: Image, rgb_msg: Image, info_msg: CameraInfo, *, invalid_depth: float = 0.0
) -> PointCloud2:
    """One-shot :class:`PointCloudXyzrgb` (keep a :class:`PointCloudXyzrgb` for streams)."""
    return PointCloudXyzrgb(invalid_depth=invalid_depth).convert(depth_msg, rgb_msg, info_msg)


@overload
def convert_metric(depth: Image) -> Image: ...


@overload
def convert_metric(depth: NDArray[Any]) -> NDArray[Any]: ...


def convert_metric(depth: Image | NDArray[Any]) -> Image | NDArray[Any]:
    """Convert depth between 16UC1 millimetres and 32FC1 metres (depth_image_proc's convert_metric).

    uint16 -> float32: ``mm * 0.001``, 0 -> NaN. float32 -> uint16: ``m * 1000``
    truncated, NaN -> 0; visnav also maps values that do not fit uint16 (negative,
    >= 65.536 m, +-inf) to 0, where depth_image_proc's cast is undefined.

    Args:
        depth: a 16UC1 / 32FC1 ``Image`` (the result is an Image with the same
            header), or a uint16 / float32 array.

    Returns:
        The converted image or array.

    Raises:
        DepthImageError: another encoding or dtype.
    """
    if isinstance(depth, Image):
        arr = _depth_array(depth)
        out = _convert_metric_array(arr)
        encoding = "32FC1" if out.dtype == np.float32 else "16UC1"
        return numpy_to_image(out, encoding, header=_copy_header(depth.header))
    return _convert_metric_array(np.asarray(depth))


def _convert_metric_array(arr: NDArray[Any]) -> NDArray[Any]:
    if arr.dtype == np.uint16:
        metres: NDArray[np.float32] = arr.astype(np.float32) * _MM
        metres[arr == 0] = np.nan
        return metres
    if arr.dtype == np.float32:
        with np.errstate(invalid="ignore", over="ignore"):
            mm = arr * np.float32(1000.0)
            ok = (mm >= 0) & (mm < 65536.0)
            out: NDArray[np.uint16] = np.where(ok, mm, 0).astype(np.uint16)
            return out
    text = f"depth has dtype {arr.dtype}: expected uint16 millimetres or float32 metres"
    raise DepthImageError(text)
