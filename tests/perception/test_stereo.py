"""StereoCameraModel against image_geometry: its unit test's checks, its Python model as an oracle.

The calibration is the real stereo pair of image_geometry's own test
(``image_geometry/test/directed.py``, Noetic). The oracle runs Debian's
python3-image-geometry (ROS 1 Python model) in the system Python.
"""

from __future__ import annotations

import json
import subprocess
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.msgs import CameraInfo, Header, RegionOfInterest, Time
from visnav.perception import CameraModelError, StereoCameraModel

SYSTEM_PYTHON = "/usr/bin/python3"
W, H = 640, 480
LEFT_P = [295.53402059708782, 0.0, 285.55760765075684, 0.0]
LEFT_P += [0.0, 295.53402059708782, 223.29617881774902, 0.0, 0.0, 0.0, 1.0, 0.0]
RIGHT_P = [295.53402059708782, 0.0, 285.55760765075684, -26.507895206214123]
RIGHT_P += [0.0, 295.53402059708782, 223.29617881774902, 0.0, 0.0, 0.0, 1.0, 0.0]
LEFT_K = [430.15433020105519, 0.0, 311.71339830549732]
LEFT_K += [0.0, 430.60920415473657, 221.06824942698509, 0.0, 0.0, 1.0]
RIGHT_K = [428.38163131344191, 0.0, 327.95553847249192]
RIGHT_K += [0.0, 428.85728580588329, 217.54828640915309, 0.0, 0.0, 1.0]
LEFT_D = [-0.363528858080088, 0.16117037733986861, -8.1109585007538829e-05]
LEFT_D += [-0.00044776712298447841, 0.0]
RIGHT_D = [-0.3560641041112021, 0.15647260261553159, -0.00016442960757099968]
RIGHT_D += [-0.00093175810713916221, 0.0]
LEFT_R = [0.99806560714807102, 0.0068562422224214027, 0.061790256276695904]
LEFT_R += [-0.0067522959054715113, 0.99997541519165112, -0.0018909025066874664]
LEFT_R += [-0.061801701660692349, 0.0014700186639396652, 0.99808736527268516]
RIGHT_R = [0.9982082576219119, 0.0067433328293516528, 0.059454199832973849]
RIGHT_R += [-0.0068433268864187356, 0.99997549128605434, 0.0014784127772287513]
RIGHT_R += [-0.059442773257581252, -0.0018826283666309878, 0.99822993965212292]


