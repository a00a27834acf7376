"""Calibration against references: OpenCV's own samples and a camera simulated in MuJoCo.

* OpenCV's ``samples/data/left01..left14.jpg`` (Debian package opencv-doc): visnav's
  calibration must match OpenCV's tutorial pipeline (findChessboardCorners +
  cornerSubPix 11x11 + calibrateCamera with k3 fixed), run here in the same test.
* The seed camera (640x480, hfov 1.0472 rad, fx = 554.256) rendered by visnav's
  simulator looking at a chessboard from 20 poses: ``visnav calibrate`` must recover it.
* Degenerate views (one pose repeated, boards parallel to the image plane), tiny and
  oversized images give one-line errors and no YAML.
"""

from __future__ import annotations

import math
import os
import shutil
import struct
import subprocess
import sys
import zlib
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

import cv2
import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from visnav.description.gazebo import CameraSpec, default_principal_point
from visnav.description.rigid import R_SENSOR_MJCAM, matrix_to_quat_wxyz
from visnav.perception._calibration_common import CalibrationError
from visnav.perception.calibration import calibrate, read_camera_info_yaml
from visnav.perception.calibration_images import header_size, read_gray_image
from visnav.perception.chessboard import MAX_IMAGE_PIXELS, find_chessboard, refine_radius
from visnav.sim.camera import CameraSensor, configure_mujoco_camera

# ------------------------------------------------------------------ the simulated board
# A white plate with black square tiles on a mocap body in front of a camera configured
# by configure_mujoco_camera with the seed camera's intrinsics, rendered by CameraSensor.

SEED_WIDTH, SEED_HEIGHT, SEED_HFOV = 640, 480, 1.0472
SEED_FX = SEED_WIDTH / (2.0 * math.tan(SEED_HFOV / 2.0))  # 554.256


def seed_camera_spec() -> CameraSpec:
    """The seed camera: 640x480, hfov 1.0472 rad, square pixels, principal point at the centre."""
    cx, cy = default_principal_point(SEED_WIDTH, SEED_HEIGHT)
    return CameraSpec(
        name="cam",
        link="cam_link",
        width=SEED_WIDTH,
        height=SEED_HEIGHT,
        hfov=SEED_HFOV,
        fx=SEED_FX,
        fy=SEED_FX,
        cx=cx,
        cy=cy,
        frame_id="cam_optical",
        image_topic="/cam/image_raw",
        clip_near=0.05,
        clip_far=10.0,
    )


def _board_model(spec: CameraSpec, pattern: tuple[int, int], square: float) -> mujoco.MjModel:
    cols, rows = pattern[0] + 1, pattern[1] + 1  # squares
    margin = square
    mj = mujoco.MjSpec()
    mj.visual.headlight.ambient = [1.0, 1.0, 1.0]
    mj.visual.headlight.diffuse = [0.0, 0.0, 0.0]
    mj.visual.headlight.specular = [0.0, 0.0, 0.0]
    mj.visual.quality.offsamples = 8
    cam_body = mj.worldbody.add_body(name="cam_link")
    cam = cam_body.add_camera(name="cam")
    cam.quat = list(matrix_to_quat_wxyz(R_SENSOR_MJCAM))
    configure_mujoco_camera(cam, spec)
    backdrop = mj.worldbody.add_geom()  # mid-grey wall behind the board
    backdrop.type = mujoco.mjtGeom.mjGEOM_BOX
    backdrop.size = [0.01, 6.0, 6.0]
    backdrop.pos = [3.0, 0.0, 0.0]
    backdrop.rgba = [0.45, 0.45, 0.45, 1.0]
    board = mj.worldbody.add_body(name="board", mocap=True)
    half_w, half_h = cols * square / 2.0, rows * square / 2.0
    plate = board.add_geom()
    plate.type = mujoco.mjtGeom.mjGEOM_BOX
    plate.size = [half_w + margin, half_h + margin, 0.002]
    plate.pos = [0.0, 0.0, -0.002]
    plate.rgba = [1.0, 1.0, 1.0, 1.0]
    tile_half = 5e-5
    for r in range(rows):
        for c in range(cols):
            if (r + c) % 2:
                continue
            tile = board.add_geom()
            tile.type = mujoco.mjtGeom.mjGEOM_BOX
            tile.size = [square / 2.0, square / 2.0, tile_half]
            tile.pos = [-half_w + (c + 0.5) * square, -half_h + (r + 0.5) * square, tile_half]
            tile.rgba = [0.0, 0.0, 0.0, 1.0]
    return mj.compile()


