"""The default views of the car, the drone and the TurtleBot3, live and from their bags.

Each scenario runs a few simulated seconds with ``--view``'s live path (its viewer
process, :class:`~visnav.viz.view_process.ViewProcess`, serving the web viewer and saving
an .rrd) and ``--record-images``; headless Chromium screenshots the page before the run's viewer
closes, then the run's bag goes through ``visnav view``'s path into a second viewer,
screenshot too. Both recordings are read back by entity path: the world's geometry, the
robot's meshes, map, scan / cloud, paths and images, with counts. ``VISNAV_SHOTS_DIR=DIR``
keeps the screenshots (``viewer-<scenario>-live.png``, ``-bag.png``): docs/images has them.
Minutes per case on the shared 2-core machine (a software-rendered page of a loaded
machine is slow); only the car case runs in CI.
"""

from __future__ import annotations

import importlib.util
import os
import random
import shutil
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

pytest.importorskip("rerun")

CHROMIUM = Path("/usr/bin/chromium")
TB3 = Path(__file__).resolve().parents[1] / "data" / "turtlebot3"
MESHES = {"Mesh3D:vertex_positions", "Asset3D:blob"}
SHAPES = MESHES | {"Boxes3D:half_sizes", "Cylinders3D:lengths", "Ellipsoids3D:half_sizes"}

pytestmark = [
    pytest.mark.slow,
    pytest.mark.timeout(1200),
    pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian chromium is not installed"),
]


def _cdp() -> ModuleType:
    spec = importlib.util.spec_from_file_location("viz_cdp", Path(__file__).with_name("_cdp.py"))
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _screenshot(url: str, shot: Path, *, min_colour: float = 0.01) -> float:
    """Open ``url`` in headless Chromium, wait until the 3D view is drawn, save ``shot``."""
    import cv2
    import numpy as np

    colour = 0.0
    chromium = _cdp().headless_chromium
    with chromium(
        shot.with_suffix(""), width=1024, height=640, log=shot.with_suffix(".log"), timeout_s=300.0
    ) as page:  # software WebGL: a loaded machine takes minutes per frame of a bigger page
        page.call("Page.navigate", url=url)
        deadline = time.monotonic() + 240.0
        previous = None
        while time.monotonic() < deadline:
            time.sleep(4.0)
            page.screenshot(shot)
            hsv = cv2.cvtColor(cv2.imread(str(shot)), cv2.COLOR_BGR2HSV)
            colour = float(((hsv[..., 1] > 60) & (hsv[..., 2] > 60)).mean())  # chrome is grey
            same = previous is not None and np.abs(hsv[..., 2].astype(int) - previous).mean() < 1
            previous = hsv[..., 2].astype(int)
            if colour > min_colour and same:  # drawn, and no longer changing
                break
    keep = os.environ.get("VISNAV_SHOTS_DIR")
    if keep:
        shutil.copy(shot, Path(keep) / shot.name)
    return colour


def _count(rrd: Any, entity: str, column: str) -> int:
    """Rows of ``column`` logged on ``entity`` and below (``image_raw/compressed``)."""
    return sum(
        len(rrd.rows(e, column)) for e in rrd.entities if e == entity or e.startswith(f"{entity}/")
    )


