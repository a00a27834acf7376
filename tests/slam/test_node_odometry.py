"""The SLAM node pairs each frame with the odometry of the frame's own stamp.

A 50 Hz diff drive and a 20 Hz camera share a stamp only every 100 ms, and in a
lock-step simulation the odometry of an instant can arrive after its image: the frame
waits for it (``odometry_wait``) instead of taking the newest, older transform.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from visnav.graph import Context
from visnav.msgs import Clock, Header, ns_to_time
from visnav.msgs.image import numpy_to_image
from visnav.slam.errors import SlamInputError
from visnav.slam.geometry import level_pose
from visnav.slam.node import SlamNode
from visnav.tf import pose_to_matrix
from visnav.tf.transforms import matrix_from_euler, yaw_from_matrix

from .conftest import Sequence
from .test_node_loop import PERIOD_NS, STEP_NS, T_BASE_CAM, _Rig, _slam, _tf


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


class _LateOdometryRig(_Rig):
    """Odometry of a frame's stamp is published ``delay_steps`` clock steps after the image."""

    def __init__(self, ctx: Context, seq: Sequence, *, delay_steps: int | None) -> None:
        super().__init__(ctx, seq)
        self.delay_steps = delay_steps  # None: odometry stops after the first frame
        self._due: list[tuple[int, int, int]] = []  # (publish at, stamp, frame)

    def _odom(self, frame: int) -> np.ndarray:
        return np.linalg.inv(self.start) @ self.seq.poses[frame] @ np.linalg.inv(T_BASE_CAM)

    stamp_lag_ns = 0  # images stamped this long before they are published (a late camera)

    def step(self, frame: int | None, *, blank: bool = False) -> None:
        del blank
        self.now += STEP_NS
        self.clock.publish(Clock(clock=ns_to_time(self.now)))
        if frame is not None:
            t = self.now - self.stamp_lag_ns
            if frame == 0 or self.delay_steps is not None:
                delay = 0 if frame == 0 else (self.delay_steps or 0)
                self._due.append((t + delay * STEP_NS, t, frame))
            header = Header(stamp=ns_to_time(t), frame_id="camera_optical")
            self.info.header = header
            self.inf.publish(self.info)
            self.img.publish(numpy_to_image(self.seq.rgb[frame], "rgb8", header=header))
            self.dep.publish(numpy_to_image(self.seq.depth[frame], "32FC1", header=header))
        for due in [d for d in self._due if d[0] <= self.now]:
            self._due.remove(due)
            self.tf.send_transform(_tf("odom", "base_link", self._odom(due[2]), due[1]))
        self.ctx.spin_some()


def test_a_frame_waits_for_the_odometry_of_its_own_stamp(
    ctx: Context, short_sequence: Sequence
) -> None:
    slam = _slam(ctx, result_latency=0.1)
    rig = _LateOdometryRig(ctx, short_sequence, delay_steps=2)  # odometry 20 ms late
    rig.run(list(range(8)))
    assert len(rig.poses) == 8
    assert slam.odometry_fallbacks == 0
    # the odometry is exact here, so map -> odom stays the identity (within SLAM's
    # error on this small sequence) when the stamps pair; pairing a frame with the
    # previous frame's odometry would put it a frame's motion (~6 cm, 2.8 deg) off
    assert slam.t_map_odom is not None
    assert np.linalg.norm(slam.t_map_odom[:3, 3]) < 0.02
    last = pose_to_matrix(rig.poses[-1][1].pose)
    assert np.linalg.norm(last[:3, 3] - rig._odom(7)[:3, 3]) < 0.02
    mispaired = last @ np.linalg.inv(rig._odom(6))
    assert np.linalg.norm(mispaired[:3, 3]) > 0.04
    slam.destroy_node()


