"""Localisation in a saved SLAM map: found where told or by place recognition, held, refused.

The saved map is a real run over a sixth of the synthetic room's circle (40 frames); the
frames localised in it are the same stretch (found, the saved keyframes held), the same
stretch with a wrong first guess (found by bag of words), and the opposite side of the
circle, which looks at other walls (never found: tracking stays lost, nothing published).
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs.serde import get_message_class
from visnav.slam import SlamConfig, SlamSystem
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.errors import SlamError, SlamInputError
from visnav.slam.localization_mode import SavedMapAnchor, check_map_camera
from visnav.slam.map_file import SlamMapFileError, load_slam_map, save_system_map
from visnav.slam.node import SlamNode
from visnav.slam.node_diagnostics import LOCALIZE_FRAMES
from visnav.slam.worker import InlineWorker

from .conftest import SMALL, Sequence, feed_rgbd, make_sequence

CONFIG = SlamConfig(n_features=400, vocabulary_keyframes=6, loop_min_inliers=30)


@pytest.fixture(scope="module")
def saved_path(short_sequence: Sequence, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The map of a real run over ``short_sequence`` (odometry: the ground truth)."""
    seq = short_sequence
    slam = SlamSystem(seq.camera, CONFIG, initial_pose=seq.poses[0])
    for i, (rgb, depth, t) in enumerate(zip(seq.rgb, seq.depth, seq.stamps_ns, strict=True)):
        slam.track(rgb, depth, int(t), odom_pose=seq.poses[i])
    path = tmp_path_factory.mktemp("saved") / "slam_map.npz"
    save_system_map(slam, path)
    return path


def _localise(
    path: Path, seq: Sequence, frames: range, start: np.ndarray
) -> tuple[SlamSystem, list]:
    slam = SlamSystem(seq.camera, CONFIG, initial_pose=start, saved_map=load_slam_map(path))
    # odometry from another session: a frame far from the saved map's odometry frame
    shift = np.eye(4)
    shift[:3, 3] = [50.0, -20.0, 0.0]
    results = [
        slam.track(seq.rgb[i], seq.depth[i], int(seq.stamps_ns[i]), odom_pose=shift @ seq.poses[i])
        for i in frames
    ]
    return slam, results


def _position_errors(results: list, seq: Sequence, frames: range) -> np.ndarray:
    return np.array(
        [
            np.linalg.norm(r.t_wc[:3, 3] - seq.poses[i][:3, 3])
            for r, i in zip(results, frames, strict=True)
        ]
    )


def test_localises_where_told_and_holds_the_saved_map(
    saved_path: Path, short_sequence: Sequence
) -> None:
    seq = short_sequence
    saved = load_slam_map(saved_path)
    before = {kf.id: kf.t_cw.copy() for kf in saved.map.keyframes}
    frames = range(40)
    slam, results = _localise(saved_path, seq, frames, seq.poses[0])
    assert all(r.t_wc is not None for r in results)  # found at the first frame, kept
    assert results[0].state == "ok"
    assert slam.localized
    assert _position_errors(results, seq, frames).max() < 0.02
    n_saved = len(before)
    assert slam.saved is not None
    assert slam.saved.n_saved == n_saved
    for kf in slam.map.keyframes[:n_saved]:  # held: bundle adjustment never moved them
        assert np.array_equal(kf.t_cw, before[kf.id])
        assert kf.odom_pose is None  # the earlier run's odometry frame is dropped
    assert slam.loops == []  # loop closing is off: the saved frame is the frame
    assert slam.loop_closer.vocabulary is None  # found where told: no place memory needed


def test_a_wrong_first_guess_is_mended_by_place_recognition(
    saved_path: Path, short_sequence: Sequence
) -> None:
    seq = short_sequence
    wrong = seq.poses[10].copy()
    wrong[:3, 3] += [2.5, -1.5, 0.0]
    frames = range(10, 30)
    slam, results = _localise(saved_path, seq, frames, wrong)
    assert results[0].t_wc is not None
    assert results[0].relocalized
    assert _position_errors(results, seq, frames).max() < 0.02
    assert slam.n_relocalized == 1
    vocabulary, database = slam.loop_closer.vocabulary, slam.loop_closer.database
    assert vocabulary is not None  # trained on the saved keyframes when first needed
    assert database is not None
    assert len(database) == len(slam.map.keyframes)  # saved and new, each once


def test_far_outside_the_saved_map_it_never_localises(saved_path: Path) -> None:
    far = make_sequence(150, turns=1.15)  # frames 75-95: the other side of the circle
    frames = range(75, 95)
    slam, results = _localise(saved_path, far, frames, far.poses[0])
    assert all(r.t_wc is None and r.state == "lost" for r in results)
    assert not slam.localized
    assert slam.saved is not None
    assert len(slam.map.keyframes) == slam.saved.n_saved  # nothing added where it is not
    text = " ".join(w for r in results for w in r.warnings)
    assert "not localised in the saved map after 20 frames" in text


