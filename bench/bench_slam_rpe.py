"""Frame-to-frame precision of visnav's RGB-D SLAM against OpenCV's ICP odometry.

Run: ``python bench/bench_slam_rpe.py [--frames N] [--seed S] [--runs R] [--ideal-sensors]``.

Records a TUM RGB-D folder from the simulator first (not timed; cached under
``--folder``): the built-in ``car`` in the ``office`` world, its registered RGB-D
camera (``depth_camera``: rgb8 + depth, 640 x 480, 20 Hz), with the robot
description's sensor noise on (gaussian colour noise, Kinect-style disparity depth
noise) unless ``--ideal-sensors``. The car is moved kinematically along a corridor
drive (straight, a quarter turn, straight; a slight steering wobble) at 0.5 m/s, one
frame every 50 ms; the ground truth is the optical frame's pose in the world.

Then, on the frames read back with :class:`visnav.slam.tum.TumSequence`:

* visnav's :class:`~visnav.slam.SlamSystem`: once with features only
  (``icp_refinement=False``, the state before issue 14 item 5) and ``R`` times with the
  default dense ICP refinement (the trajectories must be identical: determinism),
  timing tracking (features + matching + pose) per frame; ``depth_noise`` 0.002 (a
  Kinect-like sensor's ``sigma_z / z^2``; 0.0004 with ``--ideal-sensors``);
* the reference measured in the same run: OpenCV's ICP odometry
  (``cv2.rgbd.RgbdICPOdometry`` in OpenCV 4 contrib, ``cv2.Odometry`` with
  ``OdometryType_DEPTH`` in OpenCV 5), frame to frame, chained from the first
  ground-truth pose. opencv-contrib is a bench-only dependency.

Prints ATE (SE(3)-aligned RMSE, ``evo_ape -a``) and RPE (consecutive frames,
translation RMSE, ``evo_rpe``) of both, the ratios, and the frames per second.
Acceptance (issue 14 item 5): visnav's RPE <= 1.5x the reference's, lower ATE.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from visnav.slam import SlamConfig, SlamSystem, Trajectory, ate
from visnav.slam.evaluation import rpe
from visnav.slam.trajectory import read_tum, write_tum
from visnav.slam.tum import TumSequence

FloatArray = NDArray[np.float64]
TRACKING = ("features", "matching", "pose")
RATE_HZ = 20.0
SPEED = 0.5


def _path_pose(s: float) -> tuple[float, float, float]:
    """Planar pose (x, y, yaw) of the car after ``s`` metres of the corridor drive."""
    x0, y0, straight, radius = -6.0, -1.5, 3.5, 1.0
    arc = radius * math.pi / 2
    if s <= straight:
        x, y, yaw = x0, y0 + s, math.pi / 2
    elif s <= straight + arc:
        a = (s - straight) / radius  # right turn: centre at (x0 + r, y0 + straight)
        x = x0 + radius - radius * math.cos(a)
        y = y0 + straight + radius * math.sin(a)
        yaw = math.pi / 2 - a
    else:
        d = s - straight - arc
        x, y, yaw = x0 + radius + d, y0 + straight + radius, 0.0
    return x, y, yaw + math.radians(2.0) * math.sin(2 * math.pi * s / 1.7)


def record(folder: Path, n: int, *, seed: int, ideal: bool) -> Path:
    """Render ``n`` frames of the car's RGB-D camera into a TUM folder (cached)."""
    import mujoco

    from visnav.graph import Context
    from visnav.perception.camera_info_yaml import write_camera_info_yaml
    from visnav.sim.plugins import CameraPlugin
    from visnav.sim.simulator import RobotSpawn, Simulator

    if (folder / "groundtruth.txt").is_file():
        return folder
    (folder / "rgb").mkdir(parents=True, exist_ok=True)
    (folder / "depth").mkdir(parents=True, exist_ok=True)
    robot: Any = RobotSpawn(source="car", args={"ideal_sensors": "true"}) if ideal else "car"
    sim = Simulator("office", [robot], context=Context(domain=48213), seed=seed)
    try:
        car = sim.robot()
        cam = next(p for p in car.plugins if isinstance(p, CameraPlugin) and p.spec.kind == "depth")
        model, data = sim.model, sim.data
        joint = model.joint(car.handles.free_joint)
        adr = int(joint.qposadr[0])
        z = float(data.qpos[adr + 2])
        body = model.body(car.handles.bodies["depth_camera_optical_frame"]).id
        rgb_lines, depth_lines = ["# color images"], ["# depth maps"]
        stamps, poses = [], []
        for i in range(n):
            x, y, yaw = _path_pose(i * SPEED / RATE_HZ)
            data.qpos[adr : adr + 7] = [x, y, z, math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)]
            data.qvel[:] = 0
            mujoco.mj_forward(model, data)
            t = 1000.0 + i / RATE_HZ
            frame = cam.sensor.render(data, stamp_ns=round(t * 1e9))
            assert frame.color is not None
            assert frame.depth is not None
            name = f"{t:.6f}.png"
            cv2.imwrite(str(folder / "rgb" / name), cv2.cvtColor(frame.color, cv2.COLOR_RGB2BGR))
            d16 = np.rint(np.nan_to_num(frame.depth, nan=0.0, posinf=0.0) * 5000.0)
            cv2.imwrite(str(folder / "depth" / name), np.clip(d16, 0, 65535).astype(np.uint16))
            rgb_lines.append(f"{t:.6f} rgb/{name}")
            depth_lines.append(f"{t:.6f} depth/{name}")
            pose = np.eye(4)
            pose[:3, :3] = data.xmat[body].reshape(3, 3)
            pose[:3, 3] = data.xpos[body]
            stamps.append(t)
            poses.append(pose)
        write_camera_info_yaml(folder / "camera_info.yaml", frame.camera_info, camera_name="car")
    finally:
        sim.close()
    (folder / "rgb.txt").write_text("\n".join(rgb_lines) + "\n", encoding="utf-8")
    (folder / "depth.txt").write_text("\n".join(depth_lines) + "\n", encoding="utf-8")
    write_tum(
        folder / "groundtruth.txt", Trajectory.from_matrices(np.array(stamps), np.stack(poses))
    )
    return folder


