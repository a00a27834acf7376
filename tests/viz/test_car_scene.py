"""The car scene in the viewer: what a short live run and its bag put in the recording.

One short car run (SLAM off, images recorded compressed) streamed through the live
viewer's path (:class:`~visnav.viz.live_view.LiveView`: display rate, worker thread,
world geometry from the sim node's parameters) into an .rrd, then the run's bag through
``visnav view``'s path; both recordings are read back by entity path.
"""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rerun")

pytestmark = [pytest.mark.slow, pytest.mark.ci]


def _expect_scene(rrd: Any, *, live: bool) -> None:
    entities = rrd.entities
    # the office's geometry, in its colours
    for kind in ("boxes", "cylinders", "ground"):
        assert f"world/scene/{kind}" in entities, sorted(entities)
    boxes = rrd.rows("world/scene/boxes", "Boxes3D:half_sizes")
    assert len(boxes[0]) > 100  # the office's walls and furniture
    colors = {
        tuple(c) if isinstance(c, list) else c
        for c in rrd.rows("world/scene/boxes", "Boxes3D:colors")[0]
    }
    assert len(colors) > 3  # walls, wood, metal, fabric... not one colour
    # the robot's links (RobotModel from robot_description)
    links = [e for e in entities if e.startswith("world/robot_model/")]
    assert any(
        rrd.columns(e)
        & {
            "Mesh3D:vertex_positions",
            "Boxes3D:half_sizes",
            "Cylinders3D:lengths",
            "Ellipsoids3D:half_sizes",
        }
        for e in links
    ), links
    # map, costmaps, scan, paths, TF
    assert "world/map" in entities
    assert "world/move_base/global_costmap/costmap" in entities
    assert "world/scan" in entities
    assert rrd.rows("world/scan", "Points3D:positions")
    assert "world/move_base/GlobalPlanner/plan" in entities
    assert "world/tf/base_link" in entities
    # camera images beside the 3D view: JPEG colour, 16-bit depth
    cams = [e for e in entities if e.startswith("world/cameras/")]
    assert any("EncodedImage:blob" in rrd.columns(e) for e in cams), cams
    assert any("DepthImage:buffer" in rrd.columns(e) for e in cams), cams
    if live:
        assert "world/odom" in entities


def test_car_live_and_bag(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, vz: Any) -> None:
    from visnav.scenarios import runner
    from visnav.viz.live_view import LiveView

    live_rrd = tmp_path / "live.rrd"
    views: list[LiveView] = []

    class _Feed:  # the run's --view, saving instead of serving
        def __init__(self, ctx: Any, out_dir: Path, stream: Any) -> None:
            del out_dir, stream
            self.view = LiveView(ctx, web=False, save=live_rrd, sensors_in_use_only=False)
            views.append(self.view)

        def poll(self) -> None:
            self.view.poll()

        def close(self) -> None:
            self.view.close()

    monkeypatch.setattr(runner, "ViewFeed", _Feed)
    # a graph of its own: another simulation on the machine must not join this one
    monkeypatch.setenv("VISNAV_DOMAIN", str(random.SystemRandom().randint(20_000, 60_000)))
    out = tmp_path / "run"
    runner.run_scenario(
        "car",
        duration_s=4.0,
        out=out,
        view=True,
        slam=False,
        record_images=True,
        progress=None,
        log_file=False,
    )
    stats = views[0].sink.stats()
    assert stats["/tf"]["logged"] > 0
    assert sum(row["skipped"] for row in stats.values()) > 0  # the display rate worked
    _expect_scene(vz.Rrd(live_rrd), live=True)

    from visnav.viz import RerunSink, open_viewer
    from visnav.viz.display_sink import DisplaySink
    from visnav.viz.scene import world_for_bag
    from visnav.viz.sources import feed_bag

    bag_rrd = tmp_path / "bag.rrd"
    with open_viewer(save=bag_rrd) as viewer:
        sink = DisplaySink(
            RerunSink(viewer.recording), block=True, world_loader=lambda: world_for_bag(out / "bag")
        )
        feed_bag(sink, out / "bag")
        sink.close()
    assert sink.stats()["/camera/image_raw/compressed"]["logged"] > 0
    _expect_scene(vz.Rrd(bag_rrd), live=False)
