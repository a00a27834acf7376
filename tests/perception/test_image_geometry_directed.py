"""image_geometry's own directed tests (vision_opencv ``image_geometry/test/directed.py``), ported.

The inputs and expected values are upstream's (ROS 1 Noetic): ``test_monocular`` feeds an
uncalibrated CameraInfo (only width and height set), ``test_stereo`` a real stereo
calibration whose CameraInfos leave ``distortion_model`` empty, with 5 coefficients on
the left and 4 on the right. Upstream checks the stereo round trip (left pixel and
disparity to 3D and back to both pixels) and the pixel/metre deltas to 3 decimals.

Where both run, visnav is compared with Debian's python3-image-geometry (the ROS 1
Python model), run as a subprocess of the system Python, to 1e-12.

Where visnav differs: ``test_monocular``'s CameraInfo (``K`` and ``P`` all zero) is
refused with a CameraModelError naming ``k`` (image_geometry accepts it and answers NaN
to every query, shown here from the real one).
"""

from __future__ import annotations

import json
import logging
import subprocess
from typing import Any

import numpy as np
import pytest

from visnav.msgs import CameraInfo, Header, RegionOfInterest, Time
from visnav.perception import CameraModelError, PinholeCameraModel, StereoCameraModel

SYSTEM_PYTHON = "/usr/bin/python3"
WIDTH, HEIGHT = 640, 480
# 3 decimals, as unittest's assertAlmostEqual(a, b, 3): round(a - b, 3) == 0.
THREE_DECIMALS = 5e-4

# The stereo calibration of upstream's test_stereo (a real camera pair).
LEFT = {
    "d": [-0.363528858080088, 0.16117037733986861, -8.1109585007538829e-05,
          -0.00044776712298447841, 0.0],
    "k": [430.15433020105519, 0.0, 311.71339830549732,
          0.0, 430.60920415473657, 221.06824942698509, 0.0, 0.0, 1.0],
    "r": [0.99806560714807102, 0.0068562422224214027, 0.061790256276695904,
          -0.0067522959054715113, 0.99997541519165112, -0.0018909025066874664,
          -0.061801701660692349, 0.0014700186639396652, 0.99808736527268516],
    "p": [295.53402059708782, 0.0, 285.55760765075684, 0.0,
          0.0, 295.53402059708782, 223.29617881774902, 0.0, 0.0, 0.0, 1.0, 0.0],
}  # fmt: skip
RIGHT = {
    "d": [-0.3560641041112021, 0.15647260261553159, -0.00016442960757099968,
          -0.00093175810713916221],
    "k": [428.38163131344191, 0.0, 327.95553847249192,
          0.0, 428.85728580588329, 217.54828640915309, 0.0, 0.0, 1.0],
    "r": [0.9982082576219119, 0.0067433328293516528, 0.059454199832973849,
          -0.0068433268864187356, 0.99997549128605434, 0.0014784127772287513,
          -0.059442773257581252, -0.0018826283666309878, 0.99822993965212292],
    "p": [295.53402059708782, 0.0, 285.55760765075684, -26.507895206214123,
          0.0, 295.53402059708782, 223.29617881774902, 0.0, 0.0, 0.0, 1.0, 0.0],
}  # fmt: skip
ZEROS9, ZEROS12 = [0.0] * 9, [0.0] * 12


