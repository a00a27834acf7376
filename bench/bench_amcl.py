"""AMCL benchmarks on the office map: tracking from a known pose and global localisation.

Run: ``python bench/bench_amcl.py [--repeats 3] [--map PATH/map.yaml]``. The map is the
office's true occupancy grid at 0.05 m (or a saved map from a car run with ``--map``);
scans are exact ray casts on the true grid (87 degree field of view, 160 beams, 1 cm noise,
laser 0.1 m ahead of the base) along the office's corridor ring (36 m) from the car's spawn, and the
odometry drifts as the car's encoders (``car.urdf.xacro``: distance noise 0.5 %, turns
scaled by 1 % for the track error, 0.01 rad/m heading drift for unequal wheel radii). Printed, as medians over seeds:

* tracking from the spawn with a 0.3 m / 0.1 rad initial error (car configuration):
  RMSE and max of the map pose after the first 5 m, and the filter update time;
* the laser model (2000 particles x the scan's beams, the largest share of an update):
  the numba kernel against the same model in plain numpy (end points, bilinear lookup,
  ``pz^3``) measured in the same run;
* global localisation (5000 particles, recovery on): whether it converged to < 0.3 m and
  after how many metres.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.amcl import Amcl, AmclParams
from visnav.mapping.amcl_models import beam_endpoints, likelihood_field_weights, select_beams
from visnav.mapping.likelihood_field import LikelihoodField
from visnav.mapping.map_io import load_map
from visnav.sim.noise_models import DepthNoise, apply_depth_noise

ANGLES = np.linspace(-0.76, 0.76, 160)
LASER = (0.1, 0.0, 0.0)
CAR = {
    "laser_model_type": "likelihood_field_prob",
    "alpha1": 0.05, "alpha2": 0.05, "alpha3": 0.05, "alpha4": 0.05,
    "update_min_d": 0.1, "update_min_a": 0.1,
}  # fmt: skip
"""The car's configuration (car.launch.yaml)."""
NAV2_TIGHT = {**CAR, "laser_model_type": "likelihood_field", "sigma_hit": 0.1}
"""The same with amcl's default ``1 + sum(pz^3)`` laser model (its best sigma_hit here)."""
WAYPOINTS = [(-6.0, -1.5), (-6.0, 3.0), (6.0, 3.0), (6.0, -3.0), (-6.0, -3.0), (-6.0, -1.5)]
"""The office's corridor ring from the car's spawn (its free-space graph)."""


def true_grid() -> tuple[NDArray[np.bool_], tuple[float, float]]:
    """The office's true occupancy at 0.05 m and its origin."""
    from visnav.description.world import load_world
    from visnav.sim.world_geometry import true_occupancy_grid

    grid, origin = true_occupancy_grid(load_world("office"), 0.05)
    return grid, (float(origin[0]), float(origin[1]))


def raycast(
    grid: NDArray[np.bool_], origin: tuple[float, float], pose: tuple[float, float, float]
) -> NDArray[np.float64]:
    """Exact ranges along ``ANGLES`` to the first occupied cell (inf: none within 10 m)."""
    t = np.arange(0.01, 10.0, 0.01)
    theta = pose[2] + ANGLES
    col = np.floor((pose[0] + np.cos(theta)[:, None] * t - origin[0]) / 0.05).astype(int)
    row = np.floor((pose[1] + np.sin(theta)[:, None] * t - origin[1]) / 0.05).astype(int)
    ok = (col >= 0) & (col < grid.shape[1]) & (row >= 0) & (row < grid.shape[0])
    hit = np.zeros(col.shape, dtype=bool)
    hit[ok] = grid[row[ok], col[ok]]
    first = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)
    return np.where(first >= 0, t[np.maximum(first, 0)], math.inf)


def loop_poses(step: float = 0.05) -> list[tuple[float, float, float]]:
    """Poses along ``WAYPOINTS`` (turning in place at corners)."""
    out: list[tuple[float, float, float]] = []
    x, y = WAYPOINTS[0]
    yaw = math.pi / 2
    for tx, ty in WAYPOINTS[1:]:
        want = math.atan2(ty - y, tx - x)
        while abs(math.remainder(want - yaw, 2 * math.pi)) > 0.15:
            yaw += math.copysign(0.15, math.remainder(want - yaw, 2 * math.pi))
            out.append((x, y, yaw))
        yaw = want
        for _ in range(int(math.hypot(tx - x, ty - y) / step)):
            x, y = x + step * math.cos(yaw), y + step * math.sin(yaw)
            out.append((x, y, yaw))
        x, y = tx, ty
    return out


