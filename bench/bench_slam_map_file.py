"""Saving and loading the SLAM map file (``database_path``): time and size.

Run: ``python bench/bench_slam_map_file.py [MAP.npz] [--runs R]``.

With a saved map (e.g. a car run's ``slam_map.npz``) its map is loaded once and then, ``R``
times each (median printed):

* ``save_slam_map`` (``.npz`` deflated at zlib level 1: the node's shutdown save) and
  ``load_slam_map`` (read, every check, rebuild of the ``SlamMap``);
* the references measured in the same run: ``np.savez`` / ``np.load`` of the same arrays
  uncompressed and without checks (the floor of any numpy-based format), and
  ``np.savez_compressed`` (zlib level 6).

Without a path a map is built first from a synthetic sequence (150 frames around the
textured box room, one loop; not timed). Prints sizes, medians and the ratios.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from visnav.slam import SlamConfig, SlamSystem
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.map_file import SavedSlamMap, load_slam_map, save_slam_map
from visnav.slam.synthetic import SyntheticRoom, circle_trajectory


def _synthetic() -> SavedSlamMap:
    cam = CameraIntrinsics(250.0, 250.0, 159.5, 119.5, 320, 240)
    room = SyntheticRoom(seed=1)
    poses = circle_trajectory(150, turns=1.15)
    cfg = SlamConfig(n_features=600, vocabulary_keyframes=6, loop_min_inliers=30)
    system = SlamSystem(cam, cfg, initial_pose=poses[0])
    for i, pose in enumerate(poses):
        rgb, depth = room.render(cam, pose)
        system.track(rgb, depth, 1_000_000_000 + i * 33_333_333)
    return SavedSlamMap(system.map, system.camera, list(system.loops), 1)


def _median(fn: Any, runs: int) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("map", nargs="?", help="a saved SLAM map (default: built synthetic)")
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args(argv)
    saved = load_slam_map(args.map) if args.map else _synthetic()
    m = saved.map
    print(f"map: {len(m.keyframes)} keyframes, {m.n_points} map points "
          f"({'from ' + args.map if args.map else 'synthetic'})")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.npz"
        ref = Path(tmp) / "ref.npz"

        def save() -> None:
            save_slam_map(m, path, camera=saved.camera, loops=saved.loops)

        save()
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}

        def save_ref() -> None:
            with ref.open("wb") as f:
                np.savez(f, **arrays)

        def load_ref() -> None:
            with np.load(ref, allow_pickle=False) as npz:
                for k in npz.files:
                    npz[k]

        def save_z6() -> None:
            with (Path(tmp) / "z6.npz").open("wb") as f:
                np.savez_compressed(f, **arrays)

        save_ref()
        t_z6 = _median(save_z6, args.runs)
        size_z6 = (Path(tmp) / "z6.npz").stat().st_size
        t_save, t_save_ref = _median(save, args.runs), _median(save_ref, args.runs)
        t_load = _median(lambda: load_slam_map(path), args.runs)
        t_load_ref = _median(load_ref, args.runs)
        size, size_ref = path.stat().st_size, ref.stat().st_size
    print(f"size: {size / 1e6:.2f} MB compressed, {size_ref / 1e6:.2f} MB uncompressed "
          f"(ratio {size / size_ref:.2f})")  # fmt: skip
    print(f"save: {t_save * 1e3:.1f} ms median of {args.runs} (np.savez uncompressed "
          f"{t_save_ref * 1e3:.1f} ms, ratio {t_save / t_save_ref:.1f})")  # fmt: skip
    print(f"np.savez_compressed (level 6): {t_z6 * 1e3:.1f} ms, {size_z6 / 1e6:.2f} MB "
          f"(save ratio to it {t_save / t_z6:.2f}, size ratio {size / size_z6:.3f})")  # fmt: skip
    print(f"load: {t_load * 1e3:.1f} ms median of {args.runs} (np.load, no checks "
          f"{t_load_ref * 1e3:.1f} ms, ratio {t_load / t_load_ref:.1f})")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
