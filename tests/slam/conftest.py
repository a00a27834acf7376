"""Synthetic RGB-D sequences (textured box room, exact depth) shared by the SLAM tests."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from visnav.graph import Node
from visnav.msgs import CameraInfo, Header, Image
from visnav.msgs.image import numpy_to_image
from visnav.msgs.time import ns_to_time
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.synthetic import SyntheticRoom, camera_info_for, circle_trajectory

SMALL = CameraIntrinsics(125.0, 125.0, 79.5, 59.5, 160, 120)


@dataclass(frozen=True)
class Sequence:
    camera: CameraIntrinsics
    poses: np.ndarray
    stamps_ns: np.ndarray
    rgb: list[np.ndarray]
    depth: list[np.ndarray]

    @property
    def stamps_s(self) -> np.ndarray:
        return self.stamps_ns.astype(np.float64) * 1e-9


def make_sequence(
    n: int, *, turns: float, seed: int = 1, cam: CameraIntrinsics = SMALL
) -> Sequence:
    room = SyntheticRoom(seed=seed)
    poses = circle_trajectory(n, turns=turns)
    frames = [room.render(cam, p) for p in poses]
    stamps = (1_000_000_000 + np.arange(n) * 33_333_333).astype(np.int64)
    return Sequence(cam, poses, stamps, [f[0] for f in frames], [f[1] for f in frames])


@pytest.fixture(scope="session")
def short_sequence() -> Sequence:
    """40 frames along a sixth of the loop."""
    return make_sequence(40, turns=40 / 130)


@pytest.fixture(scope="session")
def loop_sequence() -> Sequence:
    """A full loop and a bit (150 frames): the end revisits the start."""
    return make_sequence(150, turns=1.15)


def feed_rgbd(feeder: Node, seq: Sequence, n: int) -> None:
    """Publish the first ``n`` frames of ``seq`` (rgb, depth, camera_info) from ``feeder``.

    Each frame is spun through the feeder's context before the next, as a camera driver's
    frames arrive one by one.
    """
    img = feeder.create_publisher(Image, "rgb/image", 10)
    dep = feeder.create_publisher(Image, "depth/image", 10)
    inf = feeder.create_publisher(CameraInfo, "rgb/camera_info", 10)
    info = camera_info_for(seq.camera, frame_id="camera_optical")
    for i in range(n):
        header = Header(stamp=ns_to_time(int(seq.stamps_ns[i])), frame_id="camera_optical")
        info.header = header
        inf.publish(info)
        img.publish(numpy_to_image(seq.rgb[i], "rgb8", header=header))
        dep.publish(numpy_to_image(seq.depth[i], "32FC1", header=header))
        feeder.context.spin_some()
