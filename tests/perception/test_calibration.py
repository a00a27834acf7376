"""Chessboard calibration on synthetic views with a known camera, and the ROS YAML format.

The views are rendered exactly: for every pixel of the distorted image the ray is
undistorted with the true K/D and intersected with the board plane, and the
board texture is sampled there.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from visnav.msgs import CameraInfo, Header, Image, Time
from visnav.msgs.image import numpy_to_image
from visnav.perception.calibration import (
    CalibrationError,
    calibrate,
    calibrate_from_images,
    find_chessboard,
    load_calibration_yaml,
    parse_pattern,
    read_camera_info_yaml,
    resolve_camera_info_url,
    select_views,
    write_camera_info_yaml,
)
from visnav.perception.camera_info_yaml import camera_info_from_matrices
from visnav.perception.image_transport import compress

SIZE = (480, 360)  # width, height
K_TRUE = np.array([[400.0, 0.0, 236.0], [0.0, 405.0, 178.0], [0.0, 0.0, 1.0]])
D_TRUE = np.array([-0.18, 0.04, 0.0008, -0.0005, 0.0])
PATTERN = (9, 6)
SQUARE = 0.025


def undistort_normalized(
    u: np.ndarray, v: np.ndarray, k: np.ndarray, d: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pixel -> undistorted normalized coordinates (plumb_bob), by fixed-point iteration."""
    x0, y0 = (u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1]
    k1, k2, p1, p2, k3 = d
    x, y = x0.copy(), y0.copy()
    for _ in range(40):
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        x, y = (x0 - dx) / radial, (y0 - dy) / radial
    return x, y


def _ramp(q: np.ndarray, count: int, px_per_unit: np.ndarray) -> np.ndarray:
    """+-1 checker sign along one axis, a 1-pixel linear ramp across each inner line."""
    n = np.clip(np.rint(q), 0, count - 1)
    sign = np.where(n % 2 == 0, 1.0, -1.0)
    return np.clip(2.0 * (q - n) * px_per_unit, -1.0, 1.0) * sign


def render_view(
    rvec: np.ndarray,
    center: np.ndarray,
    *,
    k: np.ndarray = K_TRUE,
    d: np.ndarray = D_TRUE,
    pattern: tuple[int, int] = PATTERN,
    square: float = SQUARE,
    size: tuple[int, int] = SIZE,
) -> np.ndarray:
    """Render a chessboard whose centre is at ``center`` (camera frame, m), rotated by rvec.

    Every pixel is traced to the board plane through the true K/D; the checker is
    drawn analytically with edges anti-aliased over one pixel, and a white margin
    of one square surrounds the (cols + 1) x (rows + 1) squares.
    """
    cols, rows = pattern
    rot, _ = cv2.Rodrigues(np.asarray(rvec, np.float64))
    board_center = np.array([(cols - 1) / 2 * square, (rows - 1) / 2 * square, 0.0])
    t = np.asarray(center, np.float64) - rot @ board_center
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    x, y = undistort_normalized(u, v, k, d)
    homog = np.column_stack([rot[:, 0], rot[:, 1], t])  # board (x, y, 1) -> camera ray
    board = np.linalg.solve(homog, np.stack([x.ravel(), y.ravel(), np.ones(x.size)]))
    qx = (board[0] / board[2]).reshape(h, w) / square  # board coordinates in squares
    qy = (board[1] / board[2]).reshape(h, w) / square
    # Pixels per square along each board axis (from the local Jacobian).
    px_x = 1.0 / np.hypot(*np.gradient(qx))
    px_y = 1.0 / np.hypot(*np.gradient(qy))
    value = _ramp(qx, cols, px_x) * _ramp(qy, rows, px_y)  # +1 white, -1 dark
    dist_x = np.minimum(qx + 1, cols - qx) * px_x  # pixels inside the checker area
    dist_y = np.minimum(qy + 1, rows - qy) * px_y
    inside = np.clip(dist_x + 0.5, 0, 1) * np.clip(dist_y + 0.5, 0, 1)
    value = inside * value + (1 - inside)
    return np.rint(127.5 + 107.5 * value).astype(np.uint8)


