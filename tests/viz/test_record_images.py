"""``visnav run --record-images``: the run's bag keeps the camera images through compressed
transport (``<topic>/compressed``, ``<topic>/compressedDepth``), and ``view``, ``doctor --bag``
and ``slam --bag`` read them; ``raw_images`` keeps them raw."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rerun")

from visnav.bag import BagReader
from visnav.doctor.bag_source import observe_bag
from visnav.graph import Context
from visnav.scenarios.runner import format_summary, run_scenario
from visnav.slam.offline import slam_bag
from visnav.viz import feed_bag

COMPRESSED = "sensor_msgs/msg/CompressedImage"


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(600)
def test_record_images_keeps_cameras_and_the_viewer_shows_them(
    tmp_path: Path, session: Any
) -> None:
    with Context(transport="local") as ctx:
        summary = run_scenario(
            "car",
            duration_s=0.5,
            out=tmp_path / "run",
            context=ctx,
            progress=None,
            slam=False,
            record_images=True,
        )
    with BagReader(summary["bag"]) as reader:
        types = {name: meta.type_name for name, meta in reader.topics.items()}
        formats = {}
        for m in reader.messages(
            ["/camera/image_raw/compressed", "/depth_camera/depth/image_raw/compressedDepth"]
        ):
            formats[m.topic] = m.msg.format
    assert types["/camera/image_raw/compressed"] == COMPRESSED
    assert types["/depth_camera/image_raw/compressed"] == COMPRESSED
    assert types["/depth_camera/depth/image_raw/compressedDepth"] == COMPRESSED
    assert not [t for t, ty in types.items() if ty == "sensor_msgs/msg/Image"]
    assert not [t for t, ty in types.items() if ty == "sensor_msgs/msg/PointCloud2"]
    assert formats == {
        "/camera/image_raw/compressed": "rgb8; jpeg compressed bgr8",
        "/depth_camera/depth/image_raw/compressedDepth": "32FC1; compressedDepth png",
    }
    # the size per simulated second is in the summary and the printed table
    on_disk = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert on_disk["bag_images"] == "compressed"
    assert on_disk["bag_bytes"] > 0
    assert on_disk["bag_mb_per_sim_s"] == pytest.approx(
        on_disk["bag_bytes"] / 1e6 / on_disk["sim_duration_s"], rel=0.01
    )
    assert "MB per simulated second, images compressed" in format_summary(on_disk)

    # view: the viewer shows the decoded images
    s = session()
    assert feed_bag(s.sink, summary["bag"]) > 0
    stats = s.sink.stats()
    assert stats["/camera/image_raw/compressed"]["logged"] >= 10
    assert stats["/depth_camera/depth/image_raw/compressedDepth"]["logged"] >= 5
    assert s.sink.robot_models, "robot_description was not recorded or not shown"
    (model,) = s.sink.robot_models.values()
    assert "base_link" in model.placed
    rrd = s.finish()
    assert any(e.startswith("world/cameras/camera/image_raw") for e in rrd.entities)

    # doctor --bag: the compressed topics are observed as the Image topics, decoded
    obs = observe_bag(summary["bag"])
    depth = obs.topics["/depth_camera/depth/image_raw"]
    assert depth.type_name == "sensor_msgs/msg/Image"
    assert depth.samples, "no decoded depth samples"
    assert depth.samples[-1].msg.encoding == "32FC1"
    assert obs.topics["/camera/image_raw"].samples[-1].msg.encoding == "rgb8"

    # slam --bag: reads <topic>/compressed and /compressedDepth for the default topics
    run = slam_bag(summary["bag"], output="", max_frames=5)
    assert run.frames >= 5


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_raw_images_keeps_images_raw(tmp_path: Path) -> None:
    with Context(transport="local") as ctx:
        summary = run_scenario(
            "car",
            duration_s=0.3,
            out=tmp_path / "run",
            context=ctx,
            progress=None,
            slam=False,
            record_images=True,
            raw_images=True,
        )
    with BagReader(summary["bag"]) as reader:
        types = {name: meta.type_name for name, meta in reader.topics.items()}
    assert types["/camera/image_raw"] == "sensor_msgs/msg/Image"
    assert types["/depth_camera/depth/image_raw"] == "sensor_msgs/msg/Image"
    assert COMPRESSED not in types.values()
    assert summary["bag_images"] == "raw"
