"""The observer's summary keys and files, computed from what it collected.

:func:`car_results` and :func:`drone_results` give the task keys of ``summary.json``
(:mod:`visnav.scenarios.runner` lists them); :func:`write_outputs` writes the mapped
grid (``map.yaml`` + ``map.pgm``, map_saver's format) and the SLAM trajectories
(``slam_trajectory.tum``, ``ground_truth.tum``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.scenarios.observer_metrics import (
    FloatArray,
    interpolate_poses,
    path_length,
    pose_error,
    slam_metrics,
)
from visnav.tf.transforms import yaw_from_matrix

if TYPE_CHECKING:
    from visnav.scenarios.observer import ObserverNode
    from visnav.slam.trajectory import Trajectory

__all__ = [
    "SlamTrajectories",
    "car_results",
    "drone_results",
    "slam_trajectories",
    "write_outputs",
]

SlamTrajectories = tuple["Trajectory", "Trajectory", int]
"""``(estimate, ground truth at its stamps, poses tracked)``: :func:`slam_trajectories`."""


def _spawn(node: ObserverNode) -> tuple[float, float, float]:
    """The world's spawn pose: where encoder odometry starts (``map -> odom``)."""
    spawn = node.world.metadata.get("spawn")
    if isinstance(spawn, (list, tuple)) and len(spawn) >= 2:
        return float(spawn[0]), float(spawn[1]), float(spawn[2]) if len(spawn) >= 3 else 0.0
    return 0.0, 0.0, 0.0


def _odometry(node: ObserverNode) -> dict[str, Any]:
    source = node.params.odometry_source
    truth = np.asarray(node._truth or np.zeros((0, 3)))[:, :2]
    out: dict[str, Any] = {"source": source, "distance_m": round(path_length(truth), 3)}
    if not node._truth_poses or node._odom_pose is None:
        return {**out, "drift_m": None, "heading_drift_deg": None}
    x0, y0, yaw0 = _spawn(node) if source == "encoder" else (0.0, 0.0, 0.0)
    odom = node._odom_pose
    c, s = math.cos(yaw0), math.sin(yaw0)
    ox, oy = x0 + c * odom[0, 3] - s * odom[1, 3], y0 + s * odom[0, 3] + c * odom[1, 3]
    oyaw = yaw0 + yaw_from_matrix(odom)
    tx, ty, _ = node._truth[-1]
    tyaw = yaw_from_matrix(node._truth_poses[-1])
    out["drift_m"] = round(math.hypot(ox - tx, oy - ty), 4)
    out["heading_drift_deg"] = round(math.degrees(math.remainder(oyaw - tyaw, 2 * math.pi)), 3)
    return out


def _odometry_drift_m(node: ObserverNode) -> float | None:
    """Final ``odom -> base`` (TF) against ground truth, both anchored at the first sample."""
    if node._odom_tf is None:
        return None
    truth0, odom0, truth1, odom1 = node._odom_tf
    estimate = truth0 @ np.linalg.inv(odom0) @ odom1
    return round(pose_error(estimate, truth1)[0], 4)


def car_results(node: ObserverNode, slam: SlamTrajectories | None = None) -> dict[str, Any]:
    """The car's summary keys (goals, collisions, path, odometry, localization, SLAM).

    Args:
        node: the observer.
        slam: :func:`slam_trajectories` of ``node`` if already computed (else computed here
            when the node scores SLAM).
    """
    goals = node._goals[: node.params.goals]
    ended = [g for g in goals if g.ended]
    reached = [g for g in ended if g.reached]
    travelled = sum(g.travelled_m for g in reached)
    shortest = sum(g.shortest_m for g in reached)
    out: dict[str, Any] = {
        "goals_total": node.params.goals,
        "goals_reached": len(reached),
        "collisions": node._contacts.events,
        "path_length_m": round(travelled, 3),
        "shortest_path_m": round(shortest, 3),
        "path_ratio": round(travelled / shortest, 4) if shortest > 0 else None,
        "goal_times_s": [round(g.duration_s, 2) for g in ended],
        "odometry": _odometry(node),
        "odometry_drift_m": _odometry_drift_m(node),
    }
    if node.params.localization_source:
        out["localization"] = node._loc.summary(node.params.localization_source)
    if node.params.slam:
        out["slam"] = _slam(node, slam if slam is not None else slam_trajectories(node))
    if node.params.map_quality:
        out["map_quality"] = _map_quality(node)
    return out


def _map_quality(node: ObserverNode) -> dict[str, Any] | None:
    """:func:`~visnav.scenarios.map_quality.map_quality` of the last map (None: no map)."""
    from visnav.scenarios.map_quality import map_quality  # noqa: PLC0415 - only when asked

    grid = node._map
    if grid is None or not node._truth:
        return None
    info = grid.info
    data = np.asarray(grid.data, dtype=np.int8).reshape(info.height, info.width)
    start = (float(node._truth[0][0]), float(node._truth[0][1]))
    origin = (float(info.origin.position.x), float(info.origin.position.y))
    return map_quality(
        data,
        resolution=float(info.resolution),
        origin=origin,
        world=node.world,
        start=start,
        robot_radius=node.params.robot_radius,
    )


