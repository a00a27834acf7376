"""A pinhole camera model from ``sensor_msgs/CameraInfo`` (image_geometry's ``PinholeCameraModel``).

The operations and their semantics are image_geometry's (ROS 2), with snake_case
names::

    model = PinholeCameraModel.from_camera_info(info)   # or model.from_camera_info(info)
    rect = model.rectify_image(raw)                      # maps built once per calibration
    uv_rect = model.rectify_point((100.0, 100.0))
    ray = model.project_pixel_to_3d_ray(uv_rect)          # z = 1, like image_geometry C++
    uv = model.project_3d_to_pixel(ray)

What follows image_geometry exactly:

* ``fx``, ``fy``, ``cx``, ``cy``, ``Tx``, ``Ty`` come from ``P`` (the rectified
  camera), shifted by the ROI offset and divided by the binning; ``K`` is adjusted
  the same way. ``binning_x/y`` of 0 mean 1; an all-zero ROI means the full image.
* Distortion is applied when the model is ``plumb_bob``, ``rational_polynomial``
  or ``equidistant`` (OpenCV's fisheye) and some coefficient is non-zero;
  otherwise :meth:`rectify_image` returns a copy and :meth:`rectify_point`
  returns its input unchanged (even if ``R`` or ``P`` differ from identity / ``K``).
* ``D`` goes to OpenCV as image_geometry hands it over: plumb_bob and rational_polynomial
  take 4 (k3 = 0 added), 5, 8, 12 or 14 coefficients, read by length; an empty
  ``distortion_model`` with a non-zero ``D`` too (image_geometry's Python model), warned once.
* Rectification maps are fixed-point (``CV_16SC2``) at the binned full
  resolution, cropped to the ROI, rebuilt only when the calibration (or, for the
  crop, the ROI) changes. Float images are remapped with NaN outside the image.
* :meth:`rectify_point` uses ``cv2.undistortPoints`` with OpenCV's default
  iterations (5 for plumb_bob / rational_polynomial, 10 for equidistant) unless
  ``iterations`` is given.

Where visnav differs, on purpose:

* Bad calibrations raise :class:`CameraModelError` in :meth:`from_camera_info`
  instead of yielding a model that divides by zero later: ``K`` all zero (an
  uncalibrated camera), ``P`` all zero (image_geometry does *not* fall back to
  ``K``: its ``fx()`` would be 0), a non-zero ``D`` of a length OpenCV does not
  take (equidistant: 4) or of an unknown model name (a typo: the C++ model refuses
  to rectify it), an all-zero ``R`` with distortion to remove, an ROI outside the image.
  An unknown model with no non-zero coefficient is accepted as distortion-free
  (image_geometry accepts it too but raises on every rectify call).
* Points are computed in float64 (image_geometry rounds to float32 for
  ``cv::undistortPoints``) and the point methods accept (2,) / (N, 2) arrays.
* :meth:`project_3d_to_pixel` returns NaN for ``z == 0`` (as image_geometry's
  Python model); :meth:`rectify_image` raises if the image size does not match
  the camera_info (image_geometry remaps silently to the map size).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, overload

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.msgs.time import time_to_ns
from visnav.msgs.types import CameraInfo, Time
from visnav.perception._camera_info import (
    DISTORTION_MODELS,
    EQUIDISTANT,
    PLUMB_BOB,
    RATIONAL_POLYNOMIAL,
    Calibration,
    Roi,
    RoiState,
    as_points,
    binned,
    parse_camera_info,
    shaped,
)
from visnav.perception.errors import CameraModelError

__all__ = [
    "DISTORTION_MODELS",
    "EQUIDISTANT",
    "PLUMB_BOB",
    "RATIONAL_POLYNOMIAL",
    "PinholeCameraModel",
]

_FLOAT_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))
_REMAP_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.int16), *_FLOAT_DTYPES)
_MAX_REMAP_CHANNELS = 4

_Maps = tuple[NDArray[np.int16], NDArray[np.uint16]]
_M = TypeVar("_M", bound="PinholeCameraModel")


def _frozen(array: NDArray[np.float64]) -> NDArray[np.float64]:
    array.flags.writeable = False
    return array


class _FromCameraInfo:
    """``from_camera_info``: a constructor on the class, an in-place update on an instance."""

    @overload
    def __get__(self, obj: None, objtype: type[_M]) -> Callable[[CameraInfo], _M]: ...

    @overload
    def __get__(self, obj: _M, objtype: type[_M] | None = None) -> Callable[[CameraInfo], bool]: ...

    def __get__(
        self, obj: _M | None, objtype: type[_M] | None = None
    ) -> Callable[[CameraInfo], _M] | Callable[[CameraInfo], bool]:
        if obj is None:
            if objtype is None:  # pragma: no cover - Python always passes the owner
                text = "from_camera_info needs the class or an instance"
                raise CameraModelError(text)
            cls = objtype

            def build(info: CameraInfo) -> _M:
                model = cls()
                model._update(info)
                return model

            build.__doc__ = PinholeCameraModel.__doc__
            return build
        return obj._update


class PinholeCameraModel:
    """An idealized monocular camera built from ``sensor_msgs/CameraInfo`` (image_geometry).

    Build one with ``PinholeCameraModel.from_camera_info(info)``; update it with
    ``model.from_camera_info(info)``, which returns True when the calibration or
    ROI changed (cached rectification maps are then rebuilt on next use) and False
    when only the header did. Properties raise :class:`CameraModelError` before the
    first camera_info.

    ``from_camera_info`` raises :class:`CameraModelError` for a camera_info that
    cannot make a usable model (see the module docstring).

    Args:
        name: what the once-per-model warnings call this camera (e.g. "left camera").
    """

    from_camera_info = _FromCameraInfo()

    def __init__(self, *, name: str = "camera") -> None:
        self._name = name
        self._assumed: set[str] = set()
        self._calib: Calibration | None = None
        self._roi = RoiState(0, 0, 0, 0, False)
        self._info: CameraInfo | None = None
        self._frame_id = ""
        self._stamp = Time(sec=0, nanosec=0)
        self._k_full = self._p_full = self._k = self._p = self._r = np.zeros((0, 0))
        self._d = np.zeros(0)
        self._has_distortion = False
        self._fisheye = False
        self._full_maps: _Maps | None = None
        self._reduced_maps: _Maps | None = None
        self._unrect_full_maps: _Maps | None = None
        self._unrect_reduced_maps: _Maps | None = None
        self._rectified_roi: Roi | None = None

    # ------------------------------------------------------------------ update

    def _update(self, info: CameraInfo) -> bool:
        """Set the camera from a CameraInfo; return whether calibration or ROI changed."""
        parsed = parse_camera_info(info)
        calib, roi = parsed.calibration, parsed.roi
        parsed.warn_once(self._assumed, camera=self._name, frame=str(info.header.frame_id))
        full_dirty = calib != self._calib
        reduced_dirty = full_dirty or roi != self._roi
        self._info = info
        self._frame_id = str(info.header.frame_id)
        stamp = info.header.stamp
        self._stamp = Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec))
        if full_dirty:
            self._calib = calib
            self._full_maps = self._unrect_full_maps = None
            self._k_full = _frozen(np.array(calib.k).reshape(3, 3))
            self._p_full = _frozen(np.array(calib.p).reshape(3, 4))
            self._r = _frozen(np.array(calib.r).reshape(3, 3))
            self._d = _frozen(np.array(calib.d))
            self._has_distortion = calib.distortion_model in DISTORTION_MODELS and any(calib.d)
            self._fisheye = calib.distortion_model == EQUIDISTANT
        if reduced_dirty:
            self._roi = roi
            self._reduced_maps = self._unrect_reduced_maps = None
            self._rectified_roi = None
            k, p = self._k_full.copy(), self._p_full.copy()
            # The ROI is in full-resolution pixels: shift the principal point, then bin.
            k[0, 2] -= roi.x
            k[1, 2] -= roi.y
            p[0, 2] -= roi.x
            p[1, 2] -= roi.y
            k, p = binned(k, p, calib.binning_x, calib.binning_y)
            self._k, self._p = _frozen(k), _frozen(p)
        return reduced_dirty

    def _calibration(self) -> Calibration:
        if self._calib is None:
            text = (
                "the camera model has no calibration yet: call model.from_camera_info(info) "
                "or build it with PinholeCameraModel.from_camera_info(info)"
            )
            raise CameraModelError(text)
        return self._calib

    # -------------------------------------------------------------- accessors

    @property
    def initialized(self) -> bool:
        """Whether a camera_info has been applied."""
        return self._calib is not None

    @property
    def camera_info(self) -> CameraInfo:
        """The last camera_info applied (the message object itself, not a copy)."""
        self._calibration()
        info = self._info
        if info is None:  # pragma: no cover - set together with the calibration
            text = "the camera model has no camera_info"
            raise CameraModelError(text)
        return info

    @property
    def tf_frame(self) -> str:
        """The camera's frame (the camera_info's ``header.frame_id``)."""
        self._calibration()
        return self._frame_id

    @property
    def stamp(self) -> Time:
        """The camera_info's ``header.stamp``."""
        self._calibration()
        return Time(sec=self._stamp.sec, nanosec=self._stamp.nanosec)

    @property
    def stamp_ns(self) -> int:
        """The camera_info's stamp in integer nanoseconds."""
        self._calibration()
        return time_to_ns(self._stamp)

    @property
    def distortion_model(self) -> str:
        """The distortion model applied: the camera_info's, or the one read from ``D``."""
        return self._calibration().distortion_model

    @property
    def has_distortion(self) -> bool:
        """Whether rectification changes anything (known model, a non-zero coefficient)."""
        self._calibration()
        return self._has_distortion

    @property
    def width(self) -> int:
        """Full-resolution image width (``CameraInfo.width``)."""
        return self._calibration().width

    @property
    def height(self) -> int:
        """Full-resolution image height (``CameraInfo.height``)."""
        return self._calibration().height

    @property
    def binning_x(self) -> int:
        """Horizontal binning (0 in the message reads as 1)."""
        return self._calibration().binning_x

    @property
    def binning_y(self) -> int:
        """Vertical binning (0 in the message reads as 1)."""
        return self._calibration().binning_y

    @property
    def K(self) -> NDArray[np.float64]:  # noqa: N802 - image_geometry's name
        """3x3 intrinsic matrix of the raw image, adjusted for ROI and binning (read-only)."""
        self._calibration()
        return self._k

    @property
    def P(self) -> NDArray[np.float64]:  # noqa: N802 - image_geometry's name
        """3x4 projection matrix of the rectified image, adjusted for ROI and binning."""
        self._calibration()
        return self._p

    @property
    def R(self) -> NDArray[np.float64]:  # noqa: N802 - image_geometry's name
        """3x3 rectification rotation (read-only)."""
        self._calibration()
        return self._r

    @property
    def D(self) -> NDArray[np.float64]:  # noqa: N802 - image_geometry's name
        """Distortion coefficients as applied (read-only; may be empty; 4 padded to 5)."""
        self._calibration()
        return self._d

    @property
    def full_K(self) -> NDArray[np.float64]:  # noqa: N802 - image_geometry's name
        """``K`` of the full-resolution image (no ROI or binning adjustment)."""
        self._calibration()
        return self._k_full

    @property
    def full_P(self) -> NDArray[np.float64]:  # noqa: N802 - image_geometry's name
        """``P`` of the full-resolution image (no ROI or binning adjustment)."""
        self._calibration()
        return self._p_full

    @property
    def fx(self) -> float:
        """Focal length in x, pixels (``P[0, 0]`` adjusted for binning)."""
        return float(self.P[0, 0])

    @property
    def fy(self) -> float:
        """Focal length in y, pixels (``P[1, 1]`` adjusted for binning)."""
        return float(self.P[1, 1])

    @property
    def cx(self) -> float:
        """Principal point x, pixels (``P[0, 2]`` adjusted for ROI and binning)."""
        return float(self.P[0, 2])

    @property
    def cy(self) -> float:
        """Principal point y, pixels (``P[1, 2]`` adjusted for ROI and binning)."""
        return float(self.P[1, 2])

    @property
    def Tx(self) -> float:  # noqa: N802 - image_geometry's name
        """X translation term of P (``-fx' * baseline`` for a right stereo camera)."""
        return float(self.P[0, 3])

    @property
    def Ty(self) -> float:  # noqa: N802 - image_geometry's name
        """Y translation term of P."""
        return float(self.P[1, 3])

    @property
    def full_resolution_size(self) -> tuple[int, int]:
        """``(width, height)`` of the full-resolution image (image_geometry ``fullResolution``)."""
        calib = self._calibration()
        return calib.width, calib.height

    @property
    def raw_roi(self) -> Roi:
        """``(x, y, width, height)`` of the ROI in full-resolution raw pixels."""
        self._calibration()
        roi = self._roi
        return roi.x, roi.y, roi.width, roi.height

    @property
    def rectified_roi(self) -> Roi:
        """The ROI in rectified pixels: the raw ROI, or its rectification if ``do_rectify``."""
        self._calibration()
        if self._rectified_roi is None:
            raw = self.raw_roi
            self._rectified_roi = self.rectify_roi(raw) if self._roi.do_rectify else raw
        return self._rectified_roi

    @property
    def reduced_resolution_size(self) -> tuple[int, int]:
        """``(width, height)`` of the images this camera publishes (ROI, then binning)."""
        calib = self._calibration()
        _, _, w, h = self.rectified_roi
        return w // calib.binning_x, h // calib.binning_y

    @property
    def raw_image_size(self) -> tuple[int, int]:
        """``(width, height)`` of the raw images (ROI-cropped, then binned)."""
        calib = self._calibration()
        return self._roi.width // calib.binning_x, self._roi.height // calib.binning_y

    def to_full_resolution(self, uv_reduced: ArrayLike) -> NDArray[np.float64]:
        """Map reduced-image pixels (binned, ROI) to full-resolution pixels."""
        pts, single = as_points(uv_reduced, 2, "uv_reduced")
        x, y, _, _ = self.rectified_roi
        calib = self._calibration()
        out = pts * (calib.binning_x, calib.binning_y) + (x, y)
        return shaped(out, single)

    def to_reduced_resolution(self, uv_full: ArrayLike) -> NDArray[np.float64]:
        """Map full-resolution pixels to reduced-image pixels (binned, ROI)."""
        pts, single = as_points(uv_full, 2, "uv_full")
        x, y, _, _ = self.rectified_roi
        calib = self._calibration()
        out = (pts - (x, y)) / (calib.binning_x, calib.binning_y)
        return shaped(out, single)

    # ------------------------------------------------------------ projection

    def project_3d_to_pixel(self, xyz: ArrayLike) -> NDArray[np.float64]:
        """Project 3D points (camera optical frame) to rectified pixels with ``P``.

        Args:
            xyz: a (3,) point or (N, 3) points.

        Returns:
            (2,) or (N, 2) pixel coordinates ``u = (fx x + Tx) / z + cx``; NaN where z is 0.
        """
        pts, single = as_points(xyz, 3, "xyz")
        p = self.P
        z = pts[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (p[0, 0] * pts[:, 0] + p[0, 3]) / z + p[0, 2]
            v = (p[1, 1] * pts[:, 1] + p[1, 3]) / z + p[1, 2]
        out = np.stack((u, v), axis=1)
        out[z == 0.0] = np.nan
        return shaped(out, single)

    def project_pixel_to_3d_ray(
        self, uv_rect: ArrayLike, *, normalize: bool = False
    ) -> NDArray[np.float64]:
        """Return the ray through rectified pixels, the inverse of :meth:`project_3d_to_pixel`.

        Args:
            uv_rect: a (2,) pixel or (N, 2) pixels of the rectified image.
            normalize: return unit vectors (image_geometry's Python model) instead of
                the ``z = 1`` points image_geometry's C++ model returns (default).

        Returns:
            (3,) or (N, 3): ``((u - cx - Tx) / fx, (v - cy - Ty) / fy, 1)``, optionally
            scaled to length 1.
        """
        pts, single = as_points(uv_rect, 2, "uv_rect")
        return shaped(self._rays(pts, self.P, normalize=normalize), single)

    @staticmethod
    def _rays(
        pts: NDArray[np.float64], p: NDArray[np.float64], *, normalize: bool = False
    ) -> NDArray[np.float64]:
        rays = np.empty((pts.shape[0], 3))
        rays[:, 0] = (pts[:, 0] - p[0, 2] - p[0, 3]) / p[0, 0]
        rays[:, 1] = (pts[:, 1] - p[1, 2] - p[1, 3]) / p[1, 1]
        rays[:, 2] = 1.0
        if normalize:
            rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        return rays

    def get_delta_u(self, delta_x: float, z: float) -> float:
        """Pixels in u spanned by ``delta_x`` metres at depth ``z`` (inf for z = 0)."""
        return float("inf") if z == 0 else self.fx * delta_x / z

    def get_delta_v(self, delta_y: float, z: float) -> float:
        """Pixels in v spanned by ``delta_y`` metres at depth ``z`` (inf for z = 0)."""
        return float("inf") if z == 0 else self.fy * delta_y / z

    def get_delta_x(self, delta_u: float, z: float) -> float:
        """Metres in x spanned by ``delta_u`` pixels at depth ``z``."""
        return z * delta_u / self.fx

    def get_delta_y(self, delta_v: float, z: float) -> float:
        """Metres in y spanned by ``delta_v`` pixels at depth ``z``."""
        return z * delta_v / self.fy

    # ----------------------------------------------------------- rectify points

    def rectify_point(
        self, uv_raw: ArrayLike, *, iterations: int | None = None
    ) -> NDArray[np.float64]:
        """Map raw (distorted) pixels to rectified pixels.

        Args:
            uv_raw: a (2,) pixel or (N, 2) pixels of the raw image (ROI, binned).
            iterations: iterations of OpenCV's undistortion solver; None uses OpenCV's
                default as image_geometry does (5, or 10 for equidistant). More
                iterations converge further from the image centre.

        Returns:
            (2,) or (N, 2) float64 rectified pixels; the input unchanged if the model
            has no distortion.
        """
        self._calibration()
        pts, single = as_points(uv_raw, 2, "uv_raw")
        if not self._has_distortion:
            return shaped(pts.copy(), single)
        return shaped(self._rectify_points(pts, self._k, self._p, iterations), single)

    def _rectify_points(
        self,
        pts: NDArray[np.float64],
        k: NDArray[np.float64],
        p: NDArray[np.float64],
        iterations: int | None,
    ) -> NDArray[np.float64]:
        src = np.ascontiguousarray(pts.reshape(-1, 1, 2))
        if self._fisheye:
            if iterations is None:
                out = cv2.fisheye.undistortPoints(src, k, self._d, R=self._r, P=p)
            else:
                criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, iterations, 1e-12)
                out = cv2.fisheye.undistortPoints(
                    src, k, self._d, R=self._r, P=p, criteria=criteria
                )
        elif iterations is None:
            out = cv2.undistortPoints(src, k, self._d, R=self._r, P=p)
        else:
            criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, iterations, 1e-12)
            out = cv2.undistortPoints(src, k, self._d, R=self._r, P=p, criteria=criteria)
        result: NDArray[np.float64] = np.asarray(out, dtype=np.float64).reshape(-1, 2)
        return result

    def unrectify_point(self, uv_rect: ArrayLike) -> NDArray[np.float64]:
        """Map rectified pixels back to raw (distorted) pixels.

        The rectified pixel's ray (from ``P``) is rotated by ``R^T`` and projected with
        ``K`` and ``D`` (``cv2.projectPoints`` or ``cv2.fisheye.projectPoints``).

        Args:
            uv_rect: a (2,) pixel or (N, 2) pixels of the rectified image.

        Returns:
            (2,) or (N, 2) raw pixels; the input unchanged if the model has no distortion.
        """
        self._calibration()
        pts, single = as_points(uv_rect, 2, "uv_rect")
        if not self._has_distortion:
            return shaped(pts.copy(), single)
        return shaped(self._unrectify_points(pts, self._k, self._p), single)

    def _unrectify_points(
        self, pts: NDArray[np.float64], k: NDArray[np.float64], p: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        rays = self._rays(pts, p) @ self._r  # row-vector form of R^T @ ray
        obj = np.ascontiguousarray(rays.reshape(-1, 1, 3))
        zero = np.zeros((3, 1))
        if self._fisheye:
            out, _ = cv2.fisheye.projectPoints(obj, zero, zero, k, self._d)
        else:
            out, _ = cv2.projectPoints(obj, zero, zero, k, self._d)
        result: NDArray[np.float64] = np.asarray(out, dtype=np.float64).reshape(-1, 2)
        return result

    def rectify_roi(self, roi_raw: Roi) -> Roi:
        """Rectify an ROI ``(x, y, width, height)`` given in full-resolution raw pixels.

        As image_geometry: the four corners are rectified with the full-resolution
        ``K`` and ``P`` and the largest axis-aligned box inside them is returned.
        """
        self._calibration()
        x, y, w, h = (int(v) for v in roi_raw)
        corners = np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]], dtype=np.float64)
        if self._has_distortion:
            corners = self._rectify_points(corners, self._k_full, self._p_full, None)
        tl, tr, br, bl = corners
        x0 = int(np.ceil(min(tl[0], bl[0])))
        y0 = int(np.ceil(min(tl[1], tr[1])))
        x1 = int(np.floor(max(tr[0], br[0])))
        y1 = int(np.floor(max(bl[1], br[1])))
        return x0, y0, x1 - x0, y1 - y0

    def unrectify_roi(self, roi_rect: Roi) -> Roi:
        """Unrectify an ROI: the bounding box of its four unrectified corners (full resolution).

        Uses the full-resolution ``K`` and ``P`` like :meth:`rectify_roi` (image_geometry
        uses the ROI/binning-adjusted ones here, which only agree without ROI or binning).
        """
        self._calibration()
        x, y, w, h = (int(v) for v in roi_rect)
        corners = np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]], dtype=np.float64)
        if self._has_distortion:
            corners = self._unrectify_points(corners, self._k_full, self._p_full)
        tl, tr, br, bl = corners
        x0 = int(np.floor(min(tl[0], bl[0])))
        y0 = int(np.floor(min(tl[1], tr[1])))
        x1 = int(np.ceil(max(tr[0], br[0])))
        y1 = int(np.ceil(max(bl[1], br[1])))
        return x0, y0, x1 - x0, y1 - y0

    # ------------------------------------------------------------ rectify images

    def rectification_maps(self) -> _Maps | None:
        """Return the cached ``cv2.remap`` maps :meth:`rectify_image` uses (None: no distortion).

        ``map1`` is ``CV_16SC2`` (integer source pixels), ``map2`` the ``CV_16UC1``
        interpolation table, both shaped like the raw (ROI, binned) image.
        """
        self._calibration()
        if not self._has_distortion:
            return None
        if self._reduced_maps is None:
            if self._full_maps is None:
                self._full_maps = self._build_rectify_maps()
            self._reduced_maps = self._crop(self._full_maps)
        return self._reduced_maps

    def _binned_size_kp(self) -> tuple[tuple[int, int], NDArray[np.float64], NDArray[np.float64]]:
        calib = self._calibration()
        size = (calib.width // calib.binning_x, calib.height // calib.binning_y)
        k, p = binned(self._k_full, self._p_full, calib.binning_x, calib.binning_y)
        return size, k, p

    def _build_rectify_maps(self) -> _Maps:
        size, k, p = self._binned_size_kp()
        init = cv2.fisheye.initUndistortRectifyMap if self._fisheye else cv2.initUndistortRectifyMap
        map1, map2 = init(k, self._d, self._r, p, size, cv2.CV_16SC2)
        return np.asarray(map1, dtype=np.int16), np.asarray(map2, dtype=np.uint16)

    def _crop(self, maps: _Maps) -> _Maps:
        calib = self._calibration()
        roi = self._roi
        if (roi.x, roi.y, roi.width, roi.height) == (0, 0, calib.width, calib.height):
            return maps
        x, y = roi.x // calib.binning_x, roi.y // calib.binning_y
        w, h = roi.width // calib.binning_x, roi.height // calib.binning_y
        map1 = maps[0][y : y + h, x : x + w] - np.array([x, y], dtype=np.int16)
        map2 = np.ascontiguousarray(maps[1][y : y + h, x : x + w])
        return map1.astype(np.int16, copy=False), map2

    def _checked_image(self, image: ArrayLike, name: str) -> NDArray[Any]:
        arr = np.asarray(image)
        calib = self._calibration()
        want_w, want_h = self.raw_image_size
        if arr.ndim not in (2, 3) or arr.shape[:2] != (want_h, want_w):
            text = (
                f"{name} has shape {arr.shape}: the camera_info (width {calib.width}, height "
                f"{calib.height}, roi {self.raw_roi}, binning {calib.binning_x}x{calib.binning_y}) "
                f"describes ({want_h}, {want_w}) or ({want_h}, {want_w}, C) images; "
                "pair the image with its own camera_info"
            )
            raise CameraModelError(text)
        if arr.dtype not in _REMAP_DTYPES or (arr.ndim == 3 and arr.shape[2] > _MAX_REMAP_CHANNELS):
            text = (
                f"{name} has dtype {arr.dtype} and shape {arr.shape}: cv2.remap takes uint8, "
                "uint16, int16, float32 or float64 with 1 to 4 channels"
            )
            raise CameraModelError(text)
        return arr

    def rectify_image(
        self, raw: ArrayLike, *, interpolation: int = cv2.INTER_LINEAR
    ) -> NDArray[Any]:
        """Return the rectified image (undistorted and rotated by ``R`` into ``P``'s camera).

        Args:
            raw: the raw image, (H, W) or (H, W, C), sized like the camera_info's
                raw images (ROI, then binning).
            interpolation: a ``cv2.INTER_*`` flag (default bilinear, as image_geometry).

        Returns:
            A new array of the same shape and dtype; a copy if the model has no
            distortion. Pixels that map outside the raw image are 0 (NaN for floats).

        Raises:
            CameraModelError: no calibration yet, or a size / dtype cv2.remap cannot take.
        """
        arr = self._checked_image(raw, "raw")
        maps = self.rectification_maps()
        if maps is None:
            copied: NDArray[Any] = np.array(arr, copy=True)
            return copied
        border = float("nan") if arr.dtype in _FLOAT_DTYPES else 0.0
        out = cv2.remap(
            arr, maps[0], maps[1], interpolation, borderMode=cv2.BORDER_CONSTANT, borderValue=border
        )
        return np.asarray(out)

    def unrectify_image(
        self, rectified: ArrayLike, *, interpolation: int = cv2.INTER_LINEAR
    ) -> NDArray[Any]:
        """Return the raw (distorted) image a rectified image came from (image_geometry's inverse).

        The inverse maps (one :meth:`rectify_point` per pixel) are built on first use
        and cached like the forward maps.
        """
        arr = self._checked_image(rectified, "rectified")
        self._calibration()
        if not self._has_distortion:
            copied: NDArray[Any] = np.array(arr, copy=True)
            return copied
        if self._unrect_reduced_maps is None:
            if self._unrect_full_maps is None:
                size, k, p = self._binned_size_kp()
                xs, ys = np.meshgrid(np.arange(size[0]), np.arange(size[1]))
                grid = np.stack((xs.ravel(), ys.ravel()), axis=1).astype(np.float64)
                rect = self._rectify_points(grid, k, p, None).astype(np.float32)
                fx = np.ascontiguousarray(rect[:, 0].reshape(size[1], size[0]))
                fy = np.ascontiguousarray(rect[:, 1].reshape(size[1], size[0]))
                map1, map2 = cv2.convertMaps(fx, fy, cv2.CV_16SC2)
                full = (np.asarray(map1, dtype=np.int16), np.asarray(map2, dtype=np.uint16))
                self._unrect_full_maps = full
            else:
                full = self._unrect_full_maps
            self._unrect_reduced_maps = self._crop(full)
        map1, map2 = self._unrect_reduced_maps
        border = float("nan") if arr.dtype in _FLOAT_DTYPES else 0.0
        out = cv2.remap(
            arr, map1, map2, interpolation, borderMode=cv2.BORDER_CONSTANT, borderValue=border
        )
        return np.asarray(out)

    def __repr__(self) -> str:
        if self._calib is None:
            return "PinholeCameraModel(<no camera_info>)"
        c = self._calib
        return (
            f"PinholeCameraModel({c.width}x{c.height} {c.distortion_model or 'no distortion'}, "
            f"fx={self.fx:g}, fy={self.fy:g}, cx={self.cx:g}, cy={self.cy:g}, "
            f"frame={self._frame_id!r})"
        )
