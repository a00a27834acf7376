"""Perception benchmarks at 640 x 480: rectification, depth -> cloud, depth -> scan.

Run: ``python bench/bench_perception.py``. Prints medians of repeated runs and the
ratio to the reference measured in the same run:

* ``rectify_image`` vs bare ``cv2.remap`` with the same maps (target <= 1.2x);
* depth -> cloud vs Open3D's ``PointCloud.create_from_depth_image`` (bench-only
  dependency; without it, vs a bare numpy implementation);
* depth -> LaserScan with ``scan_height`` 10 (target <= 1 ms).
"""

from __future__ import annotations

import statistics
import sys
import time
import types
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from visnav.msgs import CameraInfo, Header, RegionOfInterest, Time
from visnav.msgs.image import numpy_to_image
from visnav.perception import (
    DepthImageToLaserScan,
    PinholeCameraModel,
    PointCloudXyz,
    depth_rows_to_ranges,
    depth_to_points,
)

W, H = 640, 480
FX = FY = 525.0
CX, CY = 319.5, 239.5


def median_ms(fn: Callable[[], Any], *, repeat: int = 200, warmup: int = 10) -> float:
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e3


def paired_ms(
    ours: Callable[[], Any], reference: Callable[[], Any], *, repeat: int = 300
) -> tuple[float, float]:
    """Median ms of two functions timed alternately (fair on a shared, noisy machine)."""
    for _ in range(10):
        ours()
        reference()
    a, b = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        ours()
        t1 = time.perf_counter()
        reference()
        t2 = time.perf_counter()
        a.append(t1 - t0)
        b.append(t2 - t1)
    return statistics.median(a) * 1e3, statistics.median(b) * 1e3


