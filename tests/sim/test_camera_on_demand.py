"""Cameras render only while something subscribes (gazebo_ros_camera activates on connect)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from visnav.graph import Context, Node
from visnav.msgs import Image
from visnav.sim.plugins import CameraPlugin
from visnav.sim.simulator import Simulator

from .test_simulator import car, small_world


@pytest.fixture
def ctx(mujoco_gl: str) -> Iterator[Context]:
    del mujoco_gl
    with Context(transport="local") as context:
        yield context


def test_a_camera_renders_only_while_subscribed(ctx: Context) -> None:
    with Simulator(small_world(), [car()], context=ctx) as sim:
        cams = {p.spec.name: p for p in sim.robot().plugins if isinstance(p, CameraPlugin)}
        rgb = next(p for p in cams.values() if p.spec.image_topic == "/camera/image_raw")
        sim.run(0.2)  # nobody listens: due frames are skipped, not rendered
        assert rgb.frames == 0
        assert rgb.skipped >= 5
        got: list[Image] = []
        listener = Node("listener", context=ctx)
        sub = listener.create_subscription(Image, "/camera/image_raw", got.append, 10)
        sim.run(0.2)  # 30 Hz: 6 frames in 0.2 s
        assert rgb.frames >= 5
        assert len(got) == rgb.frames
        listener.destroy_subscription(sub)
        frames = rgb.frames
        sim.run(0.2)
        assert rgb.frames == frames  # off again when the last subscriber left
