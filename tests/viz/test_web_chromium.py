"""The served web viewer, opened in headless Chromium: the camera image and the cloud render.

The page and its data server listen on 127.0.0.1 only; Chromium is driven over the
DevTools protocol (``_cdp.py``) because its one-shot ``--screenshot`` fires before the
viewer's WebAssembly is compiled. WebGL runs on SwiftShader (software), which the
flags in ``_cdp.CHROMIUM_FLAGS`` enable. 6-11 s on the 2-core machine (the WebAssembly
compile), hence marked slow: run it with ``python -m pytest -m slow tests/viz``.
"""

from __future__ import annotations

import importlib.util
import math
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rerun")

from visnav.msgs import CameraInfo, make, numpy_to_image, xyz_to_cloud
from visnav.tf import quaternion_from_euler
from visnav.viz import RerunSink, open_viewer

CHROMIUM = Path("/usr/bin/chromium")
T0 = 1_000_000_000


def _cdp() -> ModuleType:
    spec = importlib.util.spec_from_file_location("viz_cdp", Path(__file__).with_name("_cdp.py"))
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _counts(png: Path) -> dict[str, int]:
    import cv2

    bgr = cv2.imread(str(png))
    assert bgr is not None
    b, g, r = (bgr[..., i].astype(int) for i in range(3))
    return {
        "red": int(((r > 200) & (g < 60) & (b < 60)).sum()),
        "blue": int(((b > 200) & (r < 60) & (g < 60)).sum()),
        "green": int(((g > 200) & (r < 60) & (b < 60)).sum()),
    }


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian chromium is not installed")
def test_web_viewer_renders_image_and_cloud_in_headless_chromium(tmp_path: Path, vz: Any) -> None:
    cdp = _cdp()
    with open_viewer(web=True, port=0, grpc_port=0) as viewer:
        assert viewer.url is not None
        assert viewer.url.startswith("http://127.0.0.1:")
        sink = RerunSink(viewer.recording, fixed_frame="map")
        q = quaternion_from_euler(-math.pi / 2, 0.0, -math.pi / 2)  # optical frame looking +x
        sink.log("/tf_static", vz.tf_msg(vz.tf("map", "cam", 0, (0.0, 0.0, 1.0), q)))
        header = vz.header("cam", T0)
        w, h = 160, 120
        info = make(CameraInfo, header=header, width=w, height=h)
        info.k[:] = [100.0, 0.0, w / 2, 0.0, 100.0, h / 2, 0.0, 0.0, 1.0]
        sink.log("/cam/camera_info", info)
        rgb = np.zeros((h, w, 3), np.uint8)
        rgb[:, : w // 2, 0] = 255  # left half red
        rgb[:, w // 2 :, 2] = 255  # right half blue
        sink.log("/cam/image_raw", numpy_to_image(rgb, "rgb8", header=header))
        rng = np.random.default_rng(0)
        pts = rng.uniform([2.0, -1.0, 0.0], [4.0, 1.0, 2.0], (5000, 3)).astype(np.float32)
        green = np.tile(np.array([[0, 255, 0]], np.uint8), (len(pts), 1))
        cloud = xyz_to_cloud(pts, header=vz.header("map", T0), rgb=green)
        sink.log("/points", cloud)
        sink.close()

        shot = tmp_path / "viewer.png"
        counts: dict[str, int] = {}
        with cdp.headless_chromium(tmp_path / "chromium", log=tmp_path / "chromium.log") as page:
            page.call("Page.navigate", url=viewer.url)
            deadline = time.monotonic() + 120.0
            while time.monotonic() < deadline:
                time.sleep(2.0)
                page.screenshot(shot)
                counts = _counts(shot)
                if min(counts.values()) > 1500:
                    break
        print(f"screenshot {shot}: {counts}")
        assert counts["red"] > 1500, counts  # left half of the camera image
        assert counts["blue"] > 1500, counts  # right half of the camera image
        assert counts["green"] > 1500, counts  # the point cloud


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian chromium is not installed")
def test_office_world_renders_in_its_colours_in_headless_chromium(tmp_path: Path, vz: Any) -> None:
    """The default 3D view of the office: its floor, walls and furniture fill the page."""
    import cv2

    from visnav.description.world import load_world

    cdp = _cdp()
    world = load_world("office", seed=0)
    with open_viewer(web=True, port=0, grpc_port=0) as viewer:
        assert viewer.url is not None
        sink = RerunSink(viewer.recording, fixed_frame="map")
        paths = sink.log_world(world)
        assert "world/scene/boxes" in paths
        sink.log("/tf_static", vz.tf_msg(vz.tf("map", "odom", 0)))
        sink.close()
        shot = tmp_path / "office.png"
        colourful = 0.0
        with cdp.headless_chromium(tmp_path / "chromium", log=tmp_path / "chromium.log") as page:
            page.call("Page.navigate", url=viewer.url)
            deadline = time.monotonic() + 150.0
            while time.monotonic() < deadline:
                time.sleep(3.0)
                page.screenshot(shot)
                hsv = cv2.cvtColor(cv2.imread(str(shot)), cv2.COLOR_BGR2HSV)
                # the viewer's chrome is grey; the office's materials are coloured
                colourful = float(((hsv[..., 1] > 60) & (hsv[..., 2] > 60)).mean())
                if colourful > 0.05:
                    break
        print(f"screenshot {shot}: {colourful:.1%} coloured pixels")
        assert colourful > 0.05