def _quat_wxyz(rotation: NDArray[np.float64]) -> list[float]:
    return [float(v) for v in matrix_to_quat_wxyz(rotation)]


def _rot(axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    axis = axis / np.linalg.norm(axis)
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) * c + s * k + (1 - c) * np.outer(axis, axis)


def board_poses(count: int, *, seed: int) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """``count`` board poses (position, rotation) in the camera link frame (x forward).

    The board faces the camera (its normal along -x) tilted by 25-45 degrees about a
    random in-plane axis, at 0.4-0.65 m, shifted across the view.
    """
    rng = np.random.default_rng(seed)
    # Board z (its tiled face) towards the camera (-x), board x along -y (image right),
    # board y along +z (image up): columns are the board axes in the link frame.
    facing = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    poses = []
    for k in range(count):
        distance = rng.uniform(0.4, 0.65)
        lateral = rng.uniform(-0.18, 0.18) * distance
        vertical = rng.uniform(-0.1, 0.1) * distance
        axis_angle = rng.uniform(0.0, 2.0 * math.pi)
        axis = np.array([0.0, math.cos(axis_angle), math.sin(axis_angle)])
        tilt = math.radians(rng.uniform(25.0, 45.0)) * (1 if k % 2 else -1)
        spin = math.radians(rng.uniform(-20.0, 20.0))
        rotation = _rot(axis, tilt) @ facing @ _rot(np.array([0.0, 0.0, 1.0]), spin)
        poses.append((np.array([distance, lateral, vertical]), rotation))
    return poses


@contextmanager
def chessboard_renderer(
    pattern: tuple[int, int], square: float
) -> Iterator[tuple[CameraSpec, Any]]:
    """Yield ``(spec, render)`` where ``render(position, rotation)`` returns a BGR image."""
    spec = seed_camera_spec()
    model = _board_model(spec, pattern, square)
    data = mujoco.MjData(model)
    sensor = CameraSensor(model, spec, camera="cam")

    def render(position: NDArray[np.float64], rotation: NDArray[np.float64]) -> NDArray[np.uint8]:
        data.mocap_pos[0] = position
        data.mocap_quat[0] = _quat_wxyz(rotation)
        mujoco.mj_forward(model, data)
        frame = sensor.render(data)
        assert frame.color is not None
        rgb = np.asarray(frame.color)
        return np.ascontiguousarray(rgb[..., ::-1])

    try:
        yield spec, render
    finally:
        sensor.close()


OPENCV_SAMPLES = "/usr/share/doc/opencv-doc/examples/data"
PATTERN = (9, 6)
SQUARE = 0.025


def opencv_sample_files() -> list[str]:
    return sorted(str(p) for p in Path(OPENCV_SAMPLES).glob("left[01][0-9].jpg"))


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "calibrate", *args],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


