"""Camera intrinsics and depth handling for SLAM, with the input checks.

SLAM works on rectified images: the intrinsics are the rectified projection
``P`` of a ``sensor_msgs/CameraInfo`` (image_geometry's ``fx()``, ``cx()`` ...),
with binning and ROI applied. RGB-D observations are turned into a virtual
stereo pair (as ORB-SLAM2 does): a feature at ``u`` with depth ``z`` also gets
``u_right = u - bf / z`` for a virtual baseline ``b``, so the optimisers weigh
depth like a disparity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.errors import VisnavError
from visnav.msgs.types import CameraInfo
from visnav.perception.camera_model import PinholeCameraModel
from visnav.slam.errors import SlamInputError

__all__ = [
    "DEFAULT_VIRTUAL_BASELINE",
    "CameraIntrinsics",
    "check_depth_scale",
    "depth_to_metres",
]

DEFAULT_VIRTUAL_BASELINE = 0.08
"""Metres; ORB-SLAM2's TUM settings use ``bf = 40`` for ``fx = 517`` (b ~ 0.077 m)."""

_MAX_MEDIAN_DEPTH = 200.0
_MIN_MEDIAN_DEPTH = 0.02


@dataclass(frozen=True)
class CameraIntrinsics:
    """A rectified pinhole camera: focal lengths, principal point, image size.

    Attributes:
        fx: focal length in pixels along x.
        fy: focal length in pixels along y.
        cx: principal point x (pixels).
        cy: principal point y (pixels).
        width: image width (pixels).
        height: image height (pixels).
        baseline: the virtual stereo baseline in metres used to weigh depth.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    baseline: float = DEFAULT_VIRTUAL_BASELINE

    def __post_init__(self) -> None:
        values = (self.fx, self.fy, self.cx, self.cy, self.baseline)
        if not all(math.isfinite(v) for v in values) or self.fx <= 0 or self.fy <= 0:
            text = (
                f"camera intrinsics fx={self.fx}, fy={self.fy}, cx={self.cx}, cy={self.cy} "
                "are unusable: focal lengths must be finite and positive (an all-zero "
                "camera_info K/P means the camera is uncalibrated: calibrate it first)"
            )
            raise SlamInputError(text)
        if self.width <= 0 or self.height <= 0:
            text = (
                f"camera image size {self.width}x{self.height} is unusable: "
                "camera_info width/height must be positive"
            )
            raise SlamInputError(text)
        if self.baseline <= 0:
            text = f"virtual baseline {self.baseline} m must be positive"
            raise SlamInputError(text)

    @property
    def bf(self) -> float:
        """Baseline times fx (pixels * metres): ``u_right = u - bf / depth``."""
        return self.baseline * self.fx

    def matrix(self) -> NDArray[np.float64]:
        """Return the 3x3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @classmethod
    def from_camera_info(
        cls,
        info: CameraInfo,
        *,
        source: str = "camera_info",
        baseline: float = DEFAULT_VIRTUAL_BASELINE,
    ) -> tuple[CameraIntrinsics, list[str]]:
        """Build intrinsics from a CameraInfo; return them and warnings to log.

        Args:
            info: the camera_info of the (rectified) image stream.
            source: where it came from (a topic or file), named in messages.
            baseline: the virtual stereo baseline (m).

        Returns:
            ``(intrinsics, warnings)``.

        Raises:
            SlamInputError: the camera_info cannot describe a camera.
        """
        try:
            model = PinholeCameraModel.from_camera_info(info)
            fx, fy, cx, cy = model.fx, model.fy, model.cx, model.cy
            width, height = model.reduced_resolution_size
        except VisnavError as exc:
            text = f"{source}: unusable camera_info ({exc})"
            raise SlamInputError(text) from exc
        warnings: list[str] = []
        if model.has_distortion:
            warnings.append(
                f"{source}: distortion {model.distortion_model} D={list(info.d)} is not zero; "
                "SLAM expects rectified images and uses the rectified projection P; feed "
                "image_rect (image_proc) or the distortion will bias the trajectory"
            )
        return cls(fx, fy, cx, cy, int(width), int(height), baseline), warnings

    def check_image(self, shape: tuple[int, ...], *, source: str) -> None:
        """Raise if an image's (height, width) disagrees with these intrinsics."""
        h, w = int(shape[0]), int(shape[1])
        if (w, h) != (self.width, self.height):
            text = (
                f"{source}: image is {w}x{h} but the camera_info describes {self.width}x"
                f"{self.height}; the image and camera_info come from different cameras or "
                "resolutions (check remappings, binning and ROI)"
            )
            raise SlamInputError(text)


