"""Offline runs: ``slam_tum`` / ``visnav slam --tum``, ``slam_bag`` / ``--bag``, TUM output."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from visnav.cli.main import main
from visnav.slam import SlamConfig, SlamInputError, read_tum, slam_bag, slam_tum
from visnav.slam.synthetic import (
    SyntheticRoom,
    camera_info_for,
    circle_trajectory,
    write_tum_folder,
)

from .conftest import SMALL

CONFIG = SlamConfig(n_features=400)


@pytest.fixture(scope="module")
def tum_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("tum") / "room"
    poses = circle_trajectory(30, turns=30 / 130)
    return write_tum_folder(folder, SyntheticRoom(seed=1), SMALL, poses, depth_offset_s=0.003)


def test_slam_tum_writes_and_evaluates(tum_folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "est.txt"
    run = slam_tum(tum_folder, output=out, config=CONFIG)
    assert run.frames == 30
    assert run.tracked == 30
    assert run.output == out
    est = read_tum(out)
    assert len(est) == 30
    # the map frame starts at the ground truth's first pose
    gt = read_tum(tum_folder / "groundtruth.txt")
    np.testing.assert_allclose(est.positions[0], gt.positions[0], atol=1e-6)
    assert run.ate is not None
    assert run.ate.rmse < 0.02
    assert run.rpe is not None
    assert run.rpe.rmse < 0.02
    assert "ATE (aligned) rmse" in run.summary()


def test_cli_slam_then_eval(
    tum_folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cli.txt"
    code = main(
        [
            "slam",
            "--tum",
            str(tum_folder),
            "-o",
            str(out),
            "--features",
            "400",
            "--max-frames",
            "12",
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "frames 12, tracked 12" in text
    assert len(read_tum(out)) == 12
    assert main(["eval", "ate", str(out), str(tum_folder / "groundtruth.txt"), "-a"]) == 0
    assert "ATE w.r.t. trans_part (m)" in capsys.readouterr().out


def test_tum_folder_without_intrinsics(
    tum_folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bare = tmp_path / "bare"
    bare.mkdir()
    for name in ("rgb.txt", "depth.txt", "rgb", "depth"):
        (bare / name).symlink_to(tum_folder / name)
    with pytest.raises(SlamInputError, match="--intrinsics"):
        slam_tum(bare, output="", max_frames=2)
    assert main(["slam", "--tum", str(bare), "--max-frames", "2"]) == 1
    assert "error:" in capsys.readouterr().err
    out = tmp_path / "i.txt"
    code = main(
        [
            "slam",
            "--tum",
            str(bare),
            "--intrinsics",
            "125,125,79.5,59.5",
            "--max-frames",
            "3",
            "-o",
            str(out),
        ]
    )
    assert code == 0
    assert len(read_tum(out)) == 3


def test_wrong_tum_depth_scale_is_reported(tum_folder: Path) -> None:
    with pytest.raises(SlamInputError, match="1000x"):
        slam_tum(tum_folder, output="", depth_scale=5.0, max_frames=1)


def _write_bag(path: Path, n: int) -> None:
    from visnav.bag import BagWriter
    from visnav.msgs import Header, Odometry, TFMessage, TransformStamped, make
    from visnav.msgs.image import numpy_to_image
    from visnav.msgs.serde import serialize
    from visnav.msgs.time import ns_to_time
    from visnav.tf import matrix_to_pose, matrix_to_transform

    room = SyntheticRoom(seed=1)
    poses = circle_trajectory(n, turns=n / 130)
    # camera mounted 10 cm ahead of base_link, optical axes (z forward, x right, y down)
    t_base_cam = np.array([[0, 0, 1, 0.1], [-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=float)
    info = camera_info_for(SMALL, frame_id="camera_optical")
    with BagWriter(path) as bag:
        h_img = bag.add_topic("/depth_camera/image_raw", "sensor_msgs/msg/Image")
        h_dep = bag.add_topic("/depth_camera/depth/image_raw", "sensor_msgs/msg/Image")
        h_inf = bag.add_topic("/depth_camera/camera_info", "sensor_msgs/msg/CameraInfo")
        h_gt = bag.add_topic("/ground_truth/odom", "nav_msgs/msg/Odometry")
        h_tf = bag.add_topic("/tf_static", "tf2_msgs/msg/TFMessage")
        tf = make(
            TransformStamped,
            header=Header(stamp=ns_to_time(10**9), frame_id="base_link"),
            child_frame_id="camera_optical",
            transform=matrix_to_transform(t_base_cam),
        )
        bag.write(h_tf, 10**9, serialize(TFMessage(transforms=[tf])))
        for i, pose in enumerate(poses):
            t = 2 * 10**9 + i * 33_333_333
            header = Header(stamp=ns_to_time(t), frame_id="camera_optical")
            rgb, depth = room.render(SMALL, pose)
            mm = np.rint(depth * 1000).astype(np.uint16)
            odom = make(
                Odometry,
                header=Header(stamp=ns_to_time(t), frame_id="odom"),
                child_frame_id="base_link",
            )
            odom.pose.pose = matrix_to_pose(pose @ np.linalg.inv(t_base_cam))
            bag.write(h_gt, t, serialize(odom))
            info.header = header
            bag.write(h_inf, t, serialize(info))
            bag.write(h_img, t, serialize(numpy_to_image(rgb, "rgb8", header=header)))
            bag.write(h_dep, t + 1000, serialize(numpy_to_image(mm, "16UC1", header=header)))


def test_slam_bag_runs_and_evaluates_in_the_base_frame(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    _write_bag(bag, 20)
    run = slam_bag(bag, config=CONFIG)
    assert run.tracked >= 18  # the synchroniser may hold back the last set
    assert run.output is not None
    assert run.output.name == "run.slam.txt"
    assert run.groundtruth is not None
    # base_link poses, in the ground truth's frame from the start: small unaligned error
    est = read_tum(run.output)
    gt = run.groundtruth
    i = int(np.argmin(np.abs(gt.stamps - est.stamps[0])))
    np.testing.assert_allclose(est.positions[0], gt.positions[i], atol=1e-3)
    assert run.ate is not None
    assert run.ate.rmse < 0.02


def test_slam_bag_names_a_missing_topic(tmp_path: Path) -> None:
    bag = tmp_path / "b"
    _write_bag(bag, 2)
    with pytest.raises(SlamInputError, match=r"no depth topic '/depth'.*its topics"):
        slam_bag(bag, depth_topic="/depth")
