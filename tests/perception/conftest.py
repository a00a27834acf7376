"""Shared camera_info factories for the perception tests."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from visnav.msgs import CameraInfo, Header, RegionOfInterest, Time

# A real plumb_bob calibration (image_geometry's utest.cpp).
PLUMB_D = [
    -0.363528858080088,
    0.16117037733986861,
    -8.1109585007538829e-05,
    -0.00044776712298447841,
    0.0,
]
PLUMB_K = [
    430.15433020105519,
    0.0,
    311.71339830549732,
    0.0,
    430.60920415473657,
    221.06824942698509,
    0.0,
    0.0,
    1.0,
]
PLUMB_R = [
    0.99806560714807102, 0.0068562422224214027, 0.061790256276695904,
    -0.0067522959054715113, 0.99997541519165112, -0.0018909025066874664,
    -0.061801701660692349, 0.0014700186639396652, 0.99808736527268516,
]  # fmt: skip
PLUMB_P = [
    295.53402059708782,
    0.0,
    285.55760765075684,
    0.0,
    0.0,
    295.53402059708782,
    223.29617881774902,
    0.0,
    0.0,
    0.0,
    1.0,
    0.0,
]

# A real equidistant calibration (image_geometry's utest_equi.cpp), 640 x 512.
EQUI_D = [-0.08857683871674071, 0.0708113094372378, -0.09127623055964429, 0.04006922269778478]
EQUI_K = [
    403.603063319358,
    0.0,
    306.15842863283063,
    0.0,
    403.7028851121003,
    261.09715697592696,
    0.0,
    0.0,
    1.0,
]
EQUI_R = [
    0.999963944103842, -0.008484152966323483, 0.00036005656766869323,
    0.008484153516269438, 0.9999640089218772, 0.0,
    -0.0003600436088446379, 3.0547751946422504e-06, 0.999999935179632,
]  # fmt: skip
EQUI_P = [
    347.2569964503485,
    0.0,
    350.5,
    0.0,
    0.0,
    347.2569964503485,
    256.0,
    0.0,
    0.0,
    0.0,
    1.0,
    0.0,
]

IDENTITY = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]

InfoFactory = Callable[..., CameraInfo]


def _camera_info(
    *,
    width: int = 640,
    height: int = 480,
    k: Sequence[float] | None = None,
    p: Sequence[float] | None = None,
    r: Sequence[float] = IDENTITY,
    d: Sequence[float] = (),
    distortion_model: str = "plumb_bob",
    fx: float = 525.0,
    fy: float | None = None,
    cx: float | None = None,
    cy: float | None = None,
    binning: tuple[int, int] = (0, 0),
    roi: tuple[int, int, int, int] = (0, 0, 0, 0),
    do_rectify: bool = False,
    frame_id: str = "camera_optical",
    stamp: tuple[int, int] = (12, 345),
) -> CameraInfo:
    """Return a CameraInfo; without k/p, a pinhole with fx (fy), cx, cy and P = [K | 0]."""
    fy = fx if fy is None else fy
    cx = (width - 1) / 2.0 if cx is None else cx
    cy = (height - 1) / 2.0 if cy is None else cy
    if k is None:
        k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    if p is None:
        p = [*k[0:3], 0.0, *k[3:6], 0.0, *k[6:9], 0.0]
    x, y, w, h = roi
    return CameraInfo(
        header=Header(stamp=Time(sec=stamp[0], nanosec=stamp[1]), frame_id=frame_id),
        height=height,
        width=width,
        distortion_model=distortion_model,
        d=np.array(d, dtype=np.float64),
        k=np.array(k, dtype=np.float64),
        r=np.array(r, dtype=np.float64),
        p=np.array(p, dtype=np.float64),
        binning_x=binning[0],
        binning_y=binning[1],
        roi=RegionOfInterest(x_offset=x, y_offset=y, height=h, width=w, do_rectify=do_rectify),
    )


@pytest.fixture(scope="session")
def make_info() -> InfoFactory:
    """Factory of CameraInfo messages (keyword arguments as :func:`_camera_info`)."""
    return _camera_info


@pytest.fixture(scope="session")
def plumb_info() -> Callable[..., CameraInfo]:
    """Factory of image_geometry's test plumb_bob camera (overrides as keywords)."""

    def make(**kwargs: Any) -> CameraInfo:
        args: dict[str, Any] = {"k": PLUMB_K, "p": PLUMB_P, "r": PLUMB_R, "d": PLUMB_D}
        args.update(kwargs)
        return _camera_info(**args)

    return make


@pytest.fixture(scope="session")
def equi_info() -> Callable[..., CameraInfo]:
    """Factory of image_geometry's test equidistant camera (640 x 512)."""

    def make(**kwargs: Any) -> CameraInfo:
        args: dict[str, Any] = {
            "k": EQUI_K,
            "p": EQUI_P,
            "r": EQUI_R,
            "d": EQUI_D,
            "distortion_model": "equidistant",
            "height": 512,
        }
        args.update(kwargs)
        return _camera_info(**args)

    return make


@pytest.fixture(scope="session")
def upstream() -> SimpleNamespace:
    """image_geometry's test calibrations (PLUMB_* and EQUI_* lists)."""
    return SimpleNamespace(
        PLUMB_D=PLUMB_D,
        PLUMB_K=PLUMB_K,
        PLUMB_R=PLUMB_R,
        PLUMB_P=PLUMB_P,
        EQUI_D=EQUI_D,
        EQUI_K=EQUI_K,
        EQUI_R=EQUI_R,
        EQUI_P=EQUI_P,
    )
