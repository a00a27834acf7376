"""Per-frame input checks and stage timing of :class:`~visnav.slam.SlamSystem`."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.slam.camera import CameraIntrinsics, check_depth_scale, depth_to_metres
from visnav.slam.errors import SlamInputError

__all__ = ["STAGES", "Stopwatch", "prepare_inputs", "virtual_baseline"]

STAGES = ("features", "matching", "pose", "mapping", "loop")
"""The timed stages of one frame (:attr:`TrackResult.timings` keys)."""


@dataclass
class Stopwatch:
    """Accumulates wall time and thread CPU time per stage; :meth:`start` switches stage.

    CPU time (:attr:`cpu`) is what a stage costs on a loaded machine, where wall time
    also counts the other processes' turns.
    """

    times: dict[str, float] = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))
    cpu: dict[str, float] = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))
    _t: float = 0.0
    _c: float = 0.0
    _stage: str = ""

    def start(self, stage: str) -> None:
        """End the running stage (if any) and start ``stage`` ("" starts none)."""
        now, cpu = time.perf_counter(), time.thread_time()
        if self._stage:
            self.times[self._stage] += now - self._t
            self.cpu[self._stage] += cpu - self._c
        self._stage, self._t, self._c = stage, now, cpu

    def stop(self) -> dict[str, float]:
        """End the running stage; return seconds per stage."""
        self.start("")
        return dict(self.times)


def virtual_baseline(depth_noise: float, fx: float) -> float:
    """Virtual stereo baseline (m) whose disparity noise matches ``depth_noise * z^2``.

    Raises:
        SlamInputError: ``depth_noise`` is not positive.
    """
    if not depth_noise > 0:
        text = f"depth_noise {depth_noise} must be positive (depth sigma = depth_noise * z^2, m)"
        raise SlamInputError(text)
    return 1.0 / (depth_noise * fx)


def prepare_inputs(
    image: NDArray[Any],
    depth: NDArray[Any] | None,
    cam: CameraIntrinsics,
    *,
    depth_scale: float | None,
    mono: bool,
) -> tuple[NDArray[np.uint8], NDArray[np.uint8] | None, NDArray[np.float32], list[str]]:
    """Check one frame and convert it: ``(gray, colour or None, depth metres, warnings)``.

    Raises:
        SlamInputError: the image or depth does not fit the camera or each other, or
            the depth is missing for RGB-D.
    """
    cam.check_image(image.shape, source="image")
    if depth is None:
        if not mono:
            text = "depth is None: RGB-D SLAM needs a depth image per frame (or sensor 'mono')"
            raise SlamInputError(text)
    elif depth.shape[:2] != image.shape[:2]:
        text = (
            f"depth is {depth.shape[1]}x{depth.shape[0]} but the image is {image.shape[1]}x"
            f"{image.shape[0]}: SLAM needs depth registered to the image (same size)"
        )
        raise SlamInputError(text)
    if image.dtype != np.uint8:
        text = f"image has dtype {image.dtype}: expected uint8 (mono8, rgb8 or bgr8)"
        raise SlamInputError(text)
    colour: NDArray[np.uint8] | None = None
    if image.ndim == 3 and image.shape[2] in (3, 4):
        colour = np.ascontiguousarray(image[:, :, :3])
        gray = np.asarray(cv2.cvtColor(colour, cv2.COLOR_RGB2GRAY), dtype=np.uint8)
    elif image.ndim == 2:
        gray = np.ascontiguousarray(image)
    else:
        text = f"image has shape {image.shape}: expected (H, W) mono or (H, W, 3) colour"
        raise SlamInputError(text)
    if depth is None:  # monocular without depth
        return gray, colour, np.full(gray.shape, np.nan, dtype=np.float32), []
    depth_m = depth_to_metres(depth, depth_scale=depth_scale)
    warnings = check_depth_scale(depth_m[::4, ::4], source="depth")
    return gray, colour, depth_m, warnings