def depth_to_metres(
    depth: NDArray[Any], *, depth_scale: float | None = None
) -> NDArray[np.float32]:
    """Convert a depth image to float32 metres with NaN where there is no depth.

    Args:
        depth: uint16 (units of ``1/depth_scale`` m; ROS 16UC1 is millimetres) or
            float32/float64 metres (32FC1).
        depth_scale: raw units per metre of uint16 depth (default 1000; TUM RGB-D
            PNGs use 5000); floating-point depth is metres and is not scaled.

    Returns:
        An (H, W) float32 array of metres; 0, negative and non-finite become NaN.

    Raises:
        SlamInputError: another dtype, a bad scale or a multi-channel image.
    """
    if depth.ndim != 2:
        text = f"depth image has shape {depth.shape}: expected one channel (H, W)"
        raise SlamInputError(text)
    if depth.dtype == np.uint16:
        scale = 1000.0 if depth_scale is None else float(depth_scale)
    elif depth.dtype in (np.float32, np.float64):
        scale = 1.0  # floating-point depth is metres (REP 118): depth_scale does not apply
    else:
        text = (
            f"depth image has dtype {depth.dtype}: expected uint16 (16UC1, millimetres or "
            "1/depth_scale m) or float32 (32FC1, metres)"
        )
        raise SlamInputError(text)
    if depth_scale is not None and (not math.isfinite(depth_scale) or depth_scale <= 0):
        text = f"depth_scale {depth_scale} must be a positive number of raw units per metre"
        raise SlamInputError(text)
    out = depth.astype(np.float32)
    if scale != 1.0:
        out *= np.float32(1.0 / scale)
    with np.errstate(invalid="ignore"):
        out[~(out > 0) | ~np.isfinite(out)] = np.nan
    return out


def check_depth_scale(depth_m: NDArray[np.float32], *, source: str) -> list[str]:
    """Check that a metric depth image is plausible; return warnings.

    A scene whose median depth is above 200 m or below 2 cm is not a scene an
    RGB-D camera sees: the depth unit is wrong (millimetres read as metres or the
    other way round, a wrong TUM ``depth_scale``), which this reports as an error
    naming the factor.

    Raises:
        SlamInputError: the median depth is implausible.
    """
    valid = depth_m[np.isfinite(depth_m)]
    warnings: list[str] = []
    if valid.size < 0.01 * depth_m.size:
        warnings.append(
            f"{source}: only {valid.size} of {depth_m.size} depth pixels are valid; "
            "tracking needs depth on the textured parts of the image"
        )
        if valid.size == 0:
            return warnings
    median = float(np.median(valid))
    if median > _MAX_MEDIAN_DEPTH or median < _MIN_MEDIAN_DEPTH:
        factor = 1000.0 if median > _MAX_MEDIAN_DEPTH else 0.001
        text = (
            f"{source}: median depth {median:.4g} m is implausible for an RGB-D camera "
            f"(expected {_MIN_MEDIAN_DEPTH}..{_MAX_MEDIAN_DEPTH} m); the depth scale is "
            f"probably wrong by {factor:g}x (would give {median / factor:.3g} m): 16UC1 is "
            "millimetres (depth_scale 1000), 32FC1 metres, TUM PNGs 5000 units per metre"
        )
        raise SlamInputError(text)
    return warnings