def test_without_odometry_at_the_stamp_the_newest_is_used_after_the_wait(
    ctx: Context, short_sequence: Sequence, caplog: pytest.LogCaptureFixture
) -> None:
    slam = _slam(ctx, result_latency=0.1, odometry_wait=0.03)
    rig = _LateOdometryRig(ctx, short_sequence, delay_steps=None)  # odometry stops
    rig.run(list(range(5)))
    assert slam.odometry_fallbacks == 4  # every frame after the first
    assert len(rig.poses) == 5  # still processed, each 30 ms late at most
    assert "at the frame's stamp" in caplog.text
    assert "using the newest" in caplog.text
    slam.destroy_node()


def test_a_late_image_still_waits_from_its_arrival(ctx: Context, short_sequence: Sequence) -> None:
    # images 40 ms old on arrival (more than odometry_wait, 30 ms) and their odometry 20 ms
    # after them: the wait runs from arrival, as tf2's MessageFilter times out, so each
    # frame still gets the odometry of its own stamp
    slam = _slam(ctx, result_latency=0.0, odometry_wait=0.03)
    rig = _LateOdometryRig(ctx, short_sequence, delay_steps=2)
    rig.stamp_lag_ns = 40_000_000
    rig.run(list(range(6)))
    assert len(rig.poses) == 6
    assert slam.odometry_fallbacks == 0
    slam.destroy_node()


def test_frames_waiting_for_odometry_are_bounded_by_queue_size(
    ctx: Context, short_sequence: Sequence, caplog: pytest.LogCaptureFixture
) -> None:
    slam = _slam(ctx, odometry_wait=100.0, queue_size=3)
    rig = _LateOdometryRig(ctx, short_sequence, delay_steps=None)  # odometry stops
    rig.run(list(range(6)))
    assert len(slam._waiting) == 3  # frames 3, 4, 5 wait; 1 and 2 were dropped
    assert slam.dropped == 2
    assert "dropped the oldest frame waiting for TF" in caplog.text
    slam.destroy_node()


def test_a_negative_odometry_wait_is_refused(ctx: Context) -> None:
    with pytest.raises(SlamInputError, match=r"odometry_wait -1\.0: expected seconds >= 0"):
        SlamNode(context=ctx, parameter_overrides={"odometry_wait": -1.0})


def test_the_period_constants_match_the_rig() -> None:
    assert PERIOD_NS % STEP_NS == 0


def test_force_3dof_keeps_the_base_level_in_tf(ctx: Context, short_sequence: Sequence) -> None:
    slam = _slam(ctx, result_latency=0.1, force_3dof=True)
    rig = _LateOdometryRig(ctx, short_sequence, delay_steps=0)
    tilt = np.eye(4)  # the odometry's (planar) frame pitched 3 degrees: SLAM follows the camera
    tilt[:3, :3] = matrix_from_euler(0.0, np.radians(3.0), 0.0)
    rig.start = rig.start @ tilt
    rig.run(list(range(6)))
    assert len(rig.poses) == 6
    assert slam.t_map_odom is not None
    t_map_base = slam.t_map_odom @ rig._odom(5)
    assert np.allclose(t_map_base[2, :3], [0.0, 0.0, 1.0], atol=1e-9)  # no roll, no pitch
    assert abs(t_map_base[2, 3] - slam._level_z) < 1e-9  # type: ignore[operator]
    full = pose_to_matrix(rig.poses[-1][1].pose)  # slam/pose keeps SLAM's full pose
    assert not np.allclose(full[2, :3], [0.0, 0.0, 1.0], atol=1e-3)
    assert np.linalg.norm(full[:2, 3] - t_map_base[:2, 3]) < 1e-6
    slam.destroy_node()


def test_level_pose_keeps_x_y_yaw() -> None:
    pose = np.eye(4)
    pose[:3, :3] = matrix_from_euler(0.1, -0.05, 1.2)
    pose[:3, 3] = [1.0, -2.0, 0.3]
    level = level_pose(pose, 0.0)
    assert np.allclose(level[:2, 3], [1.0, -2.0])
    assert level[2, 3] == 0.0
    assert np.isclose(yaw_from_matrix(level), yaw_from_matrix(pose))
    assert np.allclose(level[:3, :3].T @ level[:3, :3], np.eye(3))
