"""Cameras render only while something subscribes (gazebo_ros_camera activates on connect)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from visnav.graph import Context, Node
from visnav.msgs import Image, PointCloud2
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


def test_only_subscribed_outputs_are_made(ctx: Context) -> None:
    """Depth alone: no colour pass, no cloud; the cloud only once /points has a subscriber."""
    with Simulator(small_world(), [car()], context=ctx) as sim:
        depth_cam = next(
            p for p in sim.robot().plugins if isinstance(p, CameraPlugin) and p.spec.depth_topic
        )
        spec = depth_cam.spec
        assert spec.depth_topic
        assert spec.points_topic
        assert spec.image_topic
        calls: list[bool] = []
        real_cloud = depth_cam.sensor._cloud

        def cloud(*args: Any, **kwargs: Any) -> Any:
            calls.append(True)
            return real_cloud(*args, **kwargs)

        depth_cam.sensor._cloud = cloud  # type: ignore[method-assign]
        got: dict[str, list[Any]] = {"depth": [], "points": [], "image": []}
        listener = Node("listener", context=ctx)
        listener.create_subscription(Image, spec.depth_topic, got["depth"].append, 10)
        sim.run(0.2)  # 20 Hz
        assert len(got["depth"]) >= 3
        assert calls == []  # nobody wants the cloud: not built
        assert depth_cam.sensor.depth_passes == len(got["depth"])  # depth pass only
        listener.create_subscription(PointCloud2, spec.points_topic, got["points"].append, 10)
        listener.create_subscription(Image, spec.image_topic, got["image"].append, 10)
        passes = depth_cam.sensor.depth_passes
        sim.run(0.2)
        assert len(got["points"]) >= 3
        assert len(calls) == len(got["points"]) == len(got["image"])
        # colour and depth wanted: one lit pass gives both (no separate depth pass)
        assert depth_cam.sensor.depth_passes == passes