# ------------------------------------------------------------------ OpenCV's samples


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.skipif(not opencv_sample_files(), reason="opencv-doc (OpenCV's samples) absent")
def test_a_folder_with_an_image_of_another_size(tmp_path: Path) -> None:
    # OpenCV's data folder: left.jpg (612x459, a photo) sorts before left01..left14.jpg
    # (640x480 boards); calibrate skips it with a warning instead of stopping there.
    for name in ["left.jpg", *(Path(f).name for f in opencv_sample_files())]:
        shutil.copy(Path(OPENCV_SAMPLES) / name, tmp_path / name)
    done = run_cli("--images", str(tmp_path), "--pattern", "9x6", "--square", str(SQUARE))
    assert done.returncode == 0, done.stderr
    assert "camera 'camera': 640x480, 13 views" in done.stdout
    assert "left.jpg: chessboard 9x6 not found; image skipped" in done.stderr
    # The same with a board view of another size: named once, skipped, not used.
    small = cv2.resize(cv2.imread(str(tmp_path / "left01.jpg")), (320, 240))
    assert cv2.imwrite(str(tmp_path / "left00_small.jpg"), small)
    done = run_cli("--images", str(tmp_path), "--pattern", "9x6", "--square", str(SQUARE))
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("left00_small.jpg") == 1, done.stderr
    assert "left00_small.jpg: image is 320x240 but 13 views are 640x480" in done.stderr
    assert "camera 'camera': 640x480, 13 views" in done.stdout


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.skipif(not opencv_sample_files(), reason="opencv-doc (OpenCV's samples) absent")
def test_matches_opencv_on_its_own_samples() -> None:
    files = opencv_sample_files()
    objp = np.zeros((PATTERN[0] * PATTERN[1], 3), np.float32)
    objp[:, :2] = np.mgrid[0 : PATTERN[0], 0 : PATTERN[1]].T.reshape(-1, 2) * SQUARE
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
    points = []
    size = (0, 0)
    for f in files:  # OpenCV's calibration tutorial, verbatim in substance
        gray = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
        size = (gray.shape[1], gray.shape[0])
        found, corners = cv2.findChessboardCorners(gray, PATTERN, None)
        if found:
            points.append(cv2.cornerSubPix(gray, corners, (11, 11), (-1, -1), criteria))
    rms_cv, k_cv, _, _, _ = cv2.calibrateCamera(
        [objp] * len(points), points, size, None, None, flags=cv2.CALIB_FIX_K3
    )
    result = calibrate(images=files, pattern="9x6", square=SQUARE)  # k3 fixed by default
    assert len(result.per_image_errors) == len(points) == 13
    assert result.distortion_model == "plumb_bob"
    assert result.D[4] == 0.0
    fx, fx_cv = result.K[0, 0], k_cv[0, 0]
    assert abs(fx / fx_cv - 1.0) <= 0.005, (fx, fx_cv)
    assert abs(result.K[1, 1] / k_cv[1, 1] - 1.0) <= 0.005
    assert result.rms <= 1.05 * rms_cv, (result.rms, rms_cv)
    assert abs(result.K[0, 2] - k_cv[0, 2]) < 2.0  # was 9 px off (333 vs 342)


def test_refine_window_stays_inside_the_squares() -> None:
    assert refine_radius(100.0) == 11  # OpenCV's tutorial window on large boards
    assert refine_radius(24.0) == 10  # 0.4 x spacing on small ones (ROS: 12)
    assert refine_radius(4.0) == 2
    assert refine_radius(100.0, scale=16.0) == 16  # corners found on a 16x smaller copy


# ------------------------------------------------------------------ simulated camera


@pytest.fixture(scope="module")
def sim() -> Iterator[Any]:
    os.environ.setdefault("MUJOCO_GL", "egl")
    with chessboard_renderer(PATTERN, SQUARE) as (spec, render):
        yield spec, render


def write_views(folder: Path, images: list[np.ndarray]) -> Path:
    folder.mkdir()
    for i, image in enumerate(images):
        cv2.imwrite(str(folder / f"view{i:02d}.png"), image)
    return folder


@pytest.mark.slow
@pytest.mark.ci
def test_recovers_the_seed_camera_from_simulated_views(sim: Any, tmp_path: Path) -> None:
    spec, render = sim
    assert math.isclose(SEED_FX, 554.256, abs_tol=0.01)  # 1.0472 ~ pi / 3
    folder = write_views(tmp_path / "views", [render(p, r) for p, r in board_poses(20, seed=1)])
    out = tmp_path / "cam.yaml"
    run = run_cli("--images", str(folder), "--pattern", "9x6", "--square", "0.025", "-o", str(out))
    assert run.returncode == 0, run.stderr
    info = read_camera_info_yaml(out)
    fx, fy, cx, cy = info.k[0], info.k[4], info.k[2], info.k[5]
    assert abs(fx / SEED_FX - 1.0) < 0.003, fx
    assert abs(fy / SEED_FX - 1.0) < 0.003, fy
    assert abs(cx - spec.cx) < 1.0, cx
    assert abs(cy - spec.cy) < 1.0, cy
    assert "20 views" in run.stdout


