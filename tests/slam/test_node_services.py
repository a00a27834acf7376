"""The SLAM node's services (rtabmap's names): reset, pause, resume, save_map."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, Header, Image
from visnav.msgs.image import numpy_to_image
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time
from visnav.slam.map_file import load_slam_map
from visnav.slam.node import SlamNode
from visnav.slam.synthetic import camera_info_for

from .conftest import Sequence

Empty = get_service_type("std_srvs/srv/Empty")
Trigger = get_service_type("std_srvs/srv/Trigger")
OVERRIDES = {"odom_frame": "", "base_frame": "camera_optical", "n_features": 400}


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


class Camera:
    """Publishes frames ``i`` of a sequence (rgb, depth, camera_info), one spin each."""

    def __init__(self, ctx: Context, seq: Sequence) -> None:
        self.ctx, self.seq = ctx, seq
        node = Node("camera", context=ctx)
        self.img = node.create_publisher(Image, "rgb/image", 10)
        self.dep = node.create_publisher(Image, "depth/image", 10)
        self.inf = node.create_publisher(CameraInfo, "rgb/camera_info", 10)
        self.info = camera_info_for(seq.camera, frame_id="camera_optical")
        self.client = Node("client", context=ctx)

    def frames(self, indices: range) -> None:
        for i in indices:
            header = Header(stamp=ns_to_time(int(self.seq.stamps_ns[i])), frame_id="camera_optical")
            self.info.header = header
            self.inf.publish(self.info)
            self.img.publish(numpy_to_image(self.seq.rgb[i], "rgb8", header=header))
            self.dep.publish(numpy_to_image(self.seq.depth[i], "32FC1", header=header))
            self.ctx.spin_some()

    def call(self, name: str, stype: Any = Empty) -> Any:
        future = self.client.create_client(stype, name).call_async(stype.Request())
        assert self.ctx.spin_until(future.done, 10.0)
        return future.result()


def test_services_are_served_in_the_node_namespace(ctx: Context) -> None:
    slam = SlamNode("rtabmap", context=ctx, parameter_overrides=OVERRIDES)
    names = {s.srv_name: s.srv_type.name for s in slam.services}
    assert names["/rtabmap/reset"] == "std_srvs/srv/Empty"
    assert names["/rtabmap/pause"] == names["/rtabmap/resume"] == "std_srvs/srv/Empty"
    assert names["/rtabmap/save_map"] == "std_srvs/srv/Trigger"


def test_pause_leaves_frames_out_until_resume(ctx: Context, short_sequence: Sequence) -> None:
    slam = SlamNode(context=ctx, parameter_overrides=OVERRIDES)
    cam = Camera(ctx, short_sequence)
    cam.frames(range(6))
    frames = slam.stats().frames
    assert frames >= 4
    cam.call("/slam/pause")
    cam.frames(range(6, 12))
    assert slam.stats().frames <= frames + 1  # at most the set the synchroniser held
    assert slam.slam_services.paused_frames >= 5
    cam.call("/slam/resume")
    cam.frames(range(12, 18))
    assert slam.stats().frames >= frames + 4
    assert slam.dropped == 0


def test_reset_drops_the_map_and_the_next_frame_starts_a_new_one(
    ctx: Context, short_sequence: Sequence
) -> None:
    slam = SlamNode(context=ctx, parameter_overrides=OVERRIDES)
    cam = Camera(ctx, short_sequence)
    cam.frames(range(10))
    assert slam.system is not None
    first_map = slam.system
    assert slam.stats().keyframes >= 2
    cam.call("/slam/reset")
    assert slam.worker is None
    assert slam.t_map_odom is None
    assert not slam.tracking
    assert slam.slam_services.resets == 1
    cam.frames(range(10, 20))
    assert slam.system is not None
    assert slam.system is not first_map
    assert slam.tracking
    # the new map starts where the camera was after the reset: its path begins there
    stats = slam.stats()
    assert 1 <= stats.frames <= 10
    traj = slam.trajectory()
    assert len(traj.stamps) <= 10
    assert traj.stamps[0] >= short_sequence.stamps_ns[10] * 1e-9 - 1e-6


def test_save_map_writes_database_path_or_says_why_not(
    ctx: Context, short_sequence: Sequence, tmp_path: Path
) -> None:
    target = tmp_path / "slam_map.npz"
    SlamNode(context=ctx, parameter_overrides={**OVERRIDES, "database_path": str(target)})
    SlamNode("no_path", context=ctx, parameter_overrides=OVERRIDES)
    cam = Camera(ctx, short_sequence)
    early = cam.call("/slam/save_map", Trigger)
    assert not early.success
    assert "no frame was processed" in early.message
    cam.frames(range(10))
    reply = cam.call("/slam/save_map", Trigger)
    assert reply.success, reply.message
    assert str(target) in reply.message
    saved = load_slam_map(target)
    assert len(saved.map.keyframes) >= 2
    other = cam.call("/no_path/save_map", Trigger)
    assert not other.success
    assert "database_path" in other.message


@settings(
    max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    ops=st.lists(
        st.sampled_from(["reset", "pause", "resume", "save_map", "frames"]), min_size=1, max_size=6
    )
)
def test_fuzz_service_calls_in_any_order_never_break_the_node(
    short_sequence: Sequence, tmp_path_factory: pytest.TempPathFactory, ops: list[str]
) -> None:
    target = tmp_path_factory.mktemp("slam") / "map.npz"
    with Context(transport="local") as ctx:
        slam = SlamNode(
            context=ctx, parameter_overrides={**OVERRIDES, "database_path": str(target)}
        )
        cam = Camera(ctx, short_sequence)
        start = 0
        for op in [*ops, "resume", "frames"]:
            if op == "frames":
                cam.frames(range(start, start + 3))
                start += 3
            else:
                reply = cam.call(f"/slam/{op}", Trigger if op == "save_map" else Empty)
                if op == "save_map":
                    assert isinstance(reply.success, bool)
                    assert reply.message
        assert slam.dropped == 0
        assert not slam.slam_services.paused
        assert slam.worker is not None  # the last frames started or continued a map
        assert np.isfinite(slam.stats().frames)
        slam.destroy_node()