def info(k: list[float], d: list[float], r: list[float], p: list[float]) -> CameraInfo:
    return CameraInfo(
        header=Header(stamp=Time(sec=1, nanosec=0), frame_id="stereo_left_optical"),
        height=H,
        width=W,
        distortion_model="plumb_bob",
        d=np.array(d),
        k=np.array(k),
        r=np.array(r),
        p=np.array(p),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def pair(right_p: list[float] | None = None) -> StereoCameraModel:
    left = info(LEFT_K, LEFT_D, LEFT_R, LEFT_P)
    right = info(RIGHT_K, RIGHT_D, RIGHT_R, right_p or RIGHT_P)
    return StereoCameraModel.from_camera_info(left, right)


def test_image_geometry_directed_test_round_trip() -> None:
    # image_geometry's test_stereo: pixel + disparity -> 3D -> both pixels.
    cam = pair()
    for x in (16, 320, W - 16):
        for y in (16, 240, H - 16):
            for d in range(1, 10):
                pt = cam.project_pixel_to_3d((x, y), d)
                (lx, ly), (rx, ry) = cam.project_3d_to_pixel(pt)
                assert ly == pytest.approx(y, abs=1e-3)
                assert ry == pytest.approx(y, abs=1e-3)
                assert lx == pytest.approx(x, abs=1e-3)
                assert rx + d == pytest.approx(x, abs=1e-3)
    assert cam.tf_frame == "stereo_left_optical"


def test_baseline_depth_and_disparity() -> None:
    cam = pair()
    fx = LEFT_P[0]
    baseline = 26.507895206214123 / fx
    assert cam.baseline == pytest.approx(baseline)
    assert cam.get_z(10.0) == pytest.approx(fx * baseline / 10.0)
    assert cam.get_disparity(cam.get_z(7.5)) == pytest.approx(7.5)
    assert cam.get_z(0.0) == float("inf")
    assert cam.get_disparity(0.0) == float("inf")
    assert np.all(np.isinf(cam.project_pixel_to_3d((100.0, 100.0), 0.0)))


def test_verged_cameras_with_different_cx() -> None:
    # Right principal point 12.5 px to the left: disparities carry a 12.5 px offset.
    right_p = list(RIGHT_P)
    right_p[2] -= 12.5
    cam = pair(right_p)
    points = np.array([[0.3, -0.2, 2.0], [-1.0, 0.5, 5.0], [0.0, 0.0, 0.8]])
    left_uv, right_uv = cam.project_3d_to_pixel(points)
    disparity = left_uv[:, 0] - right_uv[:, 0]
    assert np.allclose(cam.project_pixel_to_3d(left_uv, disparity), points, atol=1e-9)
    for z, d in zip(points[:, 2], disparity, strict=True):
        assert cam.get_z(d) == pytest.approx(z)
        assert cam.get_disparity(z) == pytest.approx(d)


def test_disparity_image_to_3d_matches_point_method() -> None:
    cam = pair()
    rng = np.random.default_rng(7)
    disp = rng.uniform(2.0, 40.0, size=(6, 8)).astype(np.float32)
    cloud = cam.project_disparity_image_to_3d(disp)
    v, u = np.mgrid[0:6, 0:8]
    uv = np.stack((u.ravel(), v.ravel()), axis=1).astype(float)
    expected = cam.project_pixel_to_3d(uv, disp.ravel().astype(float))
    assert np.allclose(cloud.reshape(-1, 3), expected, rtol=1e-5)


def test_not_a_rectified_pair_is_refused() -> None:
    bad = list(RIGHT_P)
    bad[5] += 3.0  # fy differs
    with pytest.raises(CameraModelError, match=r"right camera_info P fy is 298\.534"):
        pair(bad)
    with pytest.raises(CameraModelError, match=r"P\[3\] \(Tx = -fx \* baseline\) is 0"):
        pair(LEFT_P)
    with pytest.raises(CameraModelError, match="no calibration yet"):
        StereoCameraModel().get_z(1.0)


def test_update_reports_changes() -> None:
    cam = pair()
    left = info(LEFT_K, LEFT_D, LEFT_R, LEFT_P)
    right = info(RIGHT_K, RIGHT_D, RIGHT_R, RIGHT_P)
    assert cam.from_camera_info(left, right) is False
    right_p = list(RIGHT_P)
    right_p[3] *= 2.0
    assert cam.from_camera_info(left, info(RIGHT_K, RIGHT_D, RIGHT_R, right_p)) is True
    assert cam.baseline == pytest.approx(2 * 26.507895206214123 / LEFT_P[0])


# ------------------------------------------------------------------ oracle

ORACLE = r"""
import json, sys
import image_geometry
from sensor_msgs.msg import CameraInfo
args = json.loads(sys.argv[1])
def msg(k, d, r, p):
    m = CameraInfo()
    m.width, m.height = 640, 480
    m.distortion_model = "plumb_bob"
    m.K, m.D, m.R, m.P = k, d, r, p
    return m
cam = image_geometry.StereoCameraModel()
cam.fromCameraInfo(msg(*args["left"]), msg(*args["right"]))
out = {"xyz": [list(cam.projectPixelTo3d(uv, d)) for uv, d in args["queries"]],
       "pix": [[list(map(float, l)), list(map(float, r))]
               for l, r in (cam.project3dToPixel(p) for p in args["points"])],
       "z": [cam.getZ(d) for _, d in args["queries"]],
       "disp": [cam.getDisparity(p[2]) for p in args["points"]]}
print(json.dumps(out))
"""


def oracle_available() -> bool:
    probe = subprocess.run(
        [SYSTEM_PYTHON, "-c", "import image_geometry, sensor_msgs.msg"],
        capture_output=True,
        check=False,
    )
    return probe.returncode == 0


@pytest.mark.skipif(not oracle_available(), reason="python3-image-geometry absent")
def test_equals_image_geometry_python_model() -> None:
    rng = np.random.default_rng(18)
    queries = [([float(rng.uniform(0, W)), float(rng.uniform(0, H))], float(rng.uniform(0.5, 60)))]
    queries += [([float(rng.uniform(0, W)), float(rng.uniform(0, H))], float(rng.uniform(0.5, 60)))
                for _ in range(40)]  # fmt: skip
    points = [[float(rng.uniform(-2, 2)), float(rng.uniform(-1, 1)), float(rng.uniform(0.3, 20))]
              for _ in range(40)]  # fmt: skip
    args = {
        "left": [LEFT_K, LEFT_D, LEFT_R, LEFT_P],
        "right": [RIGHT_K, RIGHT_D, RIGHT_R, RIGHT_P],
        "queries": queries,
        "points": points,
    }
    done = subprocess.run(
        [SYSTEM_PYTHON, "-c", ORACLE, json.dumps(args)],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    want: dict[str, Any] = json.loads(done.stdout)
    cam = pair()
    for (uv, d), xyz in zip(queries, want["xyz"], strict=True):
        assert np.allclose(cam.project_pixel_to_3d(uv, d), xyz, rtol=1e-12, atol=1e-12)
    for p, (left, right) in zip(points, want["pix"], strict=True):
        ours_left, ours_right = cam.project_3d_to_pixel(p)
        assert np.allclose(ours_left, left, atol=1e-9)
        assert np.allclose(ours_right, right, atol=1e-9)
    assert np.allclose([cam.get_z(d) for _, d in queries], want["z"], rtol=1e-12)
    assert np.allclose([cam.get_disparity(p[2]) for p in points], want["disp"], rtol=1e-12)


@settings(max_examples=50, deadline=None)
@given(
    x=st.floats(-5, 5),
    y=st.floats(-5, 5),
    z=st.floats(0.2, 50),
    offset=st.floats(-30, 30),
)
def test_projection_round_trip_property(x: float, y: float, z: float, offset: float) -> None:
    right_p = list(RIGHT_P)
    right_p[2] += offset
    cam = pair(right_p)
    left_uv, right_uv = cam.project_3d_to_pixel((x, y, z))
    d = float(left_uv[0] - right_uv[0])
    assert np.allclose(cam.project_pixel_to_3d(left_uv, d), (x, y, z), rtol=1e-9, atol=1e-9)