def camera_info(d: list[float]) -> CameraInfo:
    k = [FX, 0.0, CX, 0.0, FY, CY, 0.0, 0.0, 1.0]
    p = [FX * 0.8, 0.0, CX, 0.0, 0.0, FY * 0.8, CY, 0.0, 0.0, 0.0, 1.0, 0.0]
    return CameraInfo(
        header=Header(stamp=Time(sec=1, nanosec=0), frame_id="camera_optical"),
        height=H,
        width=W,
        distortion_model="plumb_bob",
        d=np.array(d, dtype=np.float64),
        k=np.array(k),
        r=np.eye(3).reshape(-1),
        p=np.array(p),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def import_open3d() -> Any:
    """Import Open3D, or return None. Stubs ``dash`` if absent (only its web viewer needs it)."""
    if "dash" not in sys.modules:
        try:
            import dash  # type: ignore[import-not-found]  # noqa: F401
        except ImportError:
            html, dcc = types.ModuleType("dash.html"), types.ModuleType("dash.dcc")
            stub = types.ModuleType("dash")
            stub.__dict__.update(html=html, dcc=dcc, Dash=object)
            sys.modules.update({"dash": stub, "dash.html": html, "dash.dcc": dcc})
    try:
        import open3d as o3d
    except ImportError as exc:
        print(f"  (Open3D not importable: {exc})")
        return None
    return o3d


def bench_rectify() -> None:
    print("rectification, 640x480, plumb_bob, fixed-point maps, bilinear")
    model = PinholeCameraModel.from_camera_info(camera_info([-0.28, 0.07, 0.0005, -0.0003, 0.0]))
    maps = model.rectification_maps()
    assert maps is not None
    map1, map2 = maps
    rng = np.random.default_rng(0)
    for name, image in (
        ("rgb8 ", rng.integers(0, 255, (H, W, 3), dtype=np.uint8)),
        ("mono8", rng.integers(0, 255, (H, W), dtype=np.uint8)),
        ("32FC1", rng.random((H, W), dtype=np.float32)),
    ):
        border = float("nan") if image.dtype == np.float32 else 0.0

        def bare(image: np.ndarray = image, border: float = border) -> Any:
            return cv2.remap(
                image,
                map1,
                map2,
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=border,
            )

        ours, bare_ms = paired_ms(lambda image=image: model.rectify_image(image), bare)
        print(
            f"  {name}: rectify_image {ours:.3f} ms, bare cv2.remap {bare_ms:.3f} ms, "
            f"ratio {ours / bare_ms:.2f}x (target <= 1.2x)"
        )
    start = time.perf_counter()
    PinholeCameraModel.from_camera_info(
        camera_info([-0.28, 0.07, 0.0, 0.0, 0.0])
    ).rectification_maps()
    build_ms = (time.perf_counter() - start) * 1e3
    print(f"  first call (map build, once per camera_info): {build_ms:.1f} ms")


def bench_cloud() -> None:
    print("depth -> point cloud, 640x480, 10% invalid pixels")
    info = camera_info([0.0] * 5)
    model = PinholeCameraModel.from_camera_info(info)
    rng = np.random.default_rng(1)
    metres = (0.5 + 4.0 * rng.random((H, W))).astype(np.float32)
    metres[rng.random((H, W)) < 0.1] = np.nan
    mm = np.nan_to_num(metres * 1000.0, nan=0.0).astype(np.uint16)
    mm_msg = numpy_to_image(mm, "16UC1", header=info.header)
    converter = PointCloudXyz()
    converter.convert(mm_msg, info)

    us = (np.arange(W, dtype=np.float32) - np.float32(model.cx)) / np.float32(model.fx)
    vs = (np.arange(H, dtype=np.float32) - np.float32(model.cy)) / np.float32(model.fy)

    def bare_numpy() -> np.ndarray:
        z = mm.astype(np.float32) * np.float32(0.001)
        z[mm == 0] = np.nan
        return np.stack((z * us, z * vs[:, None], z), axis=-1)

    ours_f = median_ms(lambda: depth_to_points(metres, model))
    ours_mm, ref_np = paired_ms(lambda: depth_to_points(mm, model), bare_numpy)
    print(f"  depth_to_points 32FC1 -> (H,W,3): {ours_f:.3f} ms")
    print(f"  depth_to_points 16UC1 -> (H,W,3): {ours_mm:.3f} ms")
    print(f"  bare numpy (np.stack) 16UC1: {ref_np:.3f} ms; ratio {ours_mm / ref_np:.2f}x")
    o3d = import_open3d()
    if o3d is None:
        ours_msg = median_ms(lambda: converter.convert(mm_msg, info))
        print(f"  PointCloudXyz.convert 16UC1 Image -> PointCloud2: {ours_msg:.3f} ms")
        print("  Open3D unavailable: the ratio above is to the bare numpy reference")
        return
    intrinsic = o3d.camera.PinholeCameraIntrinsic(W, H, FX, FY, CX, CY)

    def open3d_cloud() -> Any:
        return o3d.geometry.PointCloud.create_from_depth_image(
            o3d.geometry.Image(mm), intrinsic, depth_scale=1000.0, depth_trunc=1e6
        )

    ours_pts, ref_o3d = paired_ms(lambda: depth_to_points(mm, model), open3d_cloud)
    ours_msg, ref_o3d2 = paired_ms(lambda: converter.convert(mm_msg, info), open3d_cloud)
    n_o3d = len(open3d_cloud().points)
    print(
        f"  Open3D {o3d.__version__} create_from_depth_image 16UC1: {ref_o3d:.3f} ms ({n_o3d} pts)"
    )
    print(f"  ratio to Open3D: depth_to_points {ours_pts:.3f} ms = {ours_pts / ref_o3d:.2f}x")
    print(
        f"  ratio to Open3D: PointCloudXyz.convert Image -> PointCloud2 {ours_msg:.3f} ms = "
        f"{ours_msg / ref_o3d2:.2f}x (target <= 1.0x)"
    )


def bench_scan() -> None:
    print("depth -> LaserScan, 640x480, scan_height 10")
    info = camera_info([0.0] * 5)
    rng = np.random.default_rng(2)
    metres = (0.5 + 4.0 * rng.random((H, W))).astype(np.float32)
    metres[rng.random((H, W)) < 0.05] = np.nan
    metres[rng.random((H, W)) < 0.02] = np.inf
    mm = np.nan_to_num(metres * 1000.0, nan=0.0, posinf=0.0).astype(np.uint16)
    converter = DepthImageToLaserScan(scan_height=10)
    for name, array, encoding in (("32FC1", metres, "32FC1"), ("16UC1", mm, "16UC1")):
        msg = numpy_to_image(array, encoding, header=info.header)
        converter.convert(msg, info)
        full = median_ms(lambda msg=msg: converter.convert(msg, info), repeat=500)
        geometry = converter.geometry(info, W, array.dtype)
        rows = array[234:244]
        core = median_ms(
            lambda rows=rows, geometry=geometry: depth_rows_to_ranges(
                rows, geometry, range_min=0.45, range_max=10.0
            ),
            repeat=500,
        )
        print(
            f"  {name}: convert(Image, CameraInfo) {full:.3f} ms, numpy core {core:.3f} ms "
            "(target <= 1 ms)"
        )


def main() -> None:
    bench_rectify()
    bench_cloud()
    bench_scan()


if __name__ == "__main__":
    main()