def test_nearby_keyframes_look_the_same_way(saved_path: Path) -> None:
    anchor = SavedMapAnchor(load_slam_map(saved_path))
    kf = anchor.map.keyframes[2]
    near = anchor.nearby(kf.t_wc)
    assert near[0] == kf.id
    assert all(
        np.linalg.norm(anchor.map.keyframes[k].t_wc[:3, 3] - kf.t_wc[:3, 3]) <= 4.0 for k in near
    )
    turned = kf.t_wc.copy()
    turned[:3, :3] = turned[:3, :3] @ np.diag([-1.0, 1.0, -1.0])  # looking back
    assert kf.id not in anchor.nearby(turned)
    away = kf.t_wc.copy()
    away[:3, 3] += [30.0, 0.0, 0.0]
    assert anchor.nearby(away) == []


def test_another_camera_is_refused(saved_path: Path) -> None:
    saved = load_slam_map(saved_path)
    check_map_camera(saved.camera, SMALL, str(saved_path))
    other = dataclasses.replace(SMALL, fx=SMALL.fx * 1.1)
    with pytest.raises(SlamInputError) as info:
        check_map_camera(saved.camera, other, str(saved_path))
    text = str(info.value)
    assert str(saved_path) in text
    assert "fx=125" in text
    assert "fx=137.5" in text
    assert "\n" not in text
    wide = CameraIntrinsics(SMALL.fx, SMALL.fy, SMALL.cx, SMALL.cy, 320, 240)
    with pytest.raises(SlamError, match="width=160, this camera_info width=320"):
        InlineWorker(wide, CONFIG, map_path=str(saved_path))


def test_node_localises_and_does_not_write_the_map(
    saved_path: Path,
    short_sequence: Sequence,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
) -> None:
    path = tmp_path / "slam_map.npz"
    path.write_bytes(saved_path.read_bytes())
    stamp = path.stat().st_mtime_ns
    overrides = {
        "odom_frame": "",
        "base_frame": "camera_optical",
        "n_features": 400,
        "database_path": str(path),
        "localization": True,
        "global_ba_after_loop": False,  # passed on to the system's configuration
    }
    caplog.set_level(logging.INFO)
    with Context(transport="local") as ctx:
        slam = SlamNode(context=ctx, parameter_overrides=overrides)
        feed_rgbd(Node("feeder", context=ctx), short_sequence, 8)
        assert slam.system is not None
        assert slam.system.saved is not None
        assert slam.system.config.global_ba_after_loop is False
        assert slam.tracking
        assert slam.system.localized
        slam.destroy_node()
    assert path.stat().st_mtime_ns == stamp  # read, not written
    assert "SLAM map saved" not in caplog.text


def test_node_refuses_localization_without_a_map(tmp_path: Path) -> None:
    with pytest.raises(SlamMapFileError, match="localization is true but database_path is empty"):
        SlamNode(context=Context(transport="local"), parameter_overrides={"localization": True})
    missing = str(tmp_path / "none.npz")
    with pytest.raises(SlamMapFileError, match=r"no such file to localise in") as info:
        SlamNode(
            context=Context(transport="local"),
            parameter_overrides={"localization": True, "database_path": missing},
        )
    assert missing in str(info.value)


def test_node_far_outside_says_it_cannot_localise(
    saved_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    far = make_sequence(150, turns=1.15)
    part = Sequence(far.camera, far.poses[75:], far.stamps_ns[75:], far.rgb[75:], far.depth[75:])
    overrides = {
        "odom_frame": "",
        "base_frame": "camera_optical",
        "n_features": 400,
        "database_path": str(saved_path),
        "localization": True,
    }
    caplog.set_level(logging.INFO)
    with Context(transport="local") as ctx:
        slam = SlamNode(context=ctx, parameter_overrides=overrides)
        statuses: list = []
        probe = Node("probe", context=ctx)
        probe.create_subscription(
            get_message_class("diagnostic_msgs/msg/DiagnosticArray"),
            "/diagnostics",
            lambda m: statuses.extend(m.status),
            10,
        )
        feed_rgbd(Node("feeder", context=ctx), part, LOCALIZE_FRAMES + 5)
        ctx.spin_some()
        assert slam.t_map_odom is None  # nothing to publish map -> odom from
        assert not slam.tracking
        slam.destroy_node()
    errors = [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR]
    assert len(errors) == 1  # said once
    assert errors[0].startswith(
        f"[/slam] cannot localise in the saved SLAM map {saved_path}: no fix"
    )
    last = statuses[-1]
    assert last.level == 2
    assert last.message.startswith("not localised in the saved map (4")
