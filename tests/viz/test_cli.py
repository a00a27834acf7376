"""``visnav image view --snapshot`` and ``visnav view`` against a camera process / a bag."""

from __future__ import annotations

import logging
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from visnav.cli.main import main
from visnav.msgs import numpy_to_image, xyz_to_cloud

SCRIPTS = Path(__file__).parent / "scripts"


@pytest.fixture
def camera(start_script: Callable[..., subprocess.Popen[str]]) -> subprocess.Popen[str]:
    return start_script(SCRIPTS / "camera_pub.py", "60")


def _cli(capsys: Any, *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``visnav ARGS`` in this process (the domain fixture set VISNAV_DOMAIN)."""
    code = main(list(args))
    out = capsys.readouterr()
    return subprocess.CompletedProcess(list(args), code, out.out, out.err)


def test_image_snapshot_raw_compressed_and_depth(
    camera: subprocess.Popen[str], tmp_path: Path, capsys: Any
) -> None:
    raw, comp, depth = tmp_path / "raw.png", tmp_path / "comp.png", tmp_path / "depth.png"
    r = _cli(capsys, "image", "view", "/cam/image_raw", "--snapshot", str(raw))
    assert r.returncode == 0, r.stderr
    assert "64x48, rgb8" in r.stdout
    bgr = cv2.imread(str(raw))
    assert bgr is not None
    assert bgr.shape == (48, 64, 3)
    assert tuple(bgr[10, 5]) == (0, 0, 255)  # red on the left (BGR on disk)
    assert tuple(bgr[10, 60]) == (255, 0, 0)  # blue on the right
    r = _cli(capsys, "image", "view", "/cam/image_raw/compressed", "--snapshot", str(comp))
    assert r.returncode == 0, r.stderr
    assert "png compressed" in r.stdout
    assert np.array_equal(cv2.imread(str(comp)), bgr)  # PNG is lossless
    r = _cli(capsys, "image", "view", "/depth/image_raw", "--snapshot", str(depth))
    assert r.returncode == 0, r.stderr
    gray = cv2.imread(str(depth), cv2.IMREAD_GRAYSCALE)
    assert gray is not None
    assert gray[0, 0] == 0
    assert gray[0, -1] == 255  # 1 m .. 3 m scaled to black .. white
    assert (np.diff(gray[0].astype(int)) >= 0).all()


def test_image_view_streams_to_rerun(
    camera: subprocess.Popen[str], tmp_path: Path, vz: Any, capsys: Any
) -> None:
    pytest.importorskip("rerun")
    out = tmp_path / "image.rrd"
    r = _cli(capsys, "image", "view", "/cam/image_raw", "--save", str(out), "--duration", "1.5")
    assert r.returncode == 0, r.stderr
    rrd = vz.Rrd(out)
    assert len(rrd.rows("world/cameras/cam/image_raw", "EncodedImage:blob")) >= 3
    assert "world/points" not in rrd.entities  # only the one image topic (and TF)


def test_image_snapshot_times_out_with_a_clear_error(
    domain: int, tmp_path: Path, capsys: Any
) -> None:
    r = _cli(
        capsys, "image", "view", "/nobody", "--snapshot", str(tmp_path / "x.png"), "--timeout", "1"
    )
    assert r.returncode == 1
    assert r.stderr.startswith("error: no image on '/nobody' within 1.0 s (0 publisher(s)")


def test_view_live_saves_the_topics(
    camera: subprocess.Popen[str], tmp_path: Path, vz: Any, capsys: Any
) -> None:
    pytest.importorskip("rerun")
    out = tmp_path / "live.rrd"
    r = _cli(capsys, "view", "--save", str(out), "--duration", "2", "--fixed-frame", "map")
    assert r.returncode == 0, r.stderr
    assert "fixed frame: map" in r.stderr
    rrd = vz.Rrd(out)
    assert {
        "world/points",
        "world/cameras/cam",
        "world/cameras/cam/image_raw",
        "world/cameras/cam/image_raw/compressed",
        "world/cameras/depth/image_raw",
        "world/tf/cam_optical",
    } <= rrd.entities
    pts = np.array(rrd.rows("world/points", "Points3D:positions")[-1])
    assert len(pts) == 100
    assert np.allclose(pts.mean(axis=0)[2], 1.0, atol=0.3)  # cloud raised by the static TF
    assert len(rrd.rows("world/cameras/cam/image_raw", "EncodedImage:blob")) >= 5


def _write_bag(path: Path, vz: Any) -> None:
    from visnav.bag import BagWriter
    from visnav.msgs import serialize

    with BagWriter(path) as w:
        tf = w.add_topic("/tf_static", "tf2_msgs/msg/TFMessage")
        points = w.add_topic("/points", "sensor_msgs/msg/PointCloud2")
        image = w.add_topic("/cam/image_raw", "sensor_msgs/msg/Image")
        tf_static = vz.tf_msg(vz.tf("map", "base", 0, (0.0, 0.0, 2.0)))
        w.write(tf, 1_000_000_000, serialize(tf_static))
        for i in range(5):
            t = 1_000_000_000 + i * 100_000_000
            header = vz.header("base", t)
            cloud = xyz_to_cloud(np.ones((3, 3), np.float32), header=header)
            w.write(points, t, serialize(cloud))
            img = numpy_to_image(np.zeros((4, 4, 3), np.uint8), "rgb8", header=header)
            w.write(image, t, serialize(img))


def test_view_bag_saves_an_rrd(tmp_path: Path, vz: Any, capsys: Any) -> None:
    pytest.importorskip("rerun")
    bag = tmp_path / "bag"
    _write_bag(bag, vz)
    out = tmp_path / "bag.rrd"
    args = ["view", str(bag), "--save", str(out), "--topics", "/points", "--all-frames"]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "logged 6 messages" in err  # /points + /tf_static, not the image
    rrd = vz.Rrd(out)
    assert "world/cameras/cam/image_raw" not in rrd.entities
    rows = rrd.rows("world/points", "Points3D:positions")
    assert len(rows) == 5
    assert np.allclose(rows[0], [[1.0, 1.0, 3.0]] * 3)
    assert rrd.times("world/points", "Points3D:positions")[0] == 1_000_000_000


def test_view_bag_skips_a_message_that_does_not_decode(
    tmp_path: Path, vz: Any, capsys: Any, caplog: Any
) -> None:
    """One corrupt message (as a damaged recording has) is counted; the rest is shown."""
    pytest.importorskip("rerun")
    from visnav.bag import BagWriter
    from visnav.msgs import serialize

    bag = tmp_path / "bag"
    with BagWriter(bag) as w:
        points = w.add_topic("/points", "sensor_msgs/msg/PointCloud2")
        for i in range(4):
            t = 1_000_000_000 + i * 100_000_000
            data = serialize(xyz_to_cloud(np.ones((3, 3), np.float32), header=vz.header("b", t)))
            w.write(points, t, data[:30] if i == 2 else data)  # the third one cut short
    out = tmp_path / "bag.rrd"
    with caplog.at_level(logging.WARNING, logger="visnav.viz"):
        assert main(["view", str(bag), "--save", str(out), "--all-frames"]) == 0
    err = capsys.readouterr().err
    assert "logged 3 messages" in err
    (row,) = [line.split() for line in err.splitlines() if line.startswith("/points")]
    assert row[-4:] == ["3", "0", "0", "1"]  # logged, skipped, dropped, errors
    assert "/points (sensor_msgs/msg/PointCloud2) skipped: bag" in caplog.text
    assert len(vz.Rrd(out).rows("world/points", "Points3D:positions")) == 3


def test_view_bag_shows_clouds_at_the_display_rate(tmp_path: Path, vz: Any, capsys: Any) -> None:
    """10 Hz clouds are shown at 5 Hz by default: every other one, counted as skipped."""
    pytest.importorskip("rerun")
    bag = tmp_path / "bag"
    _write_bag(bag, vz)
    out = tmp_path / "bag.rrd"
    assert main(["view", str(bag), "--save", str(out), "--world", "none"]) == 0
    err = capsys.readouterr().err
    (row,) = [line.split() for line in err.splitlines() if line.startswith("/points")]
    assert row[-4:] == ["3", "2", "0", "0"]  # logged, skipped, dropped, errors
    assert len(vz.Rrd(out).rows("world/points", "Points3D:positions")) == 3


def test_view_bad_arguments(tmp_path: Path, capsys: Any) -> None:
    pytest.importorskip("rerun")
    assert main(["view", str(tmp_path / "missing_bag")]) == 1
    assert "does not exist" in capsys.readouterr().err
    assert main(["view", "--save", str(tmp_path / "a.rrd"), "--max-points", "-1"]) == 1
    assert "--max-points is -1" in capsys.readouterr().err
