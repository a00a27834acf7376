"""``visnav run --record-images``: the run's bag keeps the camera images; ``view`` shows them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rerun")

from visnav.bag import BagReader
from visnav.graph import Context
from visnav.scenarios.runner import run_scenario
from visnav.viz import feed_bag


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
    images = sorted(t for t, ty in types.items() if ty == "sensor_msgs/msg/Image")
    assert "/camera/image_raw" in images
    assert not [t for t, ty in types.items() if ty == "sensor_msgs/msg/PointCloud2"]
    s = session()
    assert feed_bag(s.sink, summary["bag"]) > 0
    stats = s.sink.stats()
    assert stats["/camera/image_raw"]["logged"] >= 10
    assert s.sink.robot_models, "robot_description was not recorded or not shown"
    (model,) = s.sink.robot_models.values()
    assert "base_link" in model.placed
    rrd = s.finish()
    assert any(e.startswith("world/cameras/camera/image_raw") for e in rrd.entities)