def _icp_odometry(
    frames: list[tuple[float, NDArray[np.uint8], NDArray[np.float32]]],
    k: FloatArray,
    start: FloatArray,
) -> tuple[Trajectory, list[float]]:
    """OpenCV's ICP odometry frame to frame, chained from ``start``; per-frame seconds."""
    settings = cv2.OdometrySettings()
    settings.setCameraMatrix(k.astype(np.float32))
    settings.setMaxDepth(8.0)  # the sensor reaches 10 m; OpenCV defaults to 4 m
    odo = cv2.Odometry(cv2.OdometryType_DEPTH, settings, cv2.OdometryAlgoType_COMMON)
    poses = [start]
    times: list[float] = []
    prev = None
    for _, rgb, depth in frames:
        t0 = time.perf_counter()
        cur = cv2.OdometryFrame(np.nan_to_num(depth), cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
        odo.prepareFrame(cur)
        if prev is not None:
            ok, rt = odo.compute(prev, cur)
            times.append(time.perf_counter() - t0)
            step = np.asarray(rt, dtype=np.float64) if ok else np.eye(4)
            poses.append(poses[-1] @ np.linalg.inv(step))  # rt maps prev-camera points to cur
        prev = cur
    stamps = np.array([t for t, _, _ in frames])
    return Trajectory.from_matrices(stamps, np.stack(poses)), times


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=280)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--ideal-sensors", action="store_true")
    parser.add_argument("--folder", type=Path, default=None)
    args = parser.parse_args()
    noise = "ideal" if args.ideal_sensors else "noisy"
    folder = args.folder or Path(f"/tmp/visnav_bench_slam_rpe_{noise}_{args.seed}_{args.frames}")
    t0 = time.perf_counter()
    record(folder, args.frames, seed=args.seed, ideal=args.ideal_sensors)
    print(f"sequence {folder} ({noise} sensors), ready in {time.perf_counter() - t0:.1f} s")
    seq = TumSequence(folder)
    cam = seq.find_intrinsics()
    assert cam is not None
    gt = read_tum(folder / "groundtruth.txt")
    frames = [(f.stamp, rgb, depth.astype(np.float32) / 5000.0) for f, rgb, depth in seq.images()]
    for _, _, d in frames:
        d[d == 0] = np.nan
    start = gt.matrices()[0]

    results: dict[str, dict[str, float]] = {}
    depth_noise = 0.0004 if args.ideal_sensors else 0.002  # Kinect-like: ~0.0016-0.0025 z^2
    same = True
    kf_ms: list[float] = []
    total_ms: list[float] = []
    for name, icp, runs in (("features", False, 1), ("visnav", True, args.runs)):
        track_ms: list[float] = []
        trajs: list[Trajectory] = []
        for _ in range(runs):
            cfg = SlamConfig(depth_scale=1.0, depth_noise=depth_noise, icp_refinement=icp)
            slam = SlamSystem(cam, cfg, initial_pose=start)
            for stamp, rgb, depth in frames:
                t = time.perf_counter()
                res = slam.track(rgb, depth, round(stamp * 1e9))
                if icp:
                    total_ms.append((time.perf_counter() - t) * 1e3)
                track_ms.append(sum(res.timings[k] for k in TRACKING) * 1e3)
                if res.keyframe and icp:
                    kf_ms.append((res.timings["mapping"] + res.timings["loop"]) * 1e3)
            slam.finish()
            trajs.append(slam.trajectory())
        if icp:
            same = all(
                len(t) == len(trajs[0]) and np.array_equal(t.positions, trajs[0].positions)
                for t in trajs
            )
        est = trajs[0]
        results[name] = {
            "ate": ate(est, gt, align=True).rmse,
            "rpe": rpe(est, gt).rmse,
            "rpe_deg": rpe(est, gt, pose_relation="angle_deg").rmse,
            "tracked": len(est),
            "ms": statistics.median(track_ms),
        }
    k = np.array([[cam.fx, 0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1]], dtype=np.float64)
    ref, icp_times = _icp_odometry(frames, k, start)
    results["opencv_icp"] = {
        "ate": ate(ref, gt, align=True).rmse,
        "rpe": rpe(ref, gt).rmse,
        "rpe_deg": rpe(ref, gt, pose_relation="angle_deg").rmse,
        "tracked": len(ref),
        "ms": statistics.median(icp_times) * 1e3,
    }
    print(f"{len(frames)} frames {cam.width}x{cam.height} at {RATE_HZ:g} Hz, {SPEED} m/s")
    print(
        f"{'method':<11} {'ATE mm':>8} {'RPE mm':>8} {'RPE deg':>8} {'frames':>7} {'ms/frame':>9}"
    )
    for name, r in results.items():
        print(
            f"{name:<11} {r['ate'] * 1e3:>8.2f} {r['rpe'] * 1e3:>8.3f} {r['rpe_deg']:>8.4f} "
            f"{int(r['tracked']):>7} {r['ms']:>9.2f}"
        )
    v, o, f = results["visnav"], results["opencv_icp"], results["features"]
    print(
        f"visnav / OpenCV ICP: RPE {v['rpe'] / o['rpe']:.2f}x (target <= 1.5), "
        f"ATE {v['ate'] / o['ate']:.2f}x (target < 1)"
    )
    print(
        f"visnav tracking median {v['ms']:.2f} ms = {1e3 / v['ms']:.1f} frames/s (target >= 30; "
        f"features only {f['ms']:.2f} ms = {1e3 / f['ms']:.1f} frames/s); "
        f"mapping + loop per keyframe median {statistics.median(kf_ms):.1f} ms; "
        f"overall mean {statistics.fmean(total_ms):.1f} ms per frame"
    )
    print(f"determinism: {args.runs} runs {'identical' if same else 'DIFFER'}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