KINECT = DepthNoise(baseline=0.075, focal_length=580.0, disparity_stddev=0.07, disparity_step=0.125)
"""The car's depth noise (``car.urdf.xacro`` ``<depth_noise>``: Kinect v1 disparity noise)."""


def depth_scan(
    ranges: NDArray[np.float64], rng: np.random.Generator, scan_height: int
) -> NDArray[np.float64]:
    """The car's depth -> scan chain on exact ranges: Kinect noise, min over ``scan_height`` rows.

    Each beam's depth (``z = r cos(angle)``) is drawn ``scan_height`` times with the
    simulator's disparity noise (:func:`~visnav.sim.noise_models.apply_depth_noise`), and
    depthimage_to_laserscan keeps the shortest range (its ``use_point``).
    """
    cos = np.cos(ANGLES)
    z = np.repeat((ranges * cos)[None, :], scan_height, axis=0).astype(np.float32)
    finite = np.isfinite(z)
    z[~finite] = np.float32(1.0)
    apply_depth_noise(z, KINECT, rng)
    z[~finite] = np.inf
    out: NDArray[np.float64] = np.nanmin(z, axis=0).astype(np.float64) / cos
    return out


def run(
    amcl: Amcl,
    drive: list[tuple[tuple[float, float, float], NDArray[np.float64]]],
    seed: int,
    scan_height: int = 0,
) -> tuple[NDArray[np.float64], list[float], list[float]]:
    """Errors per step, update times (s) and the distance driven per step.

    ``scan_height`` 0: exact ranges plus 1 cm Gaussian noise; > 0: :func:`depth_scan`.
    """
    rng = np.random.default_rng(seed)
    odom = np.array(drive[0][0])
    prev = drive[0][0]
    errors, times, dist = [], [], []
    travelled = 0.0
    for truth, ranges in drive:
        dx, dy = truth[0] - prev[0], truth[1] - prev[1]
        c, s = math.cos(prev[2]), math.sin(prev[2])
        fwd, lat = c * dx + s * dy, -s * dx + c * dy
        turn = math.remainder(truth[2] - prev[2], 2 * math.pi)
        travelled += math.hypot(dx, dy)
        fwd *= 1 + rng.normal(0, 0.005)
        turn = turn * 1.01 + 0.01 * fwd
        co, so = math.cos(odom[2]), math.sin(odom[2])
        odom += (co * fwd - so * lat, so * fwd + co * lat, turn)
        prev = truth
        noisy = (
            depth_scan(ranges, rng, scan_height)
            if scan_height
            else ranges + rng.normal(0, 0.01, ranges.shape)
        )
        beams = select_beams(
            noisy, -0.76, float(ANGLES[1] - ANGLES[0]), range_min=0.1,
            range_max=min(10.0, amcl.params.laser_max_range), max_beams=60,
        )  # fmt: skip
        t0 = time.perf_counter()
        if amcl.update((odom[0], odom[1], odom[2]), beams, LASER):
            times.append(time.perf_counter() - t0)
        mo = amcl.map_to_odom()
        assert mo is not None
        cm, sm = math.cos(mo[2]), math.sin(mo[2])
        ex, ey = mo[0] + cm * odom[0] - sm * odom[1], mo[1] + sm * odom[0] + cm * odom[1]
        errors.append(math.hypot(ex - truth[0], ey - truth[1]))
        dist.append(travelled)
    return np.array(errors), times, dist


def laser_model_times(
    field: LikelihoodField,
    drive: list[tuple[tuple[float, float, float], NDArray[np.float64]]],
    repeats: int,
) -> tuple[float, float]:
    """Median seconds of the kernel and of the numpy form of the same laser model."""
    pose, ranges = drive[0]
    beams = select_beams(ranges, -0.76, float(ANGLES[1] - ANGLES[0]), range_min=0.1,
                         range_max=10.0, max_beams=60)  # fmt: skip
    poses = np.array(pose) + np.random.default_rng(0).normal(0.0, 0.3, (2000, 3))
    kw = {"z_hit": 0.5, "z_rand": 0.5, "sigma_hit": 0.1}
    likelihood_field_weights(field, poses, beams, LASER, **kw)  # compile (cached) once

    def numpy_model() -> NDArray[np.float64]:
        d = field.distance_at(beam_endpoints(poses, beams, LASER)).astype(np.float64)
        pz = 0.5 * np.exp(-d * d / (2 * 0.1**2)) + 0.5 / beams.range_max
        return np.asarray(1.0 + (pz**3).sum(axis=1))

    fast, slow = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        likelihood_field_weights(field, poses, beams, LASER, **kw)
        fast.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        numpy_model()
        slow.append(time.perf_counter() - t0)
    return statistics.median(fast), statistics.median(slow)


