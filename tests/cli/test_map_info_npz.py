"""``visnav map info FILE.npz``: a saved SLAM map described; a bad one is one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from visnav.cli.main import main
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.features import Frame
from visnav.slam.map_file import save_slam_map
from visnav.slam.slam_map import SlamMap

CAMERA = CameraIntrinsics(125.0, 125.0, 79.5, 59.5, 160, 120)


def _saved(path: Path) -> Path:
    """Two keyframes 1.5 s and 2 m apart sharing three points; one culled point."""
    rng = np.random.default_rng(2)
    m = SlamMap()
    for k in range(2):
        n = 5
        uv = rng.uniform(0, 100, (n, 2))
        frame = Frame(
            stamp_ns=10_000_000_000 + k * 1_500_000_000,
            uv=uv,
            octave=np.zeros(n, dtype=np.int64),
            descriptors=rng.integers(0, 256, (n, 32), dtype=np.uint8),
            depth=np.full(n, 2.0),
            u_right=uv[:, 0] - 5.0,
            points_c=np.c_[uv, np.full(n, 2.0)],
            inv_sigma2=np.ones(n),
        )
        t_cw = np.eye(4)
        t_cw[:3, 3] = [-2.0 * k, 0.0, 0.0]  # the camera centre at x = 2 k
        kf = m.add_keyframe(frame, t_cw, parent=k - 1)
        if k == 0:
            m.add_points(rng.normal(size=(4, 3)), frame.descriptors[:4], kf, np.arange(4))
        else:
            for p in range(3):
                m.add_observation(p, kf, p)
    m.cull_point(3)
    return save_slam_map(m, path, camera=CAMERA)


def test_map_info_of_a_slam_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _saved(tmp_path / "slam_map.npz")
    assert main(["map", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"SLAM map:     {path} (format version 1)" in out
    assert "keyframes:    2 (of 2 with culled ones), 0 with an odometry pose" in out
    assert "map points:   3 (3 seen by >= 2 keyframes: the PLY), 6 observations" in out
    assert "time span:    10.000 .. 11.500 s (1.500 s)" in out
    assert "x 0.000 .. 2.000" in out
    assert "2.000 m between keyframes" in out
    assert "camera:       160 x 120, fx 125 fy 125 cx 79.5 cy 59.5" in out


def test_map_info_of_a_broken_slam_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _saved(tmp_path / "slam_map.npz")
    path.write_bytes(path.read_bytes()[:200])
    assert main(["map", "info", str(path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {path}: not a readable .npz")
    assert "\n" not in err