@pytest.mark.slow
@pytest.mark.ci
def test_identical_views_refused_without_writing_k(sim: Any, tmp_path: Path) -> None:
    _, render = sim
    position, rotation = board_poses(1, seed=5)[0]
    folder = write_views(tmp_path / "same", [render(position, rotation)] * 8)
    out = tmp_path / "cam.yaml"
    run = run_cli("--images", str(folder), "--pattern", "9x6", "-o", str(out))
    assert run.returncode != 0
    assert "only 1 distinct board poses among 8 views" in run.stderr
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.ci
def test_fronto_parallel_views_refused(sim: Any, tmp_path: Path) -> None:
    _, render = sim
    # Board tiles towards the camera (-x), board x along image right, y along image up.
    facing = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    offsets = [(0.5, 0, 0), (0.5, 0.1, 0.05), (0.6, -0.1, 0), (0.45, 0.05, -0.05), (0.7, 0, 0.1)]
    images = [render(np.array(o, dtype=float), facing) for o in offsets]
    folder = write_views(tmp_path / "flat", images)
    run = run_cli("--images", str(folder), "--pattern", "9x6", "-o", str(tmp_path / "c.yaml"))
    assert run.returncode != 0
    assert "nearly parallel to the image plane" in run.stderr
    assert "focal length is undetermined" in run.stderr
    assert not (tmp_path / "c.yaml").exists()


@pytest.mark.slow
@pytest.mark.ci
def test_large_image_searched_downscaled_then_refined_at_full_size(sim: Any) -> None:
    _, render = sim
    gray = cv2.cvtColor(render(*board_poses(1, seed=2)[0]), cv2.COLOR_BGR2GRAY)
    small, _ = find_chessboard(gray, PATTERN)
    big = cv2.resize(gray, None, fx=3.2, fy=3.2, interpolation=cv2.INTER_CUBIC)  # 2048x1536
    large, reason = find_chessboard(big, PATTERN)
    assert small is not None
    assert large is not None, reason
    expected = (small + 0.5) * 3.2 - 0.5
    assert float(np.abs(large - expected).max()) < 1.0


# ------------------------------------------------------------------ image size


def png_header(width: int, height: int) -> bytes:
    """A PNG signature and IHDR chunk claiming ``width`` x ``height`` (no pixel data)."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return (
        b"\x89PNG\r\n\x1a\n"
        + struct.pack(">I", len(ihdr))
        + chunk
        + struct.pack(">I", zlib.crc32(chunk))
    )


def test_oversized_png_refused_from_its_header(tmp_path: Path) -> None:
    path = tmp_path / "huge.png"
    path.write_bytes(png_header(20000, 20000))
    with pytest.raises(CalibrationError, match=r"huge.png: image is 20000x20000 px \(400 MP\)"):
        read_gray_image(path)
    run = run_cli("--images", str(tmp_path), "--pattern", "9x6")
    assert run.returncode != 0
    assert "20000x20000" in run.stderr
    assert "64 MP" in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1


def test_oversized_array_refused() -> None:
    with pytest.raises(CalibrationError, match=f"larger than the {MAX_IMAGE_PIXELS // 10**6} MP"):
        find_chessboard(np.zeros((1, MAX_IMAGE_PIXELS + 1), np.uint8), PATTERN)


@pytest.mark.parametrize("ext", [".png", ".jpg", ".bmp", ".pgm"])
def test_header_size_matches_the_decoded_image(tmp_path: Path, ext: str) -> None:
    path = tmp_path / f"img{ext}"
    cv2.imwrite(str(path), np.full((37, 53), 128, np.uint8))
    assert header_size(path) == (53, 37)
    assert read_gray_image(path).shape == (37, 53)


def test_tiny_images_give_a_clear_error(tmp_path: Path) -> None:
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"t{i}.png"), np.zeros((1, 1), np.uint8))
    run = run_cli("--images", str(tmp_path), "--pattern", "9x6")
    assert run.returncode != 0
    last = run.stderr.strip().splitlines()[-1]
    assert "only 0 of 3 images" in last
    assert "3 rejected: the image is 1x1 px, too small to show a 9x6 chessboard" in last


@settings(max_examples=200, deadline=None)
@given(
    data=st.binary(max_size=200),
    prefix=st.sampled_from([b"", b"\x89PNG\r\n\x1a\n", b"\xff\xd8", b"BM", b"P5\n"]),
)
def test_fuzz_image_header_only_calibration_errors(
    tmp_path_factory: pytest.TempPathFactory, data: bytes, prefix: bytes
) -> None:
    path = tmp_path_factory.mktemp("fuzz") / "x.img"
    path.write_bytes(prefix + data)
    size = header_size(path)
    assert size is None or (isinstance(size[0], int) and isinstance(size[1], int))
    with suppress(CalibrationError):
        read_gray_image(path)