POSES = [  # (rotation vector, board centre in the camera frame in m): tilted up to ~37 deg
    ((0.0, 0.0, 0.0), (0.0, 0.0, 0.45)),
    ((0.6, 0.0, 0.0), (-0.02, 0.02, 0.5)),
    ((-0.6, 0.0, 0.05), (0.02, -0.02, 0.5)),
    ((0.0, 0.65, 0.0), (0.03, 0.0, 0.5)),
    ((0.0, -0.65, -0.05), (-0.03, 0.0, 0.5)),
    ((0.45, 0.45, 0.1), (0.12, 0.08, 0.7)),
    ((-0.45, -0.45, -0.1), (-0.12, -0.08, 0.7)),
    ((0.4, -0.45, 0.2), (0.12, -0.08, 0.7)),
    ((-0.4, 0.45, -0.2), (-0.12, 0.08, 0.7)),
    ((0.1, 0.1, 0.5), (0.0, 0.0, 0.9)),
    ((0.3, -0.2, -0.3), (0.1, 0.1, 0.6)),
    ((-0.25, 0.35, 0.3), (-0.1, -0.1, 0.6)),
]


@functools.cache
def views() -> tuple[np.ndarray, ...]:
    return tuple(render_view(np.array(r), np.array(c)) for r, c in POSES)


@pytest.fixture
def image_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "calib"
    folder.mkdir()
    for i, img in enumerate(views()):
        assert cv2.imwrite(str(folder / f"view_{i:02d}.png"), img)
    return folder


def test_rendered_corners_match_projection() -> None:
    """The renderer is exact: detected corners sit where cv2.projectPoints puts them."""
    rvec, center = np.array(POSES[5][0]), np.array(POSES[5][1])
    corners, reason = find_chessboard(render_view(rvec, center), PATTERN)
    assert corners is not None, reason
    rot, _ = cv2.Rodrigues(rvec)
    board_center = np.array([4 * SQUARE, 2.5 * SQUARE, 0.0])
    grid = np.zeros((54, 3))
    grid[:, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2) * SQUARE
    projected, _ = cv2.projectPoints(grid, rvec, center - rot @ board_center, K_TRUE, D_TRUE)
    projected = projected.reshape(-1, 2)
    # Detection may start from the opposite corner (the board is symmetric under 180 deg).
    if np.abs(corners - projected).max() > np.abs(corners[::-1] - projected).max():
        corners = corners[::-1]
    dist = np.linalg.norm(corners - projected, axis=1)
    assert dist.max() < 0.15
    assert np.sqrt(np.mean(dist**2)) < 0.08