def camera_info(calib: dict[str, list[float]], *, distortion_model: str = "") -> CameraInfo:
    """A CameraInfo as upstream's test fills it: width, height, D, K, R, P, nothing else."""
    return CameraInfo(
        header=Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
        height=HEIGHT,
        width=WIDTH,
        distortion_model=distortion_model,
        d=np.array(calib.get("d", []), dtype=np.float64),
        k=np.array(calib.get("k", ZEROS9), dtype=np.float64),
        r=np.array(calib.get("r", ZEROS9), dtype=np.float64),
        p=np.array(calib.get("p", ZEROS12), dtype=np.float64),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def stereo_pair() -> StereoCameraModel:
    return StereoCameraModel.from_camera_info(camera_info(LEFT), camera_info(RIGHT))


# ------------------------------------------------------------------ test_monocular


def test_monocular_uncalibrated_camera_info_is_refused() -> None:
    # Upstream builds a model from a CameraInfo with only width and height and prints
    # rectifyPoint((0, 0)) and project3dToPixel((0, 0, 0)); both are NaN there.
    with pytest.raises(CameraModelError, match=r"k is all zero: the camera is uncalibrated"):
        PinholeCameraModel.from_camera_info(camera_info({}))


def test_monocular_point_at_the_optical_centre_is_nan() -> None:
    # project3dToPixel((0, 0, 0)) divides by z = 0: NaN, not an exception.
    model = PinholeCameraModel.from_camera_info(camera_info(LEFT))
    assert np.isnan(model.project_3d_to_pixel((0.0, 0.0, 0.0))).all()


# ------------------------------------------------------------------ test_stereo


def test_stereo_accepts_empty_distortion_model_and_four_coefficients() -> None:
    cam = stereo_pair()
    assert cam.left.distortion_model == cam.right.distortion_model == "plumb_bob"
    assert cam.left.has_distortion
    assert cam.right.has_distortion
    # 4 coefficients are k1 k2 p1 p2; OpenCV adds k3 = 0.
    assert cam.right.D.tolist() == [*RIGHT["d"], 0.0]


def test_stereo_round_trip() -> None:
    cam = stereo_pair()
    for x in (16, WIDTH // 2, WIDTH - 16):
        for y in (16, HEIGHT // 2, HEIGHT - 16):
            for disparity in range(1, 10):
                point = cam.project_pixel_to_3d((x, y), disparity)
                (lx, ly), (rx, ry) = cam.project_3d_to_pixel(point)
                assert abs(ly - y) < THREE_DECIMALS
                assert abs(ry - y) < THREE_DECIMALS
                assert abs(lx - x) < THREE_DECIMALS
                assert abs(rx + disparity - x) < THREE_DECIMALS


def test_stereo_pixel_and_metre_deltas() -> None:
    cam = stereo_pair()
    u, v, du, dv, z = 100.0, 200.0, 17.0, 23.0, 2.0
    near, far = cam.left.project_pixel_to_3d_ray([(u, v), (u + du, v + dv)]) * z
    dx, dy = far[0] - near[0], far[1] - near[1]
    assert abs(cam.left.get_delta_u(dx, z) - du) < THREE_DECIMALS
    assert abs(cam.left.get_delta_v(dy, z) - dv) < THREE_DECIMALS
    assert abs(cam.left.get_delta_x(du, z) - dx) < THREE_DECIMALS
    assert abs(cam.left.get_delta_y(dv, z) - dy) < THREE_DECIMALS


def test_stereo_assumption_is_logged_once_per_camera(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="visnav.perception.camera_model")
    cam = stereo_pair()
    for _ in range(3):
        cam.from_camera_info(camera_info(LEFT), camera_info(RIGHT))
    texts = [r.getMessage() for r in caplog.records]
    assert len(texts) == 2, texts
    left, right = texts
    assert left.startswith("left camera")
    assert right.startswith("right camera")
    for text in texts:
        assert "distortion_model is empty" in text
        assert "applied as 'plumb_bob'" in text
        assert "set distortion_model: plumb_bob" in text
    assert "k3 = 0" in right
    # A second model warns again: the warning is per model, not per process.
    caplog.clear()
    stereo_pair()
    assert len(caplog.records) == 2


# ------------------------------------------------------------------ oracle

ORACLE = r"""
import json, math, sys
import image_geometry
from sensor_msgs.msg import CameraInfo

args = json.loads(sys.argv[1])

def msg(calib):
    m = CameraInfo()
    m.width, m.height = 640, 480
    m.distortion_model = calib.get("model", "")
    m.D = calib.get("d", [])
    m.K = calib.get("k", [0.0] * 9)
    m.R = calib.get("r", [0.0] * 9)
    m.P = calib.get("p", [0.0] * 12)
    return m

def floats(values):
    return [None if math.isnan(v) else float(v) for v in values]

out = {}
mono = image_geometry.PinholeCameraModel()
mono.fromCameraInfo(msg({}))
out["uncalibrated"] = floats([*mono.rectifyPoint((0, 0)), *mono.project3dToPixel((0, 0, 0))])
cam = image_geometry.StereoCameraModel()
cam.fromCameraInfo(msg(args["left"]), msg(args["right"]))
out["xyz"] = [list(cam.projectPixelTo3d(uv, d)) for uv, d in args["queries"]]
out["pix"] = [[list(map(float, l)), list(map(float, r))]
              for l, r in (cam.project3dToPixel(p) for p in args["points"])]
out["z"] = [cam.getZ(d) for _, d in args["queries"]]
out["disp"] = [cam.getDisparity(p[2]) for p in args["points"]]
out["rays"] = [list(cam.left.projectPixelTo3dRay(uv)) for uv, _ in args["queries"]]
out["deltas"] = [[cam.left.getDeltaU(a, z), cam.left.getDeltaV(a, z),
                  cam.left.getDeltaX(a, z), cam.left.getDeltaY(a, z)] for a, z in args["deltas"]]
out["rect_left"] = [list(map(float, cam.left.rectifyPoint(uv))) for uv, _ in args["queries"]]
out["rect_right"] = [list(map(float, cam.right.rectifyPoint(uv))) for uv, _ in args["queries"]]
out["mono"] = {}
for name, calib in args["mono"].items():
    model = image_geometry.PinholeCameraModel()
    model.fromCameraInfo(msg(calib))
    out["mono"][name] = [list(map(float, model.rectifyPoint(uv))) for uv, _ in args["queries"]]
print(json.dumps(out))
"""


def oracle_available() -> bool:
    try:
        probe = subprocess.run(
            [SYSTEM_PYTHON, "-c", "import image_geometry, sensor_msgs.msg"],
            capture_output=True,
            check=False,
            timeout=60,
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return probe.returncode == 0


needs_oracle = pytest.mark.skipif(not oracle_available(), reason="python3-image-geometry absent")

# D of every length OpenCV takes, under the model names a camera_info may carry.
RATIONAL_8 = [*LEFT["d"][:4], 0.01, 0.002, -0.001, 0.0005]
THIN_PRISM_12 = [*RATIONAL_8, 1e-3, -2e-4, 3e-4, 1e-4]
TILTED_14 = [*THIN_PRISM_12, 1e-3, -2e-3]
MONO_D = {
    "plumb_bob_4": ("plumb_bob", RIGHT["d"]),
    "empty_8": ("", RATIONAL_8),
    "rational_8": ("rational_polynomial", RATIONAL_8),
    "rational_12": ("rational_polynomial", THIN_PRISM_12),
    "rational_14": ("rational_polynomial", TILTED_14),
    "empty_14": ("", TILTED_14),
    "rational_5": ("rational_polynomial", LEFT["d"]),
}


@pytest.fixture(scope="module")
def oracle() -> dict[str, Any]:
    """image_geometry's (ROS 1 Python model) answers for the queries of :func:`queries`."""
    rng = np.random.default_rng(30)
    queries = [([float(rng.uniform(0, WIDTH)), float(rng.uniform(0, HEIGHT))],
                float(rng.uniform(0.5, 60))) for _ in range(40)]  # fmt: skip
    points = [[float(rng.uniform(-2, 2)), float(rng.uniform(-1, 1)), float(rng.uniform(0.3, 20))]
              for _ in range(40)]  # fmt: skip
    deltas = [[float(rng.uniform(-50, 50)), float(rng.uniform(0.2, 30))] for _ in range(10)]
    mono = {name: {**LEFT, "model": model, "d": d} for name, (model, d) in MONO_D.items()}
    args = {
        "left": LEFT,
        "right": RIGHT,
        "queries": queries,
        "points": points,
        "deltas": deltas,
        "mono": mono,
    }
    done = subprocess.run(
        [SYSTEM_PYTHON, "-c", ORACLE, json.dumps(args)],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    answers: dict[str, Any] = json.loads(done.stdout)
    return {"args": args, **answers}


def close(ours: Any, theirs: Any) -> bool:
    return bool(np.allclose(ours, theirs, rtol=1e-12, atol=1e-12))


@needs_oracle
def test_image_geometry_answers_nan_for_the_uncalibrated_camera(oracle: dict[str, Any]) -> None:
    # What visnav refuses, image_geometry accepts and answers with NaN: nothing usable lost.
    assert oracle["uncalibrated"] == [None, None, None, None]


@needs_oracle
def test_stereo_agrees_with_image_geometry(oracle: dict[str, Any]) -> None:
    cam = stereo_pair()
    args = oracle["args"]
    uvs = np.array([uv for uv, _ in args["queries"]])
    disparities = np.array([d for _, d in args["queries"]])
    assert close(cam.project_pixel_to_3d(uvs, disparities), oracle["xyz"])
    for p, (left, right) in zip(args["points"], oracle["pix"], strict=True):
        ours_left, ours_right = cam.project_3d_to_pixel(p)
        assert close(ours_left, left)
        assert close(ours_right, right)
    assert close([cam.get_z(d) for d in disparities], oracle["z"])
    assert close([cam.get_disparity(p[2]) for p in args["points"]], oracle["disp"])
    assert close(cam.left.project_pixel_to_3d_ray(uvs, normalize=True), oracle["rays"])
    ours = [
        [cam.left.get_delta_u(a, z), cam.left.get_delta_v(a, z),
         cam.left.get_delta_x(a, z), cam.left.get_delta_y(a, z)]
        for a, z in args["deltas"]
    ]  # fmt: skip
    assert close(ours, oracle["deltas"])
    # Rectification with the empty distortion_model: 5 coefficients left, 4 right.
    assert close(cam.left.rectify_point(uvs), oracle["rect_left"])
    assert close(cam.right.rectify_point(uvs), oracle["rect_right"])


@needs_oracle
@pytest.mark.parametrize("name", list(MONO_D))
def test_every_opencv_length_agrees_with_image_geometry(
    oracle: dict[str, Any], name: str, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING, logger="visnav.perception.camera_model")
    model_name, d = MONO_D[name]
    model = PinholeCameraModel.from_camera_info(
        camera_info({**LEFT, "d": d}, distortion_model=model_name)
    )
    uvs = np.array([uv for uv, _ in oracle["args"]["queries"]])
    assert close(model.rectify_point(uvs), oracle["mono"][name])
    # Silent where the name fits the length (plumb_bob's 4 are OpenCV's own padding).
    fits = name in {"plumb_bob_4", "rational_8", "rational_12", "rational_14"}
    assert len(caplog.records) == (0 if fits else 1), [r.getMessage() for r in caplog.records]