def main() -> None:
    """Print the medians (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="seeds per measurement")
    ap.add_argument("--map", default=None, help="a saved map.yaml (default: the true grid)")
    args = ap.parse_args()
    grid, origin = true_grid()
    if args.map:
        saved = load_map(args.map)
        field = LikelihoodField(
            saved.data, saved.metadata.resolution, saved.metadata.origin, max_dist=2.0
        )
    else:
        field = LikelihoodField(np.where(grid, 100, 0), 0.05, (*origin, 0.0), max_dist=2.0)
    poses = loop_poses()
    drive = []
    for p in poses:
        laser = (p[0] + LASER[0] * math.cos(p[2]), p[1] + LASER[0] * math.sin(p[2]), p[2])
        drive.append((p, raycast(grid, origin, laser)))
    print(f"tracking ({len(poses)} steps, {field.width}x{field.height} map, {args.repeats} seeds,"
          " medians after the first 5 m)")  # fmt: skip
    configs = {"car (likelihood_field_prob)": CAR, "likelihood_field, sigma 0.1": NAV2_TIGHT,
               "nav2 defaults": {}}  # fmt: skip
    for name, config in configs.items():
        rmse, peak, upd = [], [], []
        for seed in range(args.repeats):
            amcl = Amcl(field, AmclParams(seed=seed, **config))
            x, y, yaw = poses[0]
            amcl.set_initial_pose(x + 0.3, y - 0.2, yaw + 0.1)
            errors, times, dist = run(amcl, drive, seed)
            settled = errors[np.asarray(dist) > 5.0]
            rmse.append(float(np.sqrt(np.mean(settled**2))))
            peak.append(float(settled.max()))
            upd.append(statistics.median(times))
        print(f"  {name:30s} RMSE {statistics.median(rmse) * 100:5.1f} cm, max "
              f"{statistics.median(peak) * 100:5.1f} cm, update {statistics.median(upd) * 1e3:.1f} ms")  # fmt: skip
    print("depth-derived scans (the car's Kinect noise, depthimage_to_laserscan), car config:")
    for name, rows, config in (
        ("scan_height 10 (/scan)", 10, CAR),
        ("scan_height 10, laser_max_range 5", 10, {**CAR, "laser_max_range": 5.0}),
        ("scan_height 1 (/amcl/scan)", 1, CAR),
    ):
        rmse, peak = [], []
        for seed in range(args.repeats):
            amcl = Amcl(field, AmclParams(seed=seed, **config))
            x, y, yaw = poses[0]
            amcl.set_initial_pose(x + 0.3, y - 0.2, yaw + 0.1)
            errors, _, dist = run(amcl, drive, seed, scan_height=rows)
            settled = errors[np.asarray(dist) > 5.0]
            rmse.append(float(np.sqrt(np.mean(settled**2))))
            peak.append(float(settled.max()))
        print(f"  {name:34s} RMSE {statistics.median(rmse) * 100:5.1f} cm, max "
              f"{statistics.median(peak) * 100:5.1f} cm")  # fmt: skip
    kernel, numpy_ref = laser_model_times(field, drive, args.repeats * 5)
    print(f"laser model, 2000 particles: numba {kernel * 1e3:.2f} ms, numpy reference "
          f"{numpy_ref * 1e3:.2f} ms, ratio {kernel / numpy_ref:.3f}")  # fmt: skip
    ok, metres = 0, []
    for seed in range(args.repeats):
        params = AmclParams(
            seed=seed, max_particles=5000, recovery_alpha_slow=0.001,
            recovery_alpha_fast=0.1, **CAR,
        )  # fmt: skip
        amcl = Amcl(field, params)
        amcl.global_localization()
        errors, _, dist = run(amcl, drive, seed)
        good = np.nonzero(errors < 0.3)[0]
        # converged: from some step on, every later error stays < 0.3 m
        bad = np.nonzero(errors >= 0.3)[0]
        first = int(bad[-1]) + 1 if bad.size else 0
        if good.size and first < len(errors):
            ok += 1
            metres.append(dist[first])
    print(f"global localisation: converged in {ok}/{args.repeats} seeds", end="")
    print(f", after median {statistics.median(metres):.1f} m" if metres else "")


if __name__ == "__main__":
    main()