def test_calibrate_directory_recovers_camera_and_writes_yaml(
    image_dir: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out" / "camera.yaml"
    result = calibrate(
        images=image_dir, pattern="9x6", square=SQUARE, output=out, camera_name="test_cam"
    )
    k = result.K
    assert abs(k[0, 0] - 400.0) / 400.0 < 0.005
    assert abs(k[1, 1] - 405.0) / 405.0 < 0.005
    assert abs(k[0, 2] - 236.0) < 1.0
    assert abs(k[1, 2] - 178.0) < 1.0
    assert abs(result.D[0] - D_TRUE[0]) < 0.02
    assert result.D[4] == 0.0  # k3 fixed, as ROS's default --k-coefficients 2
    assert result.rms < 0.2
    assert len(result.per_image_errors) == len(POSES)
    assert all(err < 0.3 for _, err in result.per_image_errors)
    assert result.image_size == SIZE
    np.testing.assert_array_equal(result.R, np.eye(3))
    assert result.P[:, 3].tolist() == [0.0, 0.0, 0.0]
    assert "RMS reprojection error" in result.summary()
    assert "view_03.png" in result.summary()
    # The YAML reads back to the same numbers.
    name, info = load_calibration_yaml(out)
    assert name == "test_cam"
    assert (info.width, info.height) == SIZE
    np.testing.assert_array_equal(info.k, result.K.ravel())
    np.testing.assert_array_equal(info.d, result.D)
    np.testing.assert_array_equal(info.p, result.P.ravel())


def test_arrays_and_image_messages_as_input() -> None:
    frames = [numpy_to_image(v, "mono8") for v in views()[:6]]
    frames_bgr = [("bgr", cv2.cvtColor(v, cv2.COLOR_GRAY2BGR)) for v in views()[6:]]
    result = calibrate_from_images([*frames, *frames_bgr], PATTERN, SQUARE)
    assert abs(result.K[0, 0] - 400.0) / 400.0 < 0.01


def test_rational_polynomial_and_fixed_principal_point() -> None:
    result = calibrate_from_images(
        list(views()), PATTERN, SQUARE, distortion_model="rational_polynomial", k_coefficients=3
    )
    assert result.distortion_model == "rational_polynomial"
    assert result.D.shape == (8,)
    assert result.D[5:].tolist() == [0.0, 0.0, 0.0]
    fixed = calibrate_from_images(list(views()), PATTERN, SQUARE, fix_principal_point=True)
    assert fixed.K[0, 2] == pytest.approx((SIZE[0] - 1) / 2, abs=0.51)
    assert fixed.K[1, 2] == pytest.approx((SIZE[1] - 1) / 2, abs=0.51)


def test_board_not_found_warns_and_too_few_views(caplog: pytest.LogCaptureFixture) -> None:
    blank = np.full(SIZE[::-1], 128, np.uint8)
    images: list[Any] = [("blank.png", blank), *[(f"v{i}", v) for i, v in enumerate(views()[:4])]]
    with caplog.at_level(logging.WARNING), pytest.raises(CalibrationError) as info:
        calibrate_from_images(images, PATTERN, SQUARE)
    assert "blank.png: chessboard 9x6 not found; image skipped" in caplog.text
    assert (
        "only 4 of 5 images show the full 9x6 chessboard (1 rejected: chessboard 9x6 not "
        "found): at least 5 views" in str(info.value)
    )


def test_wrong_pattern_finds_nothing() -> None:
    with pytest.raises(CalibrationError, match="only 0 of 3 images"):
        calibrate_from_images(list(views()[:3]), "8x6", SQUARE, min_views=3)


def test_board_cut_off_by_the_border_is_rejected() -> None:
    img = render_view(np.zeros(3), np.array([0.28, 0.0, 0.55]))  # right edge off-image
    corners, reason = find_chessboard(img, PATTERN)
    assert corners is None
    assert reason in (
        "chessboard 9x6 not found",
        "chessboard touches the image border (partly outside the view)",
    )


def test_unreadable_and_missing_files(tmp_path: Path) -> None:
    bad = tmp_path / "broken.png"
    bad.write_text("not an image")
    with pytest.raises(CalibrationError, match=r"broken\.png: cannot read it as an image"):
        calibrate_from_images([bad], PATTERN, SQUARE)
    with pytest.raises(CalibrationError, match=r"nope\.png: no such image file"):
        calibrate_from_images([tmp_path / "nope.png"], PATTERN, SQUARE)
    with pytest.raises(CalibrationError, match="not a directory of calibration images"):
        calibrate(images=tmp_path / "missing_dir", pattern=PATTERN)
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("x")
    with pytest.raises(CalibrationError, match=r"empty: no image files \(\.png"):
        calibrate(images=tmp_path / "empty", pattern=PATTERN)


def test_an_image_of_another_size_is_skipped_with_a_warning(
    image_dir: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # A stray board view of another size sorts first (as OpenCV's data folder's left.jpg
    # before left01.jpg): the size most views have is calibrated, the stray one skipped.
    stray = cv2.resize(views()[3], (600, 450), interpolation=cv2.INTER_LINEAR)
    assert cv2.imwrite(str(image_dir / "a_stray.png"), stray)
    assert cv2.imwrite(str(image_dir / "b_blank.png"), np.full((100, 100), 128, np.uint8))
    with caplog.at_level(logging.WARNING):
        result = calibrate(images=image_dir, pattern=PATTERN, square=SQUARE)
    skipped = [r.getMessage() for r in caplog.records if "a_stray.png" in r.getMessage()]
    assert skipped == [
        "a_stray.png: image is 600x450 but 12 views are 480x360: one calibration is of one "
        "camera mode; image skipped"
    ]
    assert result.image_size == SIZE
    assert len(result.per_image_errors) == len(POSES)
    assert [name for name, _ in result.rejected] == ["b_blank.png", "a_stray.png"]
    alone = calibrate(images=[image_dir / f"view_{i:02d}.png" for i in range(len(POSES))],
                      pattern=PATTERN, square=SQUARE)  # fmt: skip
    np.testing.assert_allclose(result.K, alone.K, rtol=1e-8)  # OpenCV threads: not bitwise


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"pattern": "9by6"}, "pattern is '9by6'"),
        ({"pattern": (1, 6)}, "both >= 2"),
        ({"square": 0}, "square is 0"),
        ({"distortion_model": "equidistant"}, "distortion_model is 'equidistant'"),
        ({"k_coefficients": 4}, "plumb_bob estimates 0 to 3"),
        ({"alpha": 2.0}, "alpha is 2.0"),
    ],
)
def test_bad_parameters(kwargs: dict[str, Any], match: str) -> None:
    args: dict[str, Any] = {"pattern": PATTERN, "square": SQUARE, **kwargs}
    with pytest.raises(CalibrationError, match=match):
        calibrate_from_images([views()[0]], **args)


