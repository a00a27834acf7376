"""Visual SLAM on the car scenario: RGB-D SLAM on the depth camera, scored against ground truth.

:class:`CarSlamTask` starts a :class:`~visnav.slam.node.SlamNode` on the car's registered
RGB-D stream (``/depth_camera/image_raw`` rgb8, ``/depth_camera/depth/image_raw`` 32FC1,
``/depth_camera/camera_info``, 20 Hz), records ``/ground_truth/odom`` and, at the end of
the run, reports under the summary key ``slam``: ``ate_rmse_m`` (Umeyama SE(3)-aligned,
``evo_ape -a``), ``ate_unaligned_rmse_m``, ``rpe_trans_rmse_m`` and ``rpe_rot_rmse_deg``
(consecutive processed frames), ``frames`` (processed), ``tracked``, ``evaluated`` (tracked
frames within the ground truth's span), ``tracking_lost``
(processed frames without a pose after initialisation), ``relocalized``, ``keyframes``,
``loop_closures``, ``skipped`` (frames left out by the rate limit) and ``dropped``
(unusable inputs). :meth:`CarSlamTask.write_outputs` (called by the scenario runner)
writes ``slam_trajectory.tum`` and ``ground_truth.tum`` into the run directory, so
``visnav eval ate -a slam_trajectory.tum ground_truth.tum`` reproduces ``ate_rmse_m``.

Decisions, and why:

* **Frames.** Both trajectories are of ``base_footprint`` (the ground truth's child
  frame): the SLAM camera poses are moved to the base with the camera mounting from
  ``/tf_static``. The SLAM map frame starts at the ``map -> base_footprint`` pose of the
  first frame (the car task's static ``map -> odom``, the spawn pose, times the wheel
  odometry a fraction of a second after the start), so the SLAM map and the ground
  truth's ``world`` coincide at the start and the unaligned ATE is meaningful too. The
  ground truth (50 Hz) is interpolated at each SLAM frame stamp (linear position, slerp
  rotation), so the pairing is exact and ``ground_truth.tum`` has the SLAM stamps.
* **No ``map -> odom`` from SLAM here.** The navigation stack (mapper, costmaps,
  navigator) works in ``map`` with ``map -> odom`` the identity, because odometry is the
  simulator's ground truth: a SLAM correction could only add error to navigation, and
  the car's goal metrics (issue 7) would start depending on SLAM. ``odom`` can have one
  parent only, so SLAM cannot publish a second tree root (``slam_map -> odom``) either.
  The SLAM estimate therefore goes out on ``slam/pose`` and ``slam/path`` (frame ``map``,
  which it equals up to the SLAM drift) and into the summary; ``publish_tf`` is off.
* **Purely visual tracking.** The car's odometry is ground truth, so feeding it to SLAM as
  a motion prior (``odometry_prior``) would let the score lean on ground truth; tracking
  uses the constant-velocity model and relocalisation only.
* **Frame rate.** SLAM processes at most ``SLAM_FRAME_RATE`` frames per simulated second
  (chosen by stamp, never by wall clock, so the same seed gives the same trajectory):
  the full 20 Hz would halve the real-time factor of ``visnav run car`` for no gain in
  accuracy at the car's speed (<= 0.5 m/s, 5 cm between processed frames).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from visnav.graph.context import Context
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import Odometry
from visnav.slam.errors import SlamError
from visnav.slam.evaluation import ate, rpe
from visnav.slam.node import SlamNode
from visnav.slam.trajectory import Trajectory, write_tum
from visnav.tf import pose_to_matrix

__all__ = [
    "SLAM_FRAME_RATE",
    "CarSlamTask",
    "interpolate_poses",
    "slam_metrics",
]

FloatArray = NDArray[np.float64]

SLAM_FRAME_RATE = 10.0
"""Frames per simulated second given to SLAM (every other frame of the 20 Hz depth camera)."""


def interpolate_poses(
    stamps_ns: NDArray[np.int64], matrices: FloatArray, at_ns: NDArray[np.int64]
) -> tuple[NDArray[np.int64], FloatArray]:
    """Poses at ``at_ns`` by linear / slerp interpolation of stamped poses.

    Args:
        stamps_ns: (N,) increasing stamps of the known poses.
        matrices: (N, 4, 4) poses.
        at_ns: (M,) stamps wanted.

    Returns:
        ``(indices, poses)``: the indices into ``at_ns`` inside the known span and their
        (K, 4, 4) interpolated poses.
    """
    at = np.asarray(at_ns, dtype=np.int64)
    known = np.asarray(stamps_ns, dtype=np.int64)
    if len(known) < 2:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 4, 4))
    inside = np.flatnonzero((at >= known[0]) & (at <= known[-1]))
    if len(inside) == 0:
        return inside.astype(np.int64), np.zeros((0, 4, 4))
    t = (at[inside] - known[0]).astype(np.float64) * 1e-9
    tk = (known - known[0]).astype(np.float64) * 1e-9
    mats = np.asarray(matrices, dtype=np.float64)
    out = np.tile(np.eye(4), (len(inside), 1, 1))
    out[:, :3, :3] = Slerp(tk, Rotation.from_matrix(mats[:, :3, :3]))(t).as_matrix()
    for axis in range(3):
        out[:, axis, 3] = np.interp(t, tk, mats[:, axis, 3])
    return inside.astype(np.int64), out


def slam_metrics(estimate: Trajectory, reference: Trajectory) -> dict[str, float | None]:
    """ATE (aligned and not) and RPE (consecutive poses) of paired trajectories.

    Args:
        estimate: SLAM poses.
        reference: ground truth with the same stamps.

    Returns:
        ``ate_rmse_m``, ``ate_unaligned_rmse_m``, ``rpe_trans_rmse_m``,
        ``rpe_rot_rmse_deg`` (None when there are too few poses).
    """
    out: dict[str, float | None] = dict.fromkeys(
        ("ate_rmse_m", "ate_unaligned_rmse_m", "rpe_trans_rmse_m", "rpe_rot_rmse_deg")
    )
    if len(estimate) < 3 or len(reference) < 3:
        return out
    try:
        out["ate_rmse_m"] = round(ate(estimate, reference, align=True).rmse, 5)
    except SlamError:  # degenerate (the car did not move): aligned ATE is undefined
        out["ate_rmse_m"] = None
    out["ate_unaligned_rmse_m"] = round(ate(estimate, reference).rmse, 5)
    out["rpe_trans_rmse_m"] = round(rpe(estimate, reference).rmse, 5)
    out["rpe_rot_rmse_deg"] = round(rpe(estimate, reference, pose_relation="angle_deg").rmse, 4)
    return out


class CarSlamTask:
    """RGB-D SLAM on the car's depth camera, evaluated against ``/ground_truth/odom``.

    Args:
        ctx: the scenario's graph context.
        seed: seeds SLAM's random choices (RANSAC, vocabulary).
        frame_rate: frames per simulated second given to SLAM (0: all).
    """

    def __init__(
        self,
        ctx: Context,
        seed: int,
        *,
        frame_rate: float = SLAM_FRAME_RATE,
    ) -> None:
        self.slam = SlamNode(
            context=ctx,
            use_sim_time=True,
            remappings={
                "rgb/image": "/depth_camera/image_raw",
                "depth/image": "/depth_camera/depth/image_raw",
                "rgb/camera_info": "/depth_camera/camera_info",
            },
            parameter_overrides={
                "base_frame": "base_footprint",
                # the map is anchored at map -> base_footprint of the first frame: the car
                # task's static map -> odom (the spawn pose with wheel odometry) times the
                # odometry, so the SLAM map starts in the world frame as the ground truth does
                "odom_frame": "map",
                "publish_tf": False,
                "odometry_prior": False,
                "approx_sync": False,
                "max_frame_rate": float(frame_rate),
                "seed": int(seed),
            },
        )
        self._gt_stamps: list[int] = []
        self._gt_poses: list[FloatArray] = []
        self.slam.create_subscription(Odometry, "/ground_truth/odom", self._on_truth, 50)

    def _on_truth(self, msg: Odometry) -> None:
        stamp = time_to_ns(msg.header.stamp)
        if self._gt_stamps and stamp <= self._gt_stamps[-1]:
            return
        self._gt_stamps.append(stamp)
        self._gt_poses.append(pose_to_matrix(msg.pose.pose))

    def done(self) -> bool:
        """Always True: SLAM never holds the run (the navigation task ends it)."""
        return True

    def trajectories(self) -> tuple[Trajectory, Trajectory]:
        """``(estimate, ground truth)`` of ``base_footprint`` at the tracked frames' stamps."""
        return self._paired(self.slam.trajectory())

    def _paired(self, est: Trajectory) -> tuple[Trajectory, Trajectory]:
        """The poses of ``est`` within the ground truth's span, and the truth at their stamps."""
        if len(est) == 0 or len(self._gt_stamps) < 2:
            return Trajectory.empty(), Trajectory.empty()
        est_ns = np.round(est.stamps * 1e9).astype(np.int64)
        idx, gt = interpolate_poses(
            np.asarray(self._gt_stamps, dtype=np.int64), np.stack(self._gt_poses), est_ns
        )
        if len(idx) == 0:
            return Trajectory.empty(), Trajectory.empty()
        return est.subset(idx), Trajectory.from_matrices(est.stamps[idx], gt)

    def results(self) -> dict[str, Any]:
        """The ``slam`` summary key (module docstring)."""
        stats = self.slam.stats()
        tracked = self.slam.trajectory()
        est, gt = self._paired(tracked)
        out: dict[str, Any] = slam_metrics(est, gt)
        out.update(
            {
                "frames": stats.frames,
                "tracked": len(tracked),
                "evaluated": len(est),
                "tracking_lost": stats.lost,
                "relocalized": stats.relocalized,
                "keyframes": stats.keyframes,
                "loop_closures": stats.loops,
                "skipped": self.slam.skipped,
                "dropped": self.slam.dropped,
                "ba_runs": stats.ba_runs,
                "ba_failures": stats.ba_failures,
                "cpu_s": round(stats.cpu_s, 2),
            }
        )
        return {"slam": out}

    def write_outputs(self, out_dir: Path) -> list[Path]:
        """Write ``slam_trajectory.tum`` and ``ground_truth.tum`` into ``out_dir``."""
        est, gt = self.trajectories()
        out_dir.mkdir(parents=True, exist_ok=True)
        return [
            write_tum(
                out_dir / "slam_trajectory.tum",
                est,
                header="visnav SLAM, base_footprint in map (car scenario)",
            ),
            write_tum(
                out_dir / "ground_truth.tum",
                gt,
                header="ground truth base_footprint in world at the SLAM stamps",
            ),
        ]
