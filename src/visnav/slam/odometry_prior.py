"""Wheel (or any) odometry as a Gaussian prior on the tracked camera pose.

ORB-SLAM2 tracks with a constant-velocity model and nothing else. A robot that has
wheel odometry knows more: over one camera frame the encoders' motion is good to a few
millimetres, even when their heading slips by some degrees per second in a turn on the
spot. :func:`odometry_prior` turns the odometry's motion since the last tracked frame
into a :class:`~visnav.slam.geometry.PosePrior` for the motion-only optimisation. It
matters where the matched points cannot hold the pose: when all of them lie far down
a corridor, a sideways shift of the camera and a turn move them alike, and without the
prior the tracked pose slid 7 cm sideways and turned 0.7 degrees in one frame (seed 3 of
``visnav run car`` at 78 s).

A wheeled base that cannot move sideways (``odometry_model="diff"``) knows more again:
its odometry can be wrong along the motion (slip, wheel radius) and in heading, but a
sideways error only comes from the heading error over the distance moved. The prior's
covariance is then tighter across the motion, in the horizontal plane of the odometry
frame (its z axis is up, REP 105), which is the direction the corridor case leaves free.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from visnav.slam.config import SlamConfig
from visnav.slam.geometry import FloatArray, PosePrior, inverse, rotation_angle
from visnav.slam.slam_map import SlamMap


@dataclass(frozen=True)
class OdometryEdge:
    """The odometry's motion between two keyframes, a factor of local bundle adjustment.

    Attributes:
        i: the earlier keyframe's id.
        j: the later keyframe's id.
        t_ij: the pose of keyframe ``j``'s camera in keyframe ``i``'s camera frame.
        information: (6, 6) inverse covariance of the error twist in keyframe ``j``'s
            camera frame: translation x, y, z (m), then rotation x, y, z (rad).
    """

    i: int
    j: int
    t_ij: FloatArray
    information: FloatArray


def odometry_sigmas(config: SlamConfig, delta: FloatArray) -> tuple[float, float]:
    """Standard deviations (m, rad) of an odometry motion ``delta`` (4x4) per axis."""
    moved = float(np.linalg.norm(delta[:3, 3]))
    sigma_t = config.odometry_sigma_t + config.odometry_sigma_t_rel * moved
    sigma_r = float(np.radians(config.odometry_sigma_r_deg))
    sigma_r += config.odometry_sigma_r_rel * rotation_angle(delta)
    sigma_r += config.odometry_sigma_r_per_m * moved
    return sigma_t, sigma_r


def odometry_information(
    config: SlamConfig, delta: FloatArray, up: FloatArray | None = None
) -> FloatArray:
    """Inverse covariance (6, 6) of an odometry motion's error twist (translation first).

    Args:
        config: the SLAM parameters (``odometry_sigma_*``, ``odometry_model``).
        delta: the motion (4x4) whose translation is expressed in the frame of the error
            twist (its direction is the direction of travel; its sign does not matter).
        up: the odometry frame's z axis in that frame; with ``odometry_model="diff"`` the
            horizontal direction across the motion gets the sideways standard deviation.
            None (or ``"omni"``, or no motion to speak of): every axis alike.
    """
    sigma_t, sigma_r = odometry_sigmas(config, delta)
    info = np.diag([sigma_t**-2] * 3 + [sigma_r**-2] * 3)
    if config.odometry_model != "diff" or up is None:
        return info
    moved = float(np.linalg.norm(delta[:3, 3]))
    if moved < 1e-4:  # turning on the spot or standing: no direction of travel
        return info
    across = np.cross(np.asarray(up, dtype=np.float64), delta[:3, 3] / moved)
    norm = float(np.linalg.norm(across))
    if norm < 0.5:  # moving along the up axis (not a ground robot's motion): no model
        return info
    across /= norm
    sigma_lateral = min(sigma_t, config.odometry_sigma_t_lateral + moved * sigma_r)
    # sigma_t^2 on every axis, sigma_lateral^2 across the motion: the inverse is
    # I / sigma_t^2 plus (1 / sigma_lateral^2 - 1 / sigma_t^2) across across^T
    info[:3, :3] += (sigma_lateral**-2 - sigma_t**-2) * np.outer(across, across)
    return info


def odometry_edges(
    config: SlamConfig, slam_map: SlamMap, keyframe_ids: list[int]
) -> list[OdometryEdge]:
    """Odometry factors between consecutive good keyframes, one of them in ``keyframe_ids``.

    Consecutive means no good keyframe lies between them in time (a culled one may);
    both must carry an odometry pose. None with ``odom_prior`` off.
    """
    if not config.odom_prior:
        return []
    wanted = set(keyframe_ids)
    edges: list[OdometryEdge] = []
    previous = -1
    for kf in slam_map.keyframes:
        if kf.bad:
            continue
        prev_kf = slam_map.keyframes[previous] if previous >= 0 else None
        if (
            prev_kf is not None
            and (kf.id in wanted or previous in wanted)
            and kf.odom_pose is not None
            and prev_kf.odom_pose is not None
        ):
            t_ij = inverse(prev_kf.odom_pose) @ kf.odom_pose
            # the error twist is in keyframe j's frame: the motion and "up" seen from there
            t_ji = inverse(t_ij)
            info = odometry_information(config, t_ji, kf.odom_pose[2, :3])
            edges.append(OdometryEdge(previous, kf.id, t_ij, info))
        previous = kf.id
    return edges


__all__ = [
    "OdometryEdge",
    "odometry_edges",
    "odometry_information",
    "odometry_prior",
    "odometry_sigmas",
]


def odometry_prior(
    config: SlamConfig,
    predicted_t_cw: FloatArray | None,
    odom_pose: FloatArray | None,
    odom_pose_last: FloatArray | None,
) -> PosePrior | None:
    """The odometry's prediction of a frame's pose as a prior, or None without one.

    The standard deviations grow with the odometry's motion since the last tracked
    frame (``odometry_sigma_*`` of :class:`~visnav.slam.config.SlamConfig`) and are the same
    on every axis (the SLAM system does not know where the wheels are relative to the
    camera), except across the motion with ``odometry_model="diff"``
    (:func:`odometry_information`).

    Args:
        config: the SLAM parameters (``odom_prior`` off: no prior).
        predicted_t_cw: the last tracked pose moved by the odometry's motion.
        odom_pose: ``T_odom_camera`` of this frame.
        odom_pose_last: ``T_odom_camera`` of the last tracked frame.

    Returns:
        The prior, or None when the prior is off or an input is missing.
    """
    if not config.odom_prior or predicted_t_cw is None:
        return None
    if odom_pose is None or odom_pose_last is None:
        return None
    odom_pose = np.asarray(odom_pose, dtype=np.float64)
    delta = inverse(odom_pose) @ odom_pose_last  # the prior's twist is in this frame's camera
    return PosePrior(predicted_t_cw, odometry_information(config, delta, odom_pose[2, :3]))