def test_parse_pattern() -> None:
    assert parse_pattern("9x6") == (9, 6)
    assert parse_pattern(" 8 X 5 ") == (8, 5)
    assert parse_pattern([7, 4]) == (7, 4)


def test_calibrate_needs_exactly_one_source(image_dir: Path) -> None:
    with pytest.raises(CalibrationError, match="exactly one image source"):
        calibrate()
    with pytest.raises(CalibrationError, match="exactly one image source"):
        calibrate(images=image_dir, bag="x.bag", topic="t")
    with pytest.raises(CalibrationError, match="needs node= and spin_until="):
        calibrate(topic="camera/image_raw")


# ------------------------------------------------------------ bag and topic


def test_calibrate_from_bag_selects_distinct_views(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Writer

    from visnav.msgs.serde import typestore

    store = typestore()
    bag = tmp_path / "calib_bag"
    frames = [v for v in views() for _ in range(3)]  # every pose three times
    with Writer(bag, version=9) as writer:
        raw = writer.add_connection("/cam/image_raw", "sensor_msgs/msg/Image", typestore=store)
        comp = writer.add_connection(
            "/cam/image_raw/compressed", "sensor_msgs/msg/CompressedImage", typestore=store
        )
        for i, frame in enumerate(frames):
            header = Header(stamp=Time(sec=i, nanosec=0), frame_id="cam")
            img = numpy_to_image(cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR), "bgr8", header=header)
            writer.write(raw, i * 10**9, store.serialize_cdr(img, "sensor_msgs/msg/Image"))
            msg = compress(img, format="png")
            writer.write(
                comp, i * 10**9, store.serialize_cdr(msg, "sensor_msgs/msg/CompressedImage")
            )
    result = calibrate(bag=bag, topic="/cam/image_raw", pattern=PATTERN, square=SQUARE)
    used = [int(float(name.split("@")[1].split()[0])) for name, _ in result.per_image_errors]
    assert used[0] == 0
    poses = [i // 3 for i in used]
    assert len(set(poses)) == len(poses) >= 8  # repeated frames (and near-repeats) thinned out
    assert abs(result.K[0, 0] - 400.0) / 400.0 < 0.01
    compressed = calibrate(bag=bag, topic="/cam/image_raw/compressed", pattern=PATTERN, max_views=8)
    assert len(compressed.per_image_errors) == 8
    with pytest.raises(CalibrationError, match="no Image/CompressedImage topic '/other'"):
        calibrate(bag=bag, topic="/other", pattern=PATTERN)


def test_calibrate_from_bag_missing(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError, match="cannot open the bag"):
        calibrate(bag=tmp_path / "missing_bag", topic="/cam/image_raw")


def test_select_views_thins_duplicates() -> None:
    frames = [(f"f{i}", v) for i, v in enumerate([views()[0]] * 5 + [views()[3]])]
    kept = select_views(frames, PATTERN)
    assert [name for name, _ in kept] == ["f0", "f5"]


class FakeNode:
    def __init__(self) -> None:
        self.subs: dict[str, Callable[[Any], None]] = {}
        self.destroyed: list[Any] = []

    def create_subscription(
        self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: Any
    ) -> str:
        self.subs[topic] = callback
        return topic

    def destroy_subscription(self, sub: Any) -> None:
        self.destroyed.append(sub)


def test_calibrate_from_live_topic() -> None:
    node = FakeNode()
    delivered = []

    def spin_until(predicate: Callable[[], bool], timeout_s: float) -> bool:
        callback = node.subs["cam/image_raw/compressed"]
        for i, frame in enumerate(views()):
            if predicate():
                return True
            img = numpy_to_image(
                frame, "mono8", header=Header(stamp=Time(sec=i, nanosec=5), frame_id="c")
            )
            callback(compress(img, format="png"))
            delivered.append(i)
        return predicate()

    result = calibrate(
        topic="cam/image_raw/compressed",
        node=node,
        spin_until=spin_until,
        pattern=PATTERN,
        max_views=6,
    )
    assert len(result.per_image_errors) == 6
    assert len(delivered) < len(POSES)  # stopped once max_views were collected
    assert result.per_image_errors[0][0] == "cam/image_raw/compressed@0.000000005"
    assert node.destroyed == ["cam/image_raw/compressed"]


# --------------------------------------------------------------------- YAML

ROS_SAMPLE = """\
image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [ 612.3456,    0.     ,  318.9021,
            0.     ,  611.8765,  241.2468,
            0.     ,    0.     ,    1.     ]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.101203, -0.223344, 0.000812, -0.001107, 0.000000]
rectification_matrix:
  rows: 3
  cols: 3
  data: [ 1.,  0.,  0.,
          0.,  1.,  0.,
          0.,  0.,  1.]
projection_matrix:
  rows: 3
  cols: 4
  data: [ 620.1111,    0.     ,  319.5555,    0.     ,
            0.     ,  622.2222,  240.7777,    0.     ,
            0.     ,    0.     ,    1.     ,    0.     ]
"""


def test_reads_ros_written_yaml(tmp_path: Path) -> None:
    path = tmp_path / "ost.yaml"
    path.write_text(ROS_SAMPLE)
    name, info = load_calibration_yaml(path)
    assert name == "narrow_stereo"
    assert (info.width, info.height, info.distortion_model) == (640, 480, "plumb_bob")
    assert info.k.tolist() == [612.3456, 0, 318.9021, 0, 611.8765, 241.2468, 0, 0, 1]
    assert info.d.tolist() == [0.101203, -0.223344, 0.000812, -0.001107, 0.0]
    assert info.r.tolist() == np.eye(3).ravel().tolist()
    assert info.p[[0, 2, 5, 6, 10]].tolist() == [620.1111, 319.5555, 622.2222, 240.7777, 1.0]
    assert (info.binning_x, info.binning_y, info.roi.width) == (0, 0, 0)
    assert isinstance(read_camera_info_yaml(f"file://{path}"), CameraInfo)


def test_yaml_round_trip_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    info = camera_info_from_matrices(
        (1280, 720),
        "rational_polynomial",
        rng.normal(size=8) * 0.1,
        [[901.123456789, 0, 640.5], [0, 899.987654321, 360.25], [0, 0, 1]],
        np.eye(3),
        [[905.0, 0, 641.0, 0], [0, 905.0, 361.0, 0], [0, 0, 1, 0]],
    )
    path = write_camera_info_yaml(tmp_path / "a" / "b.yaml", info, camera_name="front camera: 1")
    text = path.read_text()
    assert text.startswith("image_width: 1280\nimage_height: 720\n")
    assert "distortion_coefficients:\n  rows: 1\n  cols: 8\n  data: [" in text
    name, back = load_calibration_yaml(path)
    assert name == "front camera: 1"
    assert back.distortion_model == "rational_polynomial"
    for field in ("d", "k", "r", "p"):
        np.testing.assert_array_equal(getattr(back, field), getattr(info, field))  # bit exact


def test_yaml_defaults_like_ros(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    text = ROS_SAMPLE.replace("camera_name: narrow_stereo\n", "").replace(
        "distortion_model: plumb_bob\n", ""
    )
    path = tmp_path / "old.yaml"
    path.write_text(text)
    with caplog.at_level(logging.WARNING):
        name, info = load_calibration_yaml(path)
    assert name == "unknown"
    assert info.distortion_model == "plumb_bob"
    assert "no distortion_model; assuming plumb_bob" in caplog.text


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (
            lambda t: t.replace("projection_matrix:", "projection_matrixx:"),
            "missing field 'projection_matrix'",
        ),
        (lambda t: t.replace("image_width: 640\n", ""), "missing field 'image_width'"),
        (
            lambda t: t.replace("rows: 3\n  cols: 4", "rows: 4\n  cols: 3"),
            "projection_matrix is 4x3: expected 3x4",
        ),
        (
            lambda t: t.replace("0.000000]", "0.000000, 0.5]"),
            r"distortion_coefficients\.data has 6 values",
        ),
        (lambda t: t.replace("image_height: 480", "image_height: tall"), "image_height is 'tall'"),
        (lambda t: t.replace("data: [0.101203", "data: [abc"), "holds a non-number"),
        (lambda t: "just a string", "expected a YAML mapping"),
        (lambda t: "a: [", "does not parse as YAML"),
    ],
)
def test_yaml_errors_name_file_and_field(
    tmp_path: Path, edit: Callable[[str], str], match: str
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(edit(ROS_SAMPLE))
    with pytest.raises(CalibrationError, match=match) as info:
        read_camera_info_yaml(path)
    assert str(path) in str(info.value)


def test_unreadable_yaml(tmp_path: Path) -> None:
    with pytest.raises(CalibrationError, match="the camera_info YAML does not exist"):
        read_camera_info_yaml(tmp_path / "missing.yaml")
    with pytest.raises(CalibrationError, match="INI calibration files are not supported"):
        read_camera_info_yaml(tmp_path / "cal.ini")


def test_resolve_camera_info_url(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("ROS_HOME", str(tmp_path))
    assert resolve_camera_info_url("file:///etc/cam.yaml") == Path("/etc/cam.yaml")
    assert resolve_camera_info_url("calib/cam.yaml") == Path("calib/cam.yaml")
    assert resolve_camera_info_url("", camera_name="left") == tmp_path / "camera_info" / "left.yaml"
    assert (
        resolve_camera_info_url("file://${ROS_HOME}/${NAME}.yaml", camera_name="c")
        == tmp_path / "c.yaml"
    )
    with pytest.raises(CalibrationError, match="package:// URLs need a ROS package index"):
        resolve_camera_info_url("package://my_pkg/calib.yaml")
    with pytest.raises(CalibrationError, match="unsupported scheme"):
        resolve_camera_info_url("http://host/cam.yaml")
    with pytest.raises(CalibrationError, match="pass camera_name"):
        resolve_camera_info_url("file:///x/${NAME}.yaml")


def test_calibrate_from_a_topic_on_the_graph() -> None:
    from visnav.graph import Context, Node

    with Context(transport="local") as ctx:
        camera = Node("camera", context=ctx)
        pub = camera.create_publisher(Image, "cam/image_raw", 5)
        frames = iter(views())

        def tick() -> None:
            frame = next(frames, None)
            if frame is not None:
                pub.publish(numpy_to_image(frame, "mono8"))

        camera.create_timer(0.005, tick)
        calibrator = Node("calibrator", context=ctx)
        result = calibrate(
            topic="cam/image_raw",
            node=calibrator,
            spin_until=ctx.spin_until,
            pattern=PATTERN,
            square=SQUARE,
            max_views=8,
            timeout_s=10.0,
        )
    assert len(result.per_image_errors) == 8
    assert abs(result.K[0, 0] - 400.0) / 400.0 < 0.01


def test_cli_calibrate_directory(image_dir: Path, tmp_path: Path) -> None:
    import subprocess
    import sys

    out_yaml = tmp_path / "cam.yaml"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "visnav.cli.main",
            "calibrate",
            "--images",
            str(image_dir),
            "--pattern",
            "9x6",
            "--square",
            "0.025",
            "-o",
            str(out_yaml),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert "RMS" in run.stdout or "rms" in run.stdout
    assert out_yaml.exists()
    missing = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "calibrate", "--pattern", "9x6"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert missing.returncode == 1
    assert missing.stderr.startswith("error: visnav calibrate needs a source")
