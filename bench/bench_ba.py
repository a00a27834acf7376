"""Local bundle adjustment: visnav's compiled solver against gtsam's on the same windows.

Run: ``python bench/bench_ba.py [--frames N] [--window W] [--repeats R]``. Maps a synthetic
640 x 480 RGB-D sequence with 1000 features and no bundle adjustment (not timed), then takes
every ``--stride``-th keyframe's local window as the SLAM system builds it (the keyframe and
its ``W - 1`` best covisibles free, every other keyframe seeing their points held) and solves
each window, from the same copy of the map, with both solvers (``ba_iterations`` 4, as the SLAM
runs): the median milliseconds per window over ``R`` repeats, the ratio gtsam / compiled, and
the agreement of the results (relative final error, largest pose difference).

Reference measured in the same run: gtsam's Levenberg-Marquardt on the same factor graph
(``optimizer._solve_gtsam``, which the compiled solver replaced for local windows).
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time

import numpy as np

from visnav.slam import SlamConfig, SlamSystem
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.optimizer import bundle_adjustment
from visnav.slam.synthetic import SyntheticRoom, circle_trajectory

CAM = CameraIntrinsics(500.0, 500.0, 319.5, 239.5, 640, 480)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--window", type=int, default=8)
    parser.add_argument("--stride", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    room = SyntheticRoom(seed=1)
    poses = circle_trajectory(args.frames, turns=1.15 * args.frames / 150)
    cfg = SlamConfig(n_features=1000, local_ba=False, loop_closure=False, seed=0)
    slam = SlamSystem(CAM, cfg, initial_pose=poses[0])
    for i, pose in enumerate(poses):
        rgb, depth = room.render(CAM, pose)
        slam.track(rgb, depth, 1_000_000_000 + i * 50_000_000)
    m = slam.map
    levels = slam.extractor.inv_level_sigma2
    kfs = [kf.id for kf in m.keyframes][args.window :: args.stride]
    print(
        f"{args.frames} frames, {len(m.keyframes)} keyframes, {len(kfs)} windows of {args.window}"
    )
    times: dict[str, list[float]] = {"compiled": [], "gtsam": []}
    rel_err: list[float] = []
    pose_diff: list[float] = []
    sizes: list[tuple[int, int]] = []
    for k in kfs:
        window = [k, *m.keyframes[k].best_covisibles(args.window - 1)]
        outs = {}
        for name, dense in (("compiled", 10_000), ("gtsam", 0)):
            per = []
            for _ in range(args.repeats):
                mm = copy.deepcopy(m)
                t = time.perf_counter()
                r = bundle_adjustment(
                    mm,
                    slam.camera,
                    window,
                    inv_sigma2_levels=levels,
                    iterations=4,
                    max_dense_keyframes=dense,
                )
                per.append(time.perf_counter() - t)
            times[name].append(statistics.median(per))
            outs[name] = (mm, r)
        (mc, rc), (mg, rg) = outs["compiled"], outs["gtsam"]
        sizes.append((rc.points, rc.observations))
        rel_err.append(abs(rc.error_after - rg.error_after) / max(rg.error_after, 1e-12))
        pose_diff.append(
            max(
                float(np.linalg.norm(mc.keyframes[i].t_cw[:3, 3] - mg.keyframes[i].t_cw[:3, 3]))
                for i in window
            )
        )
    med = {k: statistics.median(v) * 1e3 for k, v in times.items()}
    pts = statistics.median(s[0] for s in sizes)
    obs = statistics.median(s[1] for s in sizes)
    print(f"window: median {pts:.0f} points, {obs:.0f} observations")
    print(f"compiled: {med['compiled']:.1f} ms per window (median)")
    print(f"gtsam:    {med['gtsam']:.1f} ms per window (median)")
    print(f"ratio gtsam / compiled: {med['gtsam'] / med['compiled']:.1f}x")
    print(
        f"agreement: final error differs by {100 * max(rel_err):.2f} % at most, "
        f"poses by {1e3 * max(pose_diff):.3f} mm at most"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
