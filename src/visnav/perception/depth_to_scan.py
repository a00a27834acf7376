"""depthimage_to_laserscan: a horizontal laser scan from the middle rows of a depth image.

Semantics of ROS's ``DepthImageToLaserScan`` (parameters and defaults included):

* ``angle_max`` is the angle between the rays through the raw pixels ``(0, cy)``
  and ``(cx, cy)`` after :meth:`~PinholeCameraModel.rectify_point`, ``angle_min``
  minus the angle between ``(cx, cy)`` and ``(width - 1, cy)``;
  ``angle_increment = (angle_max - angle_min) / (width - 1)`` (all three float32,
  as in the message). There are ``width`` ranges.
* The rows used are ``scan_height`` rows starting at ``int(cy - scan_height / 2)``;
  the image must hold them (``scan_height // 2 <= cy`` and ``<= height - cy``).
* Pixel (u, v) with depth d has ``x = (u - cx) * d * unit / fx``, ``z = d * unit``,
  range ``hypot(x, z)`` (a horizontal distance) and goes to the scan index
  ``int((-atan((u - cx) / fx) - angle_min) / angle_increment)`` (truncated), so
  columns near the image edge share an index and some indices near the centre get
  no column and stay NaN, exactly as upstream.
* Several candidates for one index are merged with upstream's ``use_point``: a
  finite range inside ``[range_min, range_max]`` beats anything non-finite and a
  shorter one beats a longer one; finite ranges outside the limits are dropped;
  among non-finite values +-inf replaces NaN or an earlier inf (the last one
  in row-major order wins) and NaN never replaces anything. Invalid 32FC1 depths
  (NaN, +-inf) are passed through as ranges; invalid 16UC1 depths (0) become range
  0, which ``range_min > 0`` drops. A scan index with no candidate is NaN.

Differences: columns whose index falls outside ``[0, width)`` (possible only with
strong distortion) are dropped, where upstream writes out of bounds; the image
size must match the camera_info; bad parameters raise :class:`DepthToScanError`
in the constructor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.msgs.types import CameraInfo, Header, Image, LaserScan, Time
from visnav.perception.camera_model import PinholeCameraModel
from visnav.perception.errors import DepthToScanError

__all__ = [
    "DepthImageToLaserScan",
    "ScanGeometry",
    "depth_rows_to_ranges",
    "scan_debug_image",
    "scan_geometry",
    "scan_rows",
]

_MIN_WIDTH = 2


@dataclass(frozen=True)
class ScanGeometry:
    """The camera-dependent part of a depth -> scan conversion (cached per camera_info).

    Attributes:
        angle_min: float32 angle of scan index 0 (the image's right edge), radians.
        angle_max: float32 angle of the last index (the image's left edge).
        angle_increment: float32 angle between indices.
        center_x: ``cx`` as float32.
        constant_x: ``unit / fx`` as float32 (unit 0.001 for 16UC1, 1 for 32FC1).
        unit: metres per depth unit (float32 value).
        index: (W,) int64 scan index of each image column.
        order: column numbers with an index in range, sorted by index.
        starts: positions in ``order`` where a new index begins.
        targets: the scan index of each group in ``starts``.
    """

    angle_min: float
    angle_max: float
    angle_increment: float
    center_x: float
    constant_x: float
    unit: float
    index: NDArray[np.int64]
    order: NDArray[np.int64]
    starts: NDArray[np.int64]
    targets: NDArray[np.int64]


def _angle_between(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    cos = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.acos(max(-1.0, min(1.0, cos)))


def scan_geometry(model: PinholeCameraModel, width: int, *, unit: float = 1.0) -> ScanGeometry:
    """Compute the scan angles and the column -> index map of a camera (upstream's math).

    Args:
        model: the depth camera.
        width: depth image width (number of ranges).
        unit: 1.0 for 32FC1 metres, 0.001 for 16UC1 millimetres (rounding follows it).

    Returns:
        The :class:`ScanGeometry`.

    Raises:
        DepthToScanError: fewer than 2 columns.
    """
    if width < _MIN_WIDTH:
        text = f"depth image width is {width}: a scan needs at least 2 columns"
        raise DepthToScanError(text)
    cy = model.cy
    raw = np.array([[0.0, cy], [width - 1.0, cy], [model.cx, cy]])
    left, right, center = model.project_pixel_to_3d_ray(model.rectify_point(raw))
    angle_max = np.float32(_angle_between(left, center))
    angle_min = np.float32(-_angle_between(center, right))
    angle_increment = np.float32((angle_max - angle_min) / np.float32(width - 1))
    if not angle_increment > 0:
        text = (
            f"the camera gives a scan angle increment of {angle_increment}: fx {model.fx}, "
            f"cx {model.cx} and width {width} do not span any angle"
        )
        raise DepthToScanError(text)
    unit32 = np.float32(unit)
    center_x = np.float32(model.cx)
    constant_x = np.float32(float(unit32) / model.fx)
    u = np.arange(width, dtype=np.float32)
    # th = -atan2((u - cx) * constant_x, unit): float32 difference, double atan2 (upstream).
    th = -np.arctan2((u - center_x).astype(np.float64) * float(constant_x), float(unit32))
    q = (th - float(angle_min)) / float(angle_increment)
    index = np.trunc(q).astype(np.int64)
    inside = np.flatnonzero((index >= 0) & (index < width))
    order = inside[np.argsort(index[inside], kind="stable")]
    sorted_index = index[order]
    if order.size:
        starts = np.flatnonzero(np.r_[True, sorted_index[1:] != sorted_index[:-1]])
    else:
        starts = np.zeros(0, dtype=np.int64)
    return ScanGeometry(
        angle_min=float(angle_min),
        angle_max=float(angle_max),
        angle_increment=float(angle_increment),
        center_x=float(center_x),
        constant_x=float(constant_x),
        unit=float(unit32),
        index=index,
        order=order.astype(np.int64),
        starts=starts.astype(np.int64),
        targets=sorted_index[starts].astype(np.int64),
    )


def scan_rows(cy: float, height: int, scan_height: int) -> tuple[int, int]:
    """Return the ``[start, stop)`` rows upstream uses, checking that they fit the image.

    Raises:
        DepthToScanError: ``scan_height`` too large for the image (upstream's check
            ``scan_height // 2 > cy or scan_height // 2 > height - cy``) or rows
            that fall outside it.
    """
    half = scan_height // 2
    start = int(cy - scan_height / 2.0)  # int() truncates toward zero, like C++
    stop = start + scan_height
    if half > cy or half > height - cy or start < 0 or stop > height:
        text = (
            f"scan_height is {scan_height} pixels: too large for a {height}-row image with "
            f"cy = {cy:g} (rows {start}..{stop - 1} are needed); lower scan_height to at most "
            f"{max(1, 2 * int(min(cy, height - cy)))}"
        )
        raise DepthToScanError(text)
    return start, stop


def depth_rows_to_ranges(
    rows: NDArray[Any], geometry: ScanGeometry, *, range_min: float, range_max: float
) -> NDArray[np.float32]:
    """Reduce depth rows to one range per scan index with upstream's ``use_point`` rules.

    Args:
        rows: (scan_height, W) uint16 millimetres or float32 metres: the scan rows.
        geometry: :func:`scan_geometry` for the camera and this dtype's unit.
        range_min: minimum range kept, metres.
        range_max: maximum range kept, metres.

    Returns:
        (W,) float32 ranges.
    """
    n_rows, width = rows.shape
    rmin, rmax = np.float32(range_min), np.float32(range_max)
    offset = np.arange(width, dtype=np.float32) - np.float32(geometry.center_x)
    d = rows.astype(np.float32, copy=False)
    with np.errstate(invalid="ignore", over="ignore"):
        # Float32 x and z, double hypot, float32 range: upstream's arithmetic.
        x = offset * d * np.float32(geometry.constant_x)
        z = d * np.float32(geometry.unit) if rows.dtype == np.uint16 else d
        r = np.sqrt(x.astype(np.float64) ** 2 + z.astype(np.float64) ** 2).astype(np.float32)
    if rows.dtype == np.uint16:
        r[rows == 0] = 0.0  # invalid: upstream passes the raw 0 on, range_min drops it
    else:
        r = np.where(np.isfinite(d), r, d)  # NaN and +-inf pass through
    good = (r >= rmin) & (r <= rmax) & np.isfinite(r)
    ranges = np.full(width, np.nan, dtype=np.float32)
    order, starts, targets = geometry.order, geometry.starts, geometry.targets
    if order.size == 0:
        return ranges
    col_min = np.where(good, r, np.float32(np.inf)).min(axis=0)
    best = np.minimum.reduceat(col_min[order], starts)
    fallback = np.full(best.shape, np.nan, dtype=np.float32)
    is_inf = np.isinf(r)
    if is_inf.any():
        # The last +-inf candidate in row-major (v, u) order wins: key v * W + u, -1 if none.
        keys = np.where(is_inf, np.arange(n_rows * width).reshape(n_rows, width), -1)
        last = np.maximum.reduceat(keys.max(axis=0)[order], starts)
        fallback = np.where(last >= 0, r.reshape(-1)[np.maximum(last, 0)], fallback)
    ranges[targets] = np.where(np.isfinite(best), best, fallback)
    return ranges


def scan_debug_image(
    depth: NDArray[Any], start: int, stop: int, *, range_max: float = 10.0
) -> NDArray[np.uint8]:
    """Return a bgr8 picture of a depth image with the scan rows painted red.

    Depth is drawn grey (near bright, far / invalid black, scaled to ``range_max``).
    """
    arr = np.asarray(depth)
    metres = arr.astype(np.float32) * np.float32(0.001) if arr.dtype == np.uint16 else arr
    with np.errstate(invalid="ignore"):
        scaled = np.clip(1.0 - metres / np.float32(range_max), 0.0, 1.0)
    grey = np.nan_to_num(scaled * 255.0, nan=0.0, posinf=0.0, neginf=0.0).astype(np.uint8)
    image = np.repeat(grey[:, :, None], 3, axis=2)
    band = image[start:stop]
    band[..., 0] //= 4
    band[..., 1] //= 4
    band[..., 2] = np.maximum(band[..., 2], 160)
    return image


class DepthImageToLaserScan:
    """depthimage_to_laserscan's converter: ``convert(depth_msg, info_msg) -> LaserScan``.

    Args:
        scan_height: number of image rows, centred on ``cy``, merged into the scan.
        range_min: minimum range kept, metres.
        range_max: maximum range kept, metres (also written to the message).
        scan_time: the message's ``scan_time`` (time between scans), seconds.
        output_frame_id: the scan's frame; empty keeps the depth image's frame.
            Usually not the optical frame (e.g. ``camera_depth_frame``).

    Raises:
        DepthToScanError: ``scan_height < 1`` or range limits that are not
            ``0 <= range_min <= range_max``.
    """

    def __init__(
        self,
        scan_height: int = 1,
        range_min: float = 0.45,
        range_max: float = 10.0,
        scan_time: float = 0.033,
        output_frame_id: str = "camera_depth_frame",
    ) -> None:
        if int(scan_height) != scan_height or scan_height < 1:
            text = f"scan_height is {scan_height!r}: expected an int >= 1 (rows)"
            raise DepthToScanError(text)
        if not (0.0 <= range_min <= range_max) or math.isnan(range_max):
            text = (
                f"range_min, range_max are {range_min!r}, {range_max!r}: expected "
                "0 <= range_min <= range_max (metres)"
            )
            raise DepthToScanError(text)
        self.scan_height = int(scan_height)
        self.range_min = float(range_min)
        self.range_max = float(range_max)
        self.scan_time = float(scan_time)
        self.output_frame_id = str(output_frame_id)
        self._model = PinholeCameraModel()
        self._geometry: dict[tuple[int, str], ScanGeometry] = {}

    @property
    def model(self) -> PinholeCameraModel:
        """The camera model built from the last camera_info."""
        return self._model

    def _set_info(self, info: CameraInfo) -> None:
        if self._model.from_camera_info(info):
            self._geometry.clear()

    def geometry(self, info: CameraInfo, width: int, dtype: np.dtype[Any]) -> ScanGeometry:
        """Return the (cached) :class:`ScanGeometry` for a camera_info and image width / dtype."""
        self._set_info(info)
        key = (int(width), np.dtype(dtype).str)
        geometry = self._geometry.get(key)
        if geometry is None:
            unit = 0.001 if np.dtype(dtype) == np.uint16 else 1.0
            geometry = self._geometry[key] = scan_geometry(self._model, width, unit=unit)
        return geometry

    def _depth(self, depth_msg: Image) -> NDArray[Any]:
        if depth_msg.encoding not in ("16UC1", "32FC1"):
            text = (
                f"depth Image.encoding is {depth_msg.encoding!r}: depthimage_to_laserscan takes "
                "16UC1 (millimetres) or 32FC1 (metres)"
            )
            raise DepthToScanError(text)
        return image_to_numpy(depth_msg)

    def _check_size(self, depth: NDArray[Any]) -> None:
        width, height = self._model.raw_image_size
        if depth.shape != (height, width):
            text = (
                f"depth image is {depth.shape[1]} x {depth.shape[0]} (width x height) but its "
                f"camera_info describes {width} x {height}; pair each depth image with its own "
                "camera_info"
            )
            raise DepthToScanError(text)

    def ranges(
        self, depth: NDArray[Any], info: CameraInfo
    ) -> tuple[ScanGeometry, NDArray[np.float32]]:
        """Numpy core: the geometry and the (W,) float32 ranges of a depth array."""
        arr = np.asarray(depth)
        if arr.ndim != 2 or arr.dtype not in (np.dtype(np.uint16), np.dtype(np.float32)):
            text = (
                f"depth has dtype {arr.dtype} and shape {arr.shape}: expected (H, W) uint16 "
                "millimetres or float32 metres"
            )
            raise DepthToScanError(text)
        geometry = self.geometry(info, arr.shape[1], arr.dtype)
        self._check_size(arr)
        start, stop = scan_rows(self._model.cy, arr.shape[0], self.scan_height)
        ranges = depth_rows_to_ranges(
            arr[start:stop], geometry, range_min=self.range_min, range_max=self.range_max
        )
        return geometry, ranges

    def convert(self, depth_msg: Image, info_msg: CameraInfo) -> LaserScan:
        """Return the LaserScan of a depth image (the depth image's stamp).

        Raises:
            DepthToScanError: an encoding other than 16UC1 / 32FC1, a size that does
                not match the camera_info, or a scan_height that does not fit.
            CameraModelError: an unusable camera_info.
        """
        depth = self._depth(depth_msg)
        geometry, ranges = self.ranges(depth, info_msg)
        stamp = depth_msg.header.stamp
        frame = self.output_frame_id or depth_msg.header.frame_id
        return LaserScan(
            header=Header(
                stamp=Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec)), frame_id=frame
            ),
            angle_min=geometry.angle_min,
            angle_max=geometry.angle_max,
            angle_increment=geometry.angle_increment,
            time_increment=0.0,
            scan_time=float(np.float32(self.scan_time)),
            range_min=float(np.float32(self.range_min)),
            range_max=float(np.float32(self.range_max)),
            ranges=ranges,
            intensities=np.zeros(0, dtype=np.float32),
        )

    def debug_image(self, depth_msg: Image, info_msg: CameraInfo) -> Image:
        """Return a bgr8 image of the depth with the rows the scan uses painted red."""
        depth = self._depth(depth_msg)
        self._set_info(info_msg)
        self._check_size(depth)
        start, stop = scan_rows(self._model.cy, depth.shape[0], self.scan_height)
        picture = scan_debug_image(depth, start, stop, range_max=self.range_max)
        stamp = depth_msg.header.stamp
        header = Header(
            stamp=Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec)),
            frame_id=depth_msg.header.frame_id,
        )
        return numpy_to_image(picture, "bgr8", header=header)
