"""Input checks: camera_info, depth units, TUM folders and their association."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.msgs import CameraInfo, make
from visnav.slam import AssociationError, SlamInputError, TumSequence, associate_stamps
from visnav.slam.camera import CameraIntrinsics, check_depth_scale, depth_to_metres
from visnav.slam.synthetic import (
    SyntheticRoom,
    camera_info_for,
    circle_trajectory,
    write_tum_folder,
)

from .conftest import SMALL


def _info(**fields: object) -> CameraInfo:
    info = camera_info_for(SMALL)
    assert isinstance(info, CameraInfo)
    for k, v in fields.items():
        setattr(info, k, v)
    return info


def test_intrinsics_from_camera_info_use_the_rectified_projection() -> None:
    info = _info(
        d=np.array([0.1, 0.0, 0.0, 0.0, 0.0]),
        p=np.array([120.0, 0, 80.0, 0, 0, 121.0, 60.0, 0, 0, 0, 1, 0]),
    )
    cam, warnings = CameraIntrinsics.from_camera_info(info, source="/cam/camera_info")
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (120.0, 121.0, 80.0, 60.0)
    assert (cam.width, cam.height) == (160, 120)
    assert any("rectified" in w and "/cam/camera_info" in w for w in warnings)


def test_uncalibrated_camera_info_is_refused() -> None:
    info = make(CameraInfo, width=160, height=120)  # K and P all zero
    with pytest.raises(SlamInputError, match="/cam/camera_info"):
        CameraIntrinsics.from_camera_info(info, source="/cam/camera_info")
    with pytest.raises(SlamInputError, match="focal lengths"):
        CameraIntrinsics(0.0, 100.0, 80.0, 60.0, 160, 120)
    with pytest.raises(SlamInputError, match="image size"):
        CameraIntrinsics(100.0, 100.0, 80.0, 60.0, 0, 120)


def test_depth_conversion() -> None:
    mm = np.array([[0, 1500], [65535, 20]], dtype=np.uint16)
    m = depth_to_metres(mm)
    assert np.isnan(m[0, 0])
    assert m[0, 1] == pytest.approx(1.5)
    tum = depth_to_metres(mm, depth_scale=5000.0)
    assert tum[0, 1] == pytest.approx(0.3)
    f = depth_to_metres(np.array([[np.inf, -1.0], [2.0, np.nan]], dtype=np.float32))
    assert np.isnan(f[0, 0])
    assert np.isnan(f[0, 1])
    assert f[1, 0] == 2.0
    with pytest.raises(SlamInputError, match="dtype"):
        depth_to_metres(np.zeros((2, 2), dtype=np.int32))
    with pytest.raises(SlamInputError, match="one channel"):
        depth_to_metres(np.zeros((2, 2, 3), dtype=np.float32))
    with pytest.raises(SlamInputError, match="depth_scale"):
        depth_to_metres(mm, depth_scale=0.0)


def test_depth_scale_check() -> None:
    ok = np.full((10, 10), 2.5, dtype=np.float32)
    assert check_depth_scale(ok, source="d") == []
    with pytest.raises(SlamInputError, match=r"1000x .*2\.5 m"):
        check_depth_scale(ok * 1000, source="d")
    with pytest.raises(SlamInputError, match=r"0\.001x"):
        check_depth_scale(ok / 1000, source="d")
    sparse = np.full((10, 10), np.nan, dtype=np.float32)
    assert any("valid" in w for w in check_depth_scale(sparse, source="d"))


def _brute_force_associate(
    a: list[float], b: list[float], max_difference: float
) -> list[tuple[int, int]]:
    """TUM's associate.py, literally (quadratic)."""
    cands = sorted(
        (abs(x - y), i, j)
        for i, x in enumerate(a)
        for j, y in enumerate(b)
        if abs(x - y) < max_difference
    )
    ua: set[int] = set()
    ub: set[int] = set()
    out = []
    for _, i, j in cands:
        if i not in ua and j not in ub:
            ua.add(i)
            ub.add(j)
            out.append((i, j))
    return sorted(out)


@settings(max_examples=60, deadline=None)
@given(
    a=st.lists(st.integers(0, 400), min_size=0, max_size=30, unique=True),
    b=st.lists(st.integers(0, 400), min_size=0, max_size=30, unique=True),
)
def test_associate_stamps_matches_tum_associate(a: list[int], b: list[int]) -> None:
    fa = [x * 0.01 + 0.001 for x in sorted(a)]
    fb = [x * 0.01 for x in sorted(b)]
    got = associate_stamps(np.array(fa), np.array(fb), max_difference=0.025)
    assert got == _brute_force_associate(fa, fb, 0.025)


@pytest.fixture(scope="module")
def tum_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("tum") / "seq"
    poses = circle_trajectory(30, turns=30 / 130)
    return write_tum_folder(folder, SyntheticRoom(seed=1), SMALL, poses, depth_offset_s=0.004)


def test_tum_sequence_reads_and_associates(tum_folder: Path) -> None:
    seq = TumSequence(tum_folder)
    assert len(seq) == 30
    assert seq.groundtruth_path is not None
    cam = seq.find_intrinsics()
    assert cam is not None
    assert (cam.fx, cam.width) == (125.0, 160)
    frame, rgb, depth = next(seq.images())
    assert rgb.shape == (120, 160, 3)
    assert depth.dtype == np.uint16
    assert frame.depth_stamp - frame.stamp == pytest.approx(0.004, abs=1e-6)


def test_empty_tum_folder(tmp_path: Path) -> None:
    with pytest.raises(SlamInputError, match="does not exist"):
        TumSequence(tmp_path / "nope")
    with pytest.raises(SlamInputError, match=r"rgb\.txt"):
        TumSequence(tmp_path)
    (tmp_path / "rgb.txt").write_text("# color images\n")
    (tmp_path / "depth.txt").write_text("# depth\n1.0 depth/1.png\n")
    with pytest.raises(SlamInputError, match="empty sequence"):
        TumSequence(tmp_path)


def test_tum_stamps_that_do_not_associate(tmp_path: Path) -> None:
    (tmp_path / "rgb.txt").write_text("1.00 rgb/1.png\n1.03 rgb/2.png\n")
    (tmp_path / "depth.txt").write_text("5.00 depth/1.png\n5.03 depth/2.png\n")
    with pytest.raises(AssociationError, match="do not associate"):
        TumSequence(tmp_path)
    (tmp_path / "depth.txt").write_text("1.005 depth/1.png\n")
    seq = TumSequence(tmp_path)
    assert len(seq) == 1


def test_tum_malformed_list(tmp_path: Path) -> None:
    (tmp_path / "rgb.txt").write_text("abc rgb/1.png\n")
    (tmp_path / "depth.txt").write_text("1.0 depth/1.png\n")
    with pytest.raises(SlamInputError, match=r"rgb\.txt:1"):
        TumSequence(tmp_path)
