"""A rectified stereo pair from two ``CameraInfo`` (image_geometry's ``StereoCameraModel``).

Names are those of image_geometry's Python model (ROS 2 spelling, as visnav's
:class:`~visnav.perception.PinholeCameraModel`)::

    stereo = StereoCameraModel.from_camera_info(left_info, right_info)
    (uv_left, uv_right) = stereo.project_3d_to_pixel((x, y, z))
    xyz = stereo.project_pixel_to_3d(uv_left, disparity)
    z = stereo.get_z(disparity)
    d = stereo.get_disparity(z)
    cloud = stereo.project_disparity_image_to_3d(disparity_image)

The math is image_geometry's C++ (ROS 2, ``stereo_camera_model.cpp``), which its
Python model equals for the usual rectified pair (both cameras share ``cx`` and
``fx = fy``):

* ``baseline B = -Tx' / fx'`` from the right camera's projection matrix ``P'``
  (``Tx' = P'[0, 3] = -fx' * B``), in metres;
* the reprojection matrix ``Q`` maps ``[u, v, d, 1]`` (left rectified pixel,
  disparity ``d = u_left - u_right``) to homogeneous 3D in the left optical frame::

      [ -fy B   0      0     fy B cx      ]
      [  0     -fx B   0     fx B cy      ]
      [  0      0      0    -fx fy B      ]
      [  0      0     -fy    fy (cx - cx')]

  (``cx``, ``cy``, ``fx``, ``fy`` of the left ``P``, ``cx'`` of the right), so
  cameras with different ``cx`` (verged, or rectified with an offset) and
  non-square pixels are handled; ROS 1's models (C++ and Python) use the right
  camera's ``cx``, ``cy`` in ``Q``, which places such points off by
  ``(cx - cx') z / fx``, and a normalised ``Q`` (the same up to scale when
  ``fx = fy``);
* ``get_z(d) = -Tx' / (d - (cx - cx'))``, ``get_disparity(z) = -Tx' / z + (cx - cx')``.

Where visnav differs, on purpose:

* A pair that is not a rectified stereo pair raises :class:`CameraModelError` in
  :meth:`StereoCameraModel.from_camera_info` (image_geometry only asserts in debug
  builds): different ``fx``, ``fy`` or ``cy`` in the two ``P``, or a right ``P``
  with ``Tx' = 0`` (no baseline: probably the left camera_info twice).
* The disparity of a point at infinity (``W = 0``): :meth:`project_pixel_to_3d`
  returns ``(inf, inf, inf)`` (the C++ model divides by zero, giving inf or NaN
  per component; the Python model returns ``(0, 0, 0)``, a valid-looking point);
  :meth:`get_z` returns inf there and :meth:`get_disparity` of ``z = 0`` inf, as
  both do.
* The point methods accept (2,)/(N, 2) and (3,)/(N, 3) arrays.

Each camera_info is read as :class:`~visnav.perception.PinholeCameraModel` reads it:
an empty ``distortion_model`` with a non-zero ``D`` and 4, 8, 12 or 14 coefficients are
accepted as image_geometry and OpenCV accept them (one warning per camera and kind).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, overload

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.msgs.types import CameraInfo
from visnav.perception.camera_model import PinholeCameraModel
from visnav.perception.errors import CameraModelError

__all__ = ["StereoCameraModel"]

_S = TypeVar("_S", bound="StereoCameraModel")
# Relative tolerance for "the same fx / fy / cy" in the two rectified P matrices.
_SAME = 1e-9


class _FromCameraInfo:
    """``from_camera_info``: a constructor on the class, an in-place update on an instance."""

    @overload
    def __get__(self, obj: None, objtype: type[_S]) -> Callable[[CameraInfo, CameraInfo], _S]: ...

    @overload
    def __get__(
        self, obj: _S, objtype: type[_S] | None = None
    ) -> Callable[[CameraInfo, CameraInfo], bool]: ...

    def __get__(
        self, obj: _S | None, objtype: type[_S] | None = None
    ) -> Callable[[CameraInfo, CameraInfo], _S] | Callable[[CameraInfo, CameraInfo], bool]:
        if obj is None:
            if objtype is None:  # pragma: no cover - Python always passes the owner
                text = "from_camera_info needs the class or an instance"
                raise CameraModelError(text)
            cls = objtype

            def build(left: CameraInfo, right: CameraInfo) -> _S:
                model = cls()
                model._update(left, right)
                return model

            build.__doc__ = StereoCameraModel.__doc__
            return build
        return obj._update


def _points(values: ArrayLike, dim: int, name: str) -> tuple[NDArray[np.float64], bool]:
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape == (dim,):
        return arr.reshape(1, dim), True
    if arr.ndim == 2 and arr.shape[1] == dim:
        return arr, False
    text = f"{name} has shape {arr.shape}: expected ({dim},) or (N, {dim})"
    raise CameraModelError(text)


def _same(a: float, b: float) -> bool:
    return abs(a - b) <= _SAME * max(abs(a), abs(b), 1.0)


class StereoCameraModel:
    """An idealized stereo camera: two rectified pinhole cameras with a horizontal baseline.

    Build one with ``StereoCameraModel.from_camera_info(left_info, right_info)``;
    update it with ``model.from_camera_info(left_info, right_info)``, which returns
    True when either calibration changed. Before that, the accessors raise
    :class:`CameraModelError`.

    Attributes:
        left: the left camera (:class:`PinholeCameraModel`); 3D points are in its frame.
        right: the right camera.
    """

    from_camera_info = _FromCameraInfo()

    def __init__(self) -> None:
        self.left = PinholeCameraModel(name="left camera")
        self.right = PinholeCameraModel(name="right camera")
        self._q: NDArray[np.float64] | None = None

    def _update(self, left: CameraInfo, right: CameraInfo) -> bool:
        changed_left = self.left.from_camera_info(left)
        changed_right = self.right.from_camera_info(right)
        lp, rp = self.left.P, self.right.P
        for name, (row, col) in (("fx", (0, 0)), ("fy", (1, 1)), ("cy", (1, 2))):
            if not _same(float(lp[row, col]), float(rp[row, col])):
                text = (
                    f"right camera_info P {name} is {float(rp[row, col])!r} but the left one's "
                    f"is {float(lp[row, col])!r}: a rectified stereo pair shares fx, fy and cy "
                    "(only cx may differ). Publish both camera_infos from one stereo calibration"
                )
                raise CameraModelError(text)
        if float(rp[0, 3]) == 0.0:
            text = (
                "right camera_info P[3] (Tx = -fx * baseline) is 0: no baseline. Give the "
                "right camera's camera_info (its P holds Tx), not the left one twice"
            )
            raise CameraModelError(text)
        if changed_left or changed_right or self._q is None:
            self._q = self._reprojection(lp, rp)
        return changed_left or changed_right

    @staticmethod
    def _reprojection(lp: NDArray[np.float64], rp: NDArray[np.float64]) -> NDArray[np.float64]:
        baseline = -float(rp[0, 3]) / float(rp[0, 0])
        fx, fy, cx, cy = float(lp[0, 0]), float(lp[1, 1]), float(lp[0, 2]), float(lp[1, 2])
        tx = -baseline
        q = np.zeros((4, 4))
        q[0, 0] = fy * tx
        q[0, 3] = -fy * cx * tx
        q[1, 1] = fx * tx
        q[1, 3] = -fx * cy * tx
        q[2, 3] = fx * fy * tx
        q[3, 2] = -fy
        q[3, 3] = fy * (cx - float(rp[0, 2]))
        q.setflags(write=False)
        return q

    def _checked_q(self) -> NDArray[np.float64]:
        if self._q is None:
            text = (
                "the stereo model has no calibration yet: call model.from_camera_info(left, "
                "right) or build it with StereoCameraModel.from_camera_info(left, right)"
            )
            raise CameraModelError(text)
        return self._q

    # -------------------------------------------------------------- accessors

    @property
    def initialized(self) -> bool:
        """True once both cameras have a calibration."""
        return self._q is not None

    @property
    def Q(self) -> NDArray[np.float64]:  # noqa: N802 - image_geometry's name
        """The 4x4 reprojection matrix (read-only): ``[X Y Z W] = Q [u v d 1]`` (see module)."""
        return self._checked_q()

    @property
    def baseline(self) -> float:
        """The distance between the optical centres in metres: ``-Tx' / fx'``."""
        self._checked_q()
        return -float(self.right.P[0, 3]) / float(self.right.P[0, 0])

    @property
    def tf_frame(self) -> str:
        """The frame of the 3D points: the left camera's ``header.frame_id``."""
        self._checked_q()
        return self.left.tf_frame

    # ------------------------------------------------------------ projection

    def project_3d_to_pixel(
        self, xyz: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Project 3D points (left optical frame) into both rectified images.

        Args:
            xyz: a (3,) point or (N, 3) points.

        Returns:
            ``(uv_left, uv_right)``, each (2,) or (N, 2); NaN where z is 0.
        """
        self._checked_q()
        return self.left.project_3d_to_pixel(xyz), self.right.project_3d_to_pixel(xyz)

    def project_pixel_to_3d(self, left_uv: ArrayLike, disparity: ArrayLike) -> NDArray[np.float64]:
        """Return the 3D point seen at left rectified pixel ``left_uv`` with ``disparity``.

        The inverse of :meth:`project_3d_to_pixel` (``disparity = u_left - u_right``).

        Args:
            left_uv: a (2,) pixel or (N, 2) pixels of the left rectified image.
            disparity: pixels, a number or one per pixel.

        Returns:
            (3,) or (N, 3) points in the left optical frame; ``inf`` for the disparity
            at infinity (see the module docs).
        """
        q = self._checked_q()
        uv, single = _points(left_uv, 2, "left_uv")
        d = np.broadcast_to(np.asarray(disparity, dtype=np.float64), (uv.shape[0],))
        xyz = np.stack(
            (q[0, 0] * uv[:, 0] + q[0, 3], q[1, 1] * uv[:, 1] + q[1, 3], np.full(len(d), q[2, 3])),
            axis=1,
        )
        w = q[3, 2] * d + q[3, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            out: NDArray[np.float64] = xyz / w[:, None]
        out[w == 0.0] = np.inf
        return out[0] if single else out

    def get_z(self, disparity: float) -> float:
        """The depth in metres at which a point has ``disparity`` pixels (inf at infinity)."""
        self._checked_q()
        shifted = float(disparity) - (self.left.cx - self.right.cx)
        if shifted == 0.0:
            return float("inf")
        return -float(self.right.P[0, 3]) / shifted

    def get_disparity(self, z: float) -> float:
        """The disparity in pixels of a point at depth ``z`` metres (inf for z = 0)."""
        self._checked_q()
        if float(z) == 0.0:
            return float("inf")
        return -float(self.right.P[0, 3]) / float(z) + (self.left.cx - self.right.cx)

    def project_disparity_image_to_3d(
        self, disparity: NDArray[Any], *, handle_missing_values: bool = False
    ) -> NDArray[np.float32]:
        """Reproject a disparity image (float32 pixels) to an (H, W, 3) image of 3D points.

        ``cv2.reprojectImageTo3D`` with :attr:`Q`, as image_geometry's
        ``projectDisparityImageTo3d``; with ``handle_missing_values`` points of the
        minimal disparity (the matcher's "no match") get z = 10000.

        Raises:
            CameraModelError: not a single-channel image.
        """
        q = self._checked_q()
        disp = np.asarray(disparity)
        if disp.ndim != 2:
            text = f"disparity has shape {disp.shape}: expected a single-channel (H, W) image"
            raise CameraModelError(text)
        if disp.dtype not in (np.float32, np.int16, np.int32, np.uint8):
            disp = disp.astype(np.float32)
        points = cv2.reprojectImageTo3D(
            disp, q, handleMissingValues=handle_missing_values, ddepth=cv2.CV_32F
        )
        return np.asarray(points, dtype=np.float32)
