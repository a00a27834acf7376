"""SLAM in the loop: results applied at stamp + latency, map -> odom stops while lost."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, Clock, Header, Image, PoseStamped, make, ns_to_time
from visnav.msgs.image import numpy_to_image
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import TFMessage
from visnav.slam.errors import SlamInputError
from visnav.slam.node import SlamNode
from visnav.slam.synthetic import camera_info_for
from visnav.tf import matrix_to_transform, pose_to_matrix
from visnav.tf.ros import StaticTransformBroadcaster, TransformBroadcaster

from .conftest import Sequence

T_BASE_CAM = np.array([[0, 0, 1, 0.1], [-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=float)
PERIOD_NS = 50_000_000  # 20 Hz frames
STEP_NS = 10_000_000  # the clock advances in 10 ms steps


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _tf(parent: str, child: str, m: np.ndarray, t_ns: int) -> Any:
    from visnav.msgs import TransformStamped

    return make(
        TransformStamped,
        header=Header(stamp=ns_to_time(t_ns), frame_id=parent),
        child_frame_id=child,
        transform=matrix_to_transform(m),
    )


class _Rig:
    """A feeder in sim time: /clock in 10 ms steps, a frame and odom -> base every 50 ms."""

    def __init__(self, ctx: Context, seq: Sequence) -> None:
        self.ctx, self.seq = ctx, seq
        self.node = Node("feeder", context=ctx)
        self.clock = self.node.create_publisher(Clock, "/clock", 10)
        self.img = self.node.create_publisher(Image, "rgb/image", 10)
        self.dep = self.node.create_publisher(Image, "depth/image", 10)
        self.inf = self.node.create_publisher(CameraInfo, "rgb/camera_info", 10)
        self.tf = TransformBroadcaster(self.node)
        StaticTransformBroadcaster(self.node).send_transform(
            _tf("base_link", "camera_optical", T_BASE_CAM, 0)
        )
        self.poses: list[tuple[int, PoseStamped]] = []  # (clock when received, pose)
        self.map_odom: list[int] = []  # clock times of map -> odom messages
        self.diag: list[Any] = []
        self.now = 0
        self.node.create_subscription(
            PoseStamped, "slam/pose", lambda m: self.poses.append((self.now, m)), 10
        )
        self.node.create_subscription(TFMessage, "/tf", self._on_tf, 100)
        diag = get_message_class("diagnostic_msgs/msg/DiagnosticArray")
        self.node.create_subscription(diag, "/diagnostics", self.diag.append, 100)
        self.info = camera_info_for(seq.camera, frame_id="camera_optical")
        self.start = seq.poses[0] @ np.linalg.inv(T_BASE_CAM)

    def _on_tf(self, msg: Any) -> None:
        if any(t.header.frame_id == "map" for t in msg.transforms):
            self.map_odom.append(self.now)

    def step(self, frame: int | None, *, blank: bool = False) -> None:
        """Advance the clock 10 ms; publish frame ``frame`` of the sequence at the new time."""
        self.now += STEP_NS
        self.clock.publish(Clock(clock=ns_to_time(self.now)))
        if frame is not None:
            seq, t = self.seq, self.now
            t_odom_base = np.linalg.inv(self.start) @ seq.poses[frame] @ np.linalg.inv(T_BASE_CAM)
            self.tf.send_transform(_tf("odom", "base_link", t_odom_base, t))
            header = Header(stamp=ns_to_time(t), frame_id="camera_optical")
            self.info.header = header
            rgb = np.full_like(seq.rgb[frame], 128) if blank else seq.rgb[frame]
            self.inf.publish(self.info)
            self.img.publish(numpy_to_image(rgb, "rgb8", header=header))
            self.dep.publish(numpy_to_image(seq.depth[frame], "32FC1", header=header))
        self.ctx.spin_some()

    def run(self, frames: list[int], *, blank_from: int = 10**9, tail_steps: int = 20) -> None:
        for k, f in enumerate(frames):
            for s in range(PERIOD_NS // STEP_NS):
                self.step(f if s == PERIOD_NS // STEP_NS - 1 else None, blank=k >= blank_from)
        for _ in range(tail_steps):
            self.step(None)


def _slam(ctx: Context, **params: Any) -> SlamNode:
    return SlamNode(
        context=ctx,
        use_sim_time=True,
        parameter_overrides={
            "n_features": 400,
            "approx_sync": False,
            "tf_publish_period": 0.02,
            "diagnostic_period": 0.1,
            **params,
        },
    )


@pytest.mark.parametrize("worker", ["inline", "process"])
def test_a_result_is_applied_at_its_stamp_plus_the_latency(
    ctx: Context, short_sequence: Sequence, worker: str
) -> None:
    slam = _slam(ctx, result_latency=0.1, worker=worker)
    rig = _Rig(ctx, short_sequence)
    rig.run(list(range(8)))
    assert len(rig.poses) == 8
    for received, pose in rig.poses:
        assert received == time_to_ns(pose.header.stamp) + 100_000_000  # exactly, not later
    # map -> base_link follows the truth (the odometry here is exact: map == odom)
    last = pose_to_matrix(rig.poses[-1][1].pose)
    truth = np.linalg.inv(rig.start) @ short_sequence.poses[7] @ np.linalg.inv(T_BASE_CAM)
    assert np.linalg.norm(last[:3, 3] - truth[:3, 3]) < 0.02
    status = rig.diag[-1].status[0]
    values = {kv.key: kv.value for kv in status.values}
    assert status.message == "tracking"
    assert values["frames"] == "8"
    # the stamp of the last frame the counters include: the eighth, the last pose's
    assert values["last_frame_stamp_ns"] == str(time_to_ns(rig.poses[-1][1].header.stamp))
    assert float(values["cpu_s"]) > 0
    slam.destroy_node()


def test_inline_and_process_workers_give_the_same_poses(
    ctx: Context, short_sequence: Sequence
) -> None:
    out = []
    for worker in ("inline", "process"):
        with Context(transport="local") as c:
            _slam(c, result_latency=0.05, worker=worker, seed=2)
            rig = _Rig(c, short_sequence)
            rig.run(list(range(6)))
            out.append([(t, pose_to_matrix(p.pose)) for t, p in rig.poses])
    assert [t for t, _ in out[0]] == [t for t, _ in out[1]]
    for (_, a), (_, b) in zip(*out, strict=True):
        assert np.array_equal(a, b)


def test_map_to_odom_stops_while_tracking_is_lost(ctx: Context, short_sequence: Sequence) -> None:
    slam = _slam(ctx, result_latency=0.05, odometry_prior=False)
    rig = _Rig(ctx, short_sequence)
    rig.run(list(range(6)), blank_from=4, tail_steps=30)  # frames 4, 5: a blank wall
    assert not slam.tracking
    lost_at = rig.poses[-1][0]  # the last pose (frame 3) was applied at this clock time
    assert len(rig.poses) == 4
    assert rig.map_odom
    assert max(rig.map_odom) <= lost_at + 2 * PERIOD_NS
    assert rig.now - max(rig.map_odom) >= 0.25e9  # so a costmap's transform_tolerance trips
    lost = [d.status[0] for d in rig.diag if d.status[0].level == 1]
    assert lost
    assert "tracking lost" in lost[-1].message


def test_bad_loop_parameters_are_refused(ctx: Context) -> None:
    with pytest.raises(SlamInputError, match=r"worker 'gpu'.*inline, process"):
        SlamNode(context=ctx, parameter_overrides={"worker": "gpu"})
    with pytest.raises(SlamInputError, match=r"result_latency -1\.0"):
        SlamNode(context=ctx, parameter_overrides={"result_latency": -1.0})
    with pytest.raises(SlamInputError, match=r"global_ba_delay is -5: expected frames >= 0"):
        SlamNode(context=ctx, parameter_overrides={"global_ba_delay": -5})


def test_global_ba_delay_reaches_the_system(ctx: Context) -> None:
    node = SlamNode(context=ctx, parameter_overrides={"global_ba_delay": 40})
    assert node.config.global_ba_delay == 40
    node.destroy_node()


def test_a_worker_that_cannot_start_is_started_once_not_per_frame(
    ctx: Context, short_sequence: Sequence, monkeypatch: pytest.MonkeyPatch, tmp_path: Any
) -> None:
    import visnav.slam.node as slam_node

    starts: list[str] = []
    real = slam_node.make_worker

    def counting(*args: Any, **kwargs: Any) -> Any:
        starts.append(args[0])
        return real(*args, **kwargs)

    monkeypatch.setattr(slam_node, "make_worker", counting)
    missing = str(tmp_path / "no_such_vocabulary.npz")
    slam = _slam(ctx, result_latency=0.05, worker="process", vocabulary=missing)
    rig = _Rig(ctx, short_sequence)
    rig.run(list(range(4)))
    assert starts == ["process"]  # one attempt (a fresh interpreter each), then refused
    assert slam.dropped == 4
    assert not rig.poses
    slam.destroy_node()