def drone_results(node: ObserverNode) -> dict[str, Any]:
    """The drone's summary keys (goal, collisions, clearance, speed, planning time)."""
    from visnav.sim.world_geometry import obstacle_distance  # noqa: PLC0415

    truth = node._truth
    flight = np.asarray(truth[node._flight_start :] or truth or [(math.nan,) * 3])
    goal = node._goals[0] if node._goals else None
    reached = bool(
        node.done
        and goal is not None
        and math.dist(flight[-1, :2].tolist(), (goal.x, goal.y)) < node.params.goal_tolerance
    )
    now = node.get_clock().now_ns()
    flight_s = (now - node._goal_sent_ns) / 1e9 if node._goal_sent_ns is not None else 0.0
    length = path_length(flight)
    times = node._planning_ms
    clearance = float(obstacle_distance(node.world, flight).min()) if truth else None
    return {
        "goals_total": node.params.goals,
        "goals_reached": int(reached),
        "collisions": node._contacts.events,
        "min_clearance_m": round(clearance, 4) if clearance is not None else None,
        "mean_speed_mps": round(length / flight_s, 4) if flight_s > 0 else 0.0,
        "path_length_m": round(length, 3),
        "planning_time_ms": {
            "median": round(float(np.median(times)), 3) if times else None,
            "p95": round(float(np.percentile(times, 95)), 3) if times else None,
            "max": round(float(np.max(times)), 3) if times else None,
        },
    }


def _tracked_poses(node: ObserverNode) -> list[tuple[int, FloatArray]]:
    """``(stamp ns, pose)`` of every tracked frame: the last ``slam/path`` + later poses."""
    last = node._slam_path[-1][0] if node._slam_path else -1
    return list(node._slam_path) + [sp for sp in node._slam_poses if sp[0] > last]


def slam_trajectories(node: ObserverNode) -> SlamTrajectories:
    """``(estimate, ground truth at its stamps, poses tracked)`` from the SLAM topics."""
    from visnav.slam.trajectory import Trajectory  # noqa: PLC0415

    poses = _tracked_poses(node)
    if not poses or len(node._truth_ns) < 2:
        return Trajectory.empty(), Trajectory.empty(), len(poses)
    stamps = np.array([s for s, _ in poses], dtype=np.int64)
    est = Trajectory.from_matrices(stamps * 1e-9, np.stack([m for _, m in poses]))
    idx, gt = interpolate_poses(
        np.asarray(node._truth_ns, dtype=np.int64), np.stack(node._truth_poses), stamps
    )
    if len(idx) == 0:
        return Trajectory.empty(), Trajectory.empty(), len(poses)
    return est.subset(idx), Trajectory.from_matrices(est.stamps[idx], gt), len(poses)


def _slam(node: ObserverNode, trajectories: SlamTrajectories) -> dict[str, Any]:
    est, gt, tracked = trajectories
    out: dict[str, Any] = slam_metrics(est, gt)
    out.update({"tracked": tracked, "evaluated": len(est)})
    for key in _SLAM_COUNTERS:
        value = _counter(node, key)
        if value is not None:
            out[key] = int(value) if value.is_integer() and key != "cpu_s" else round(value, 2)
    # The counters are as of the SLAM node's last status (every diagnostic_period s): the
    # frames it tracked after the last frame they include are frames too, so that
    # ``tracked <= frames`` (frames lost after that status are not known).
    counted_upto = _counter(node, "last_frame_stamp_ns")
    if "frames" in out and counted_upto is not None:
        out["frames"] += sum(1 for stamp, _ in _tracked_poses(node) if stamp > counted_upto)
    return out


def _counter(node: ObserverNode, key: str) -> float | None:
    """The SLAM status value ``key`` as a finite number (None: absent or not a number)."""
    text = node._slam_counters.get(key)
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


_SLAM_COUNTERS = (
    "frames",
    "tracking_lost",
    "relocalized",
    "reinitialized",
    "keyframes",
    "loop_closures",
    "skipped",
    "dropped",
    "cpu_s",
)
"""The SLAM node's ``/diagnostics`` counters copied into the ``slam`` summary key."""


def write_outputs(
    node: ObserverNode, out_dir: Path, slam: SlamTrajectories | None = None
) -> list[Path]:
    """Write the mapped grid and the SLAM trajectories (whatever the run produced).

    Args:
        node: the observer.
        out_dir: the run directory.
        slam: :func:`slam_trajectories` of ``node`` if already computed (else computed here
            when the node scores SLAM).
    """
    written: list[Path] = []
    if node._map is not None:
        from visnav.mapping.map_io import save_map  # noqa: PLC0415

        written.extend(save_map(node._map, out_dir / "map"))
    if node.params.slam:
        from visnav.slam.trajectory import write_tum  # noqa: PLC0415

        est, gt, _ = slam if slam is not None else slam_trajectories(node)
        written.append(
            write_tum(
                out_dir / "slam_trajectory.tum",
                est,
                header="visnav SLAM, base_footprint in map (car scenario)",
            )
        )
        written.append(
            write_tum(
                out_dir / "ground_truth.tum",
                gt,
                header="ground truth base_footprint in world at the SLAM stamps",
            )
        )
    return written
