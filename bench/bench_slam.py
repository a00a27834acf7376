"""RGB-D SLAM benchmark at 640 x 480 on a synthetic textured room (exact depth).

Run: ``python bench/bench_slam.py [--frames N] [--runs R] [--no-icp]``. Renders a loop of
frames first (not timed), then runs SLAM ``R`` times over them and prints, per
stage, the median milliseconds per frame (features, matching, pose for every
frame; mapping and loop on keyframes, also averaged over all frames), the
tracking rate (features + matching + pose; target >= 30 frames/s), the overall
rate with mapping in the same thread, and the ATE against the ground truth.

Reference measured in the same run: OpenCV ``ORB.detectAndCompute`` with 1000
features on the same images (what feature extraction costs at least), and the
ratio of visnav's tracking time to it.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import cv2
import numpy as np

from visnav.slam import SlamConfig, SlamSystem, Trajectory, ate
from visnav.slam.camera import CameraIntrinsics
from visnav.slam.synthetic import SyntheticRoom, circle_trajectory

W, H = 640, 480
CAM = CameraIntrinsics(500.0, 500.0, 319.5, 239.5, W, H)
TRACKING = ("features", "matching", "pose")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument(
        "--mono", action="store_true", help="only compare monocular with RGB-D (see _mono)"
    )
    parser.add_argument(
        "--no-icp", action="store_true", help="features only (no dense ICP refinement)"
    )
    args = parser.parse_args()
    if args.mono:
        return _mono(args.frames, args.runs)
    n = args.frames
    room = SyntheticRoom(seed=1)
    poses = circle_trajectory(n, turns=1.15 * n / 150)
    t0 = time.perf_counter()
    frames = [room.render(CAM, p) for p in poses]
    stamps = (1_000_000_000 + np.arange(n) * 33_333_333).astype(np.int64)
    print(f"rendered {n} frames {W}x{H} in {time.perf_counter() - t0:.1f} s")

    orb = cv2.ORB.create(1000)
    grays = [cv2.cvtColor(f[0], cv2.COLOR_RGB2GRAY) for f in frames]
    ref_times = []
    for g in grays[: min(n, 60)]:
        t = time.perf_counter()
        orb.detectAndCompute(g, None)
        ref_times.append(time.perf_counter() - t)
    ref_ms = statistics.median(ref_times) * 1e3

    per_stage: dict[str, list[float]] = {s: [] for s in (*TRACKING, "mapping", "loop")}
    totals: list[float] = []
    tracking: list[float] = []
    kf_mapping: list[float] = []
    ate_rmse: list[float] = []
    for _ in range(args.runs):
        cfg = SlamConfig(final_global_ba=False, icp_refinement=not args.no_icp)
        slam = SlamSystem(CAM, cfg, initial_pose=poses[0])
        for (rgb, depth), t in zip(frames, stamps, strict=True):
            start = time.perf_counter()
            result = slam.track(rgb, depth, int(t))
            totals.append(time.perf_counter() - start)
            for k, values in per_stage.items():
                values.append(result.timings[k])
            tracking.append(sum(result.timings[k] for k in TRACKING))
            if result.keyframe:
                kf_mapping.append(result.timings["mapping"] + result.timings["loop"])
        gt = Trajectory.from_matrices(stamps * 1e-9, poses)
        ate_rmse.append(ate(slam.trajectory(), gt).rmse)
        loops = len(slam.loops)
        kfs = len(slam.map.keyframes)

    med = {k: statistics.median(v) * 1e3 for k, v in per_stage.items()}
    mean = {k: statistics.fmean(v) * 1e3 for k, v in per_stage.items()}
    track_ms = statistics.median(tracking) * 1e3
    total_ms = statistics.fmean(totals) * 1e3
    print(f"{'stage':<10} {'median ms':>10} {'mean ms':>9}")
    for k in per_stage:
        print(f"{k:<10} {med[k]:>10.2f} {mean[k]:>9.2f}")
    print(f"keyframes {kfs} of {n} frames, loops closed {loops}")
    print(f"per keyframe mapping + loop: median {statistics.median(kf_mapping) * 1e3:.1f} ms")
    print(f"reference ORB detectAndCompute (1000 features): {ref_ms:.2f} ms")
    print(
        f"tracking (features + matching + pose): median {track_ms:.2f} ms = "
        f"{1e3 / track_ms:.1f} frames/s (target >= 30); {track_ms / ref_ms:.2f}x the reference"
    )
    print(
        f"overall incl. mapping in the same thread: mean {total_ms:.1f} ms = {1e3 / total_ms:.1f} frames/s"
    )
    print(f"ATE rmse (no alignment): {statistics.median(ate_rmse) * 100:.2f} cm")
    return 0


def _mono(n: int, runs: int) -> int:
    """Monocular (scale from depth at initialisation) next to RGB-D on the same frames.

    The camera looks outward from the circle (sideways motion, the parallax monocular
    initialisation and triangulation need); the default run's forward-looking camera
    loses monocular tracking. Prints tracking ms per frame (features + matching + pose),
    overall ms per frame, unaligned ATE and the Sim(3)-aligned ATE with its scale.
    """
    room = SyntheticRoom(seed=1)
    poses = circle_trajectory(n, turns=1.15 * n / 150, look_offset_deg=0.0)
    frames = [room.render(CAM, p) for p in poses]
    stamps = (1_000_000_000 + np.arange(n) * 33_333_333).astype(np.int64)
    gt = Trajectory.from_matrices(stamps * 1e-9, poses)
    print(f"rendered {n} frames {W}x{H}, camera looking outward")
    head = f"{'sensor':<6} {'track ms':>9} {'overall ms':>11} {'tracked':>8} {'lost':>5}"
    print(f"{head} {'ATE cm':>7} {'Sim3 ATE cm':>12} {'scale':>6}")
    for sensor in ("rgbd", "mono"):
        track: list[float] = []
        overall: list[float] = []
        for _ in range(runs):
            cfg = SlamConfig(final_global_ba=False, sensor=sensor)  # type: ignore[arg-type]
            slam = SlamSystem(CAM, cfg, initial_pose=poses[0])
            for (rgb, depth), t in zip(frames, stamps, strict=True):
                start = time.perf_counter()
                result = slam.track(rgb, depth, int(t))
                overall.append(time.perf_counter() - start)
                if result.state == "ok":
                    track.append(sum(result.timings[k] for k in TRACKING))
        traj = slam.trajectory()
        raw = ate(traj, gt).rmse
        sim3 = ate(traj, gt, align=True, scale=True)
        scale = sim3.alignment.scale if sim3.alignment is not None else float("nan")
        print(
            f"{sensor:<6} {statistics.median(track) * 1e3:>9.2f} "
            f"{statistics.fmean(overall) * 1e3:>11.1f} {len(traj):>8} {slam.n_lost:>5} "
            f"{raw * 100:>7.2f} {sim3.rmse * 100:>12.2f} {scale:>6.3f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