def _check(rrd: Any, name: str, *, live: bool) -> dict[str, int]:
    """The scene of ``name``'s recording: world, robot meshes, map, scan/cloud, paths, images."""
    entities = rrd.entities
    found: dict[str, int] = {}
    # the world's geometry: the office's boxes, the forest's trees, turtlebot3_world's meshes
    scene = [e for e in entities if e.startswith("world/scene/") and rrd.columns(e) & SHAPES]
    assert len(scene) >= (2 if name != "tb3-slam" else 5), sorted(entities)
    found["world shapes"] = len(scene)
    if name == "car":  # the office's walls and furniture, in their colours
        (boxes,) = rrd.rows("world/scene/boxes", "Boxes3D:half_sizes")
        assert len(boxes) > 100
        colors = rrd.rows("world/scene/boxes", "Boxes3D:colors")[0]
        assert len({tuple(c) if isinstance(c, list) else c for c in colors}) > 3
    # the robot's links from robot_description
    links = [e for e in entities if e.startswith("world/robot_model/") and rrd.columns(e) & SHAPES]
    assert len(links) >= 3, links
    if name == "tb3-slam":  # the burger's STL meshes
        assert sum(bool(rrd.columns(e) & MESHES) for e in links) >= 3, links
    found["robot visuals"] = len(links)
    topics = {
        "car": {
            "map": "world/map",
            "scan": "world/scan",
            "path": "world/move_base/GlobalPlanner/plan",
            "costmap": "world/move_base/global_costmap/costmap",
            "tf": "world/tf/base_link",
            "odom": "world/odom",
            "image": "world/cameras/camera/image_raw",
            "depth": "world/cameras/depth_camera\\/depth/image_raw",
        },
        "drone": {
            "cloud": "world/drone/grid_map/occupancy_inflate",
            "path": "world/drone/planning/path",
            "image": "world/cameras/drone\\/depth_camera/image_raw",
            "depth": "world/cameras/drone\\/depth_camera\\/depth/image_raw",
        },
        "tb3-slam": {
            "map": "world/map",
            "scan": "world/scan",
            "path": "world/move_base/GlobalPlanner/plan",
        },
    }[name]
    columns = {
        "map": "GridMap:data",
        "costmap": "GridMap:data",
        "tf": "Transform3D:translation",
        "odom": "Arrows3D:origins",
        "scan": "Points3D:positions",
        "cloud": "Points3D:positions",
        "path": "LineStrips3D:strips",
        "image": "EncodedImage:blob",
        "depth": "DepthImage:buffer",
    }
    for what, entity in topics.items():
        if what in ("cloud", "odom") and not live:
            continue  # a bag keeps no clouds (visnav run --record-all does)
        found[what] = _count(rrd, entity, columns[what])
        assert found[what] > 0, (what, entity, sorted(entities))
    return found


@pytest.mark.parametrize(
    ("name", "duration_s"),
    [pytest.param("car", 4.0, marks=pytest.mark.ci), ("drone", 6.0), ("tb3-slam", 6.0)],
)
def test_default_view_live_and_from_the_bag(
    name: str, duration_s: float, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, vz: Any
) -> None:
    from visnav.scenarios import runner
    from visnav.viz import RerunSink, open_viewer
    from visnav.viz.display_sink import DisplaySink
    from visnav.viz.scene import world_for_bag
    from visnav.viz.sources import feed_bag
    from visnav.viz.view_process import ViewPorts, ViewProcess

    monkeypatch.setenv("ROS_PACKAGE_PATH", str(TB3))  # ROBOTIS' packages, as catkin gives them
    # a graph of its own: another simulation on the machine must not join this one
    monkeypatch.setenv("VISNAV_DOMAIN", str(random.SystemRandom().randint(20_000, 60_000)))
    live_rrd, colour = tmp_path / "live.rrd", {}

    class _Feed:  # the run's --view (its viewer process), also saving, screenshot at the end
        def __init__(self, ctx: Any, out_dir: Path, stream: Any, view: Any = True) -> None:
            del out_dir, stream, view
            self.view = ViewProcess(
                ctx.domain, tmp_path / "viewer.log", ports=ViewPorts(0, 0), save=live_rrd
            )

        def poll(self) -> None:
            pass

        def close(self) -> None:
            try:
                assert self.view.url is not None
                shot = tmp_path / f"viewer-{name}-live.png"
                colour["live"] = _screenshot(self.view.url, shot)
            finally:
                assert self.view.close() == 0, (tmp_path / "viewer.log").read_text()[-3000:]

    monkeypatch.setattr(runner, "ViewFeed", _Feed)
    out = tmp_path / "run"
    runner.run_scenario(
        name, duration_s=duration_s, out=out, view=True, slam=False, record_images=True,
        progress=None, log_file=False,
    )  # fmt: skip
    live = _check(vz.Rrd(live_rrd), name, live=True)

    bag_rrd = tmp_path / "bag.rrd"
    with open_viewer(web=True, port=0, grpc_port=0, save=bag_rrd) as viewer:
        sink = DisplaySink(
            RerunSink(viewer.recording), block=True, world_loader=lambda: world_for_bag(out / "bag")
        )
        feed_bag(sink, out / "bag")
        assert viewer.url is not None
        colour["bag"] = _screenshot(viewer.url, tmp_path / f"viewer-{name}-bag.png")
    bag = _check(vz.Rrd(bag_rrd), name, live=False)
    print(f"{name}: live {live}, bag {bag}, coloured pixels {colour}")
    assert colour["live"] > 0.005  # the page drew the scene (the viewer's own chrome is grey)
    assert colour["bag"] > 0.005
