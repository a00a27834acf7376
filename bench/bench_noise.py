"""Benchmark: the cost of the sensor error models and of the map files.

Rows (each a median of ``ROUNDS`` repeated batches, thread CPU time, so time spent
descheduled on a loaded machine is not counted; the reference is timed in the same
round right after visnav's):

* depth disparity noise (Kinect v1 model) on a 640x480 float32 depth image, against
  the gaussian additive depth noise the simulator applied before
  (``out += rng.normal(...).astype(float32)``): the price per depth frame at 20 Hz;
* one encoder odometry update with the wheel error model (quantisation, radius
  factors, slip) against the exact update: the price per physics step (500 Hz);
* ``load_map`` of a 400 x 400 map_saver PGM + YAML (parse, check, map_server's
  thresholds, flip) against ``yaml.safe_load`` of the YAML plus ``cv2.imread`` of the
  PGM (what a minimal loader without checks or thresholds does), and the image part
  alone (``read_pgm`` + ``pixels_to_grid`` against ``cv2.imread``);
* ``save_map`` of a 400 x 400 OccupancyGrid (PGM + YAML) against ``cv2.imwrite``
  of the same pixels as a PGM alone.

Run: python bench/bench_noise.py
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import yaml

from visnav.description.noise_specs import DepthNoise, WheelOdometryNoise
from visnav.mapping.map_io import (
    MapMetadata,
    OccupancyMap,
    grid_to_pgm_pixels,
    load_map,
    pixels_to_grid,
    read_pgm,
    save_map,
)
from visnav.sim.noise_models import WheelEncoderModel, apply_depth_noise
from visnav.sim.vehicles.diff_drive import EncoderOdometry

ROUNDS = 15


def _time(fn: Callable[[], object], repeat: int) -> float:
    """Thread CPU seconds per call over ``repeat`` calls."""
    start = time.thread_time_ns()
    for _ in range(repeat):
        fn()
    return (time.thread_time_ns() - start) / 1e9 / repeat


def _row(name: str, ours: Callable[[], object], ref: Callable[[], object], repeat: int) -> None:
    mine, theirs = [], []
    for _ in range(ROUNDS):
        mine.append(_time(ours, repeat))
        theirs.append(_time(ref, repeat))
    m, r = statistics.median(mine), statistics.median(theirs)
    print(f"| {name} | {m * 1e6:,.1f} us | {r * 1e6:,.1f} us | {m / r:.2f}x |")


def main() -> None:
    """Print the table."""
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.3, 8.0, (480, 640)).astype(np.float32)
    kinect = DepthNoise(disparity_stddev=0.07, disparity_step=0.125)

    def ours_depth() -> None:
        apply_depth_noise(depth.copy(), kinect, rng)

    def ref_depth() -> None:
        out = depth.copy()
        out += rng.normal(0.0, 0.01, size=out.shape).astype(np.float32)

    noisy = EncoderOdometry(
        0.36,
        0.08,
        model=WheelEncoderModel(
            WheelOdometryNoise(
                wheel_radius_error=0.003,
                wheel_separation_error=0.01,
                wheel_slip=0.005,
                encoder_resolution=4096,
            ),
            seed=0,
        ),
    )
    exact = EncoderOdometry(0.36, 0.08)
    angles = [0.0, 0.0]

    def step(odo: EncoderOdometry) -> Callable[[], None]:
        def go() -> None:
            angles[0] += 0.0125
            angles[1] += 0.0130
            odo.update(angles[0], angles[1], 0.002)

        return go

    grid = rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(400, 400))
    meta = MapMetadata(image=Path("map.pgm"), resolution=0.05, origin=(-10.0, -10.0, 0.0))
    msg = OccupancyMap(grid, meta).to_msg()
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "map"
        yaml_path, pgm_path = save_map(msg, base)
        pixels = grid_to_pgm_pixels(grid)
        ref_pgm = str(Path(tmp) / "ref.pgm")
        print("| row | visnav | reference | ratio |")
        print("|---|---|---|---|")
        _row("depth disparity noise 640x480 (vs additive gaussian)", ours_depth, ref_depth, 10)
        _row("encoder update with error model (vs exact)", step(noisy), step(exact), 20_000)
        _row(
            "load_map 400x400 PGM+YAML (vs yaml.safe_load + cv2.imread)",
            lambda: load_map(yaml_path),
            lambda: (
                yaml.safe_load(yaml_path.read_text()),
                cv2.imread(str(pgm_path), cv2.IMREAD_UNCHANGED),
            ),
            50,
        )
        _row(
            "PGM to grid 400x400: read_pgm + pixels_to_grid (vs cv2.imread PGM)",
            lambda: pixels_to_grid(read_pgm(pgm_path)[0], meta),
            lambda: cv2.imread(str(pgm_path), cv2.IMREAD_UNCHANGED),
            50,
        )
        _row(
            "save_map 400x400 (vs cv2.imwrite PGM)",
            lambda: save_map(msg, base),
            lambda: cv2.imwrite(ref_pgm, pixels),
            50,
        )


if __name__ == "__main__":
    main()
