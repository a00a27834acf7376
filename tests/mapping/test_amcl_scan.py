"""amcl's own scan in the car's launch file: one depth row, not /scan's minimum over 10.

depthimage_to_laserscan keeps the shortest range among ``scan_height`` rows (right for
obstacles); with the car's disparity noise that minimum runs short at range, which pulled
amcl's pose toward what the camera looked at (docs/navigation.md). These tests pin both
the cause (the bias of a 10-row scan, none with one row) and the wiring of the fix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import visnav
from visnav.description.noise_specs import DepthNoise
from visnav.graph.names import expand_topic_name
from visnav.launch.description import NodeSpec
from visnav.launch.loader import load_launch
from visnav.msgs.image import numpy_to_image
from visnav.msgs.types import CameraInfo, Header, RegionOfInterest, Time
from visnav.perception.depth_to_scan import DepthImageToLaserScan
from visnav.sim.noise_models import apply_depth_noise

CAR_LAUNCH = Path(visnav.__file__).parent / "scenarios" / "launch" / "car.launch.yaml"
KINECT = DepthNoise(disparity_stddev=0.07, disparity_step=0.125)
"""The car's ``<depth_noise>`` (car.urdf.xacro)."""


def _info(width: int = 160, height: int = 40, f: float = 150.0) -> CameraInfo:
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    return CameraInfo(
        header=Header(stamp=Time(sec=1, nanosec=0), frame_id="depth"),
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=np.zeros(5),
        k=np.array([f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0]),
        r=np.eye(3).ravel(),
        p=np.array([f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0]),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def _wall_scan_error(scan_height: int, distance: float, frames: int = 40) -> float:
    """Mean error (m) of the scan of a wall about ``distance`` ahead, Kinect noise on.

    The wall's distance varies by +-0.5 m between frames, so that the disparity rounding
    (a fixed error at any one depth) averages out as it does over a real scene.
    """
    info = _info()
    converter = DepthImageToLaserScan(scan_height=scan_height, range_min=0.1, range_max=10.0)
    rng = np.random.default_rng(3)
    errors = []
    for z in distance + rng.uniform(-0.5, 0.5, frames):
        depth = np.full((info.height, info.width), z, dtype=np.float32)
        apply_depth_noise(depth, KINECT, rng)
        scan = converter.convert(numpy_to_image(depth, "32FC1", header=info.header), info)
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        angles = scan.angle_min + scan.angle_increment * np.arange(ranges.size)
        ok = np.isfinite(ranges)
        errors.append(ranges[ok] - z / np.cos(angles[ok]))  # a wall facing the camera
    return float(np.mean(np.concatenate(errors)))


def test_min_over_ten_noisy_rows_runs_short_one_row_does_not() -> None:
    sigma = float(KINECT.sigma(5.0))  # 4.5 cm at 5 m
    ten = _wall_scan_error(10, 5.0)
    one = _wall_scan_error(1, 5.0)
    assert ten < -1.2 * sigma, (ten, sigma)  # the expected minimum of 10 normals: -1.54 sigma
    assert abs(one) < 0.2 * sigma, (one, sigma)


def _nodes(args: dict[str, str]) -> list[NodeSpec]:
    return list(load_launch(CAR_LAUNCH, {"seed": "0", "out": "", **args}).nodes)


def _topic(node: NodeSpec, name: str) -> str:
    remapped = dict(node.remaps).get(name, name)
    return expand_topic_name(remapped, node.name, node.namespace)


@pytest.mark.parametrize("slam", ["true", "false"])
def test_car_launch_gives_amcl_a_one_row_scan(slam: str) -> None:
    args = {"use_map": "true", "map": "/x/map.yaml", "map_localization": "amcl", "slam": slam}
    nodes = _nodes(args)
    (amcl,) = [n for n in nodes if n.executable == "amcl"]
    wanted = expand_topic_name(str(amcl.params["scan_topic"]), amcl.name, amcl.namespace)
    scans = {_topic(n, "scan"): n for n in nodes if n.executable == "depthimage_to_laserscan"}
    assert wanted != "/scan"
    assert scans[wanted].params["scan_height"] == 1
    assert scans["/scan"].params["scan_height"] == 10  # the costmaps' obstacle scan is unchanged
    assert "laser_max_range" not in amcl.params  # the scan's own 10 m: no short-range bias left


def test_car_launch_without_a_map_runs_no_amcl_scan() -> None:
    nodes = _nodes({})
    assert [n.name for n in nodes if n.executable == "depthimage_to_laserscan"] == [
        "depthimage_to_laserscan"
    ]
    assert not [n for n in nodes if n.executable == "amcl"]
