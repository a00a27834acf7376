"""AMCL's motion and sensor models, vectorised over particles (numpy in, numpy out).

* :func:`sample_diff_motion`: ROS amcl's ``diff`` odometry model (nav2's
  ``DifferentialMotionModel``; Probabilistic Robotics' ``sample_motion_model_odometry``
  with amcl's treatment of driving backwards): the odometry step between two filter
  updates is split into a first rotation, a translation and a second rotation, each
  disturbed by Gaussian noise whose variance mixes rotation and translation through
  ``alpha1`` .. ``alpha4``.
* :func:`select_beams`: amcl's beam subsampling (``max_beams`` evenly spaced by an
  integer step) and its skipping of max-range, below-minimum and NaN readings.
* :func:`likelihood_field_weights`: amcl's ``likelihood_field`` laser model: each beam
  end point scores ``pz = z_hit * exp(-d^2 / (2 sigma_hit^2)) + z_rand / range_max``
  with ``d`` its distance to the nearest obstacle (the map's likelihood field, capped,
  and the cap off the map), and a particle's factor is ``1 + sum(pz^3)`` (amcl's ad-hoc
  combination, which keeps one bad beam from zeroing a particle), or with ``product``
  nav2's ``likelihood_field_prob``: the product of the ``pz`` (as ``sum(log pz)``; nav2's
  optional beam skipping is not implemented). The loop over particles and beams is a
  numba kernel (:mod:`visnav.mapping._amcl_kernels`).

Poses are ``(x, y, yaw)`` rows; angles in radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from visnav.mapping.likelihood_field import LikelihoodField

__all__ = [
    "Beams",
    "angle_diff",
    "beam_endpoints",
    "likelihood_field_weights",
    "sample_diff_motion",
    "select_beams",
]


def angle_diff(a: float, b: float) -> float:
    """``a - b`` wrapped into ``[-pi, pi)``."""
    return math.remainder(a - b, 2.0 * math.pi)


def sample_diff_motion(
    poses: NDArray[np.float64],
    old: tuple[float, float, float],
    new: tuple[float, float, float],
    alphas: tuple[float, float, float, float],
    rng: np.random.Generator,
) -> None:
    """Move every particle by the odometry step ``old -> new`` with sampled noise (in place).

    Args:
        poses: ``(N, 3)`` particle poses, updated in place.
        old: Odometry pose at the last filter update.
        new: Odometry pose now.
        alphas: ``alpha1`` (rotation noise from rotation), ``alpha2`` (rotation from
            translation), ``alpha3`` (translation from translation), ``alpha4``
            (translation from rotation).
        rng: The filter's random generator.
    """
    a1, a2, a3, a4 = alphas
    dx, dy = new[0] - old[0], new[1] - old[1]
    trans = math.hypot(dx, dy)
    # a pure rotation (or a tiny step) has no meaningful direction of travel
    rot1 = angle_diff(math.atan2(dy, dx), old[2]) if trans >= 0.01 else 0.0
    rot2 = angle_diff(angle_diff(new[2], old[2]), rot1)
    # driving backwards is a small rotation plus a negative translation, not a half turn
    rot1_n = min(abs(angle_diff(rot1, 0.0)), abs(angle_diff(rot1, math.pi)))
    rot2_n = min(abs(angle_diff(rot2, 0.0)), abs(angle_diff(rot2, math.pi)))
    n = poses.shape[0]
    sd_rot1 = math.sqrt(a1 * rot1_n * rot1_n + a2 * trans * trans)
    sd_trans = math.sqrt(a3 * trans * trans + a4 * rot1_n * rot1_n + a4 * rot2_n * rot2_n)
    sd_rot2 = math.sqrt(a1 * rot2_n * rot2_n + a2 * trans * trans)
    noise = rng.standard_normal((n, 3))
    rot1_hat = rot1 - sd_rot1 * noise[:, 0]
    trans_hat = trans - sd_trans * noise[:, 1]
    rot2_hat = rot2 - sd_rot2 * noise[:, 2]
    heading = poses[:, 2] + rot1_hat
    poses[:, 0] += trans_hat * np.cos(heading)
    poses[:, 1] += trans_hat * np.sin(heading)
    poses[:, 2] = np.remainder(heading + rot2_hat + math.pi, 2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Beams:
    """The beams of one scan that the laser model uses.

    Attributes:
        ranges: ``(B,)`` measured ranges (m), all finite and inside the valid interval.
        angles: ``(B,)`` beam angles in the laser frame (rad).
        range_max: The maximum range the model divides ``z_rand`` by (m).
        total: Beams considered before skipping invalid ones.
    """

    ranges: NDArray[np.float64]
    angles: NDArray[np.float64]
    range_max: float
    total: int


def select_beams(
    ranges: NDArray[np.floating],
    angle_min: float,
    angle_increment: float,
    *,
    range_min: float,
    range_max: float,
    max_beams: int,
) -> Beams:
    """amcl's subsampling of a ``LaserScan`` (module docstring).

    Args:
        ranges: The scan's ranges.
        angle_min: The scan's first angle.
        angle_increment: The scan's angle step.
        range_min: Readings at or below this are treated as max range (skipped).
        range_max: Readings at or above this, NaN and inf are skipped.
        max_beams: How many evenly spaced beams to consider (>= 2).
    """
    r = np.asarray(ranges, dtype=np.float64)
    count = r.shape[0]
    step = max(1, (count - 1) // max(1, max_beams - 1))
    index = np.arange(0, count, step)
    picked = r[index]
    ok = np.isfinite(picked) & (picked < range_max) & (picked > range_min)
    angles = angle_min + index[ok].astype(np.float64) * angle_increment
    return Beams(picked[ok], angles, float(range_max), int(index.shape[0]))


def beam_endpoints(
    poses: NDArray[np.float64], beams: Beams, laser: tuple[float, float, float]
) -> NDArray[np.float64]:
    """``(N, B, 2)`` map-frame end points of the beams seen from each particle.

    Args:
        poses: ``(N, 3)`` particle (base frame) poses in the map.
        beams: The beams (laser frame).
        laser: The laser's pose ``(x, y, yaw)`` in the base frame.
    """
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    lx = poses[:, 0] + c * laser[0] - s * laser[1]
    ly = poses[:, 1] + s * laser[0] + c * laser[1]
    theta = (poses[:, 2] + laser[2])[:, None] + beams.angles[None, :]
    out = np.empty((poses.shape[0], beams.ranges.shape[0], 2))
    out[..., 0] = lx[:, None] + beams.ranges[None, :] * np.cos(theta)
    out[..., 1] = ly[:, None] + beams.ranges[None, :] * np.sin(theta)
    return out


def likelihood_field_weights(
    field: LikelihoodField,
    poses: NDArray[np.float64],
    beams: Beams,
    laser: tuple[float, float, float],
    *,
    z_hit: float,
    z_rand: float,
    sigma_hit: float,
    product: bool = False,
) -> NDArray[np.float64]:
    """amcl's likelihood field factor ``1 + sum(pz^3)`` of each particle (module docstring).

    Args:
        field: The map's likelihood field.
        poses: ``(N, 3)`` particle poses.
        beams: The selected beams.
        laser: The laser's pose in the base frame.
        z_hit: Weight of the Gaussian hit term.
        z_rand: Weight of the uniform random term.
        sigma_hit: Standard deviation of the hit term (m).
        product: nav2's ``likelihood_field_prob``: the product of the beams' ``pz``
            (returned as its logarithm, ``sum(log pz)``, 0 without beams).
    """
    if beams.ranges.shape[0] == 0:
        return np.zeros(poses.shape[0]) if product else np.ones(poses.shape[0])
    from visnav.mapping._amcl_kernels import likelihood_field_kernel  # noqa: PLC0415 - numba

    out: NDArray[np.float64] = likelihood_field_kernel(
        np.ascontiguousarray(poses, dtype=np.float64),
        np.ascontiguousarray(beams.ranges, dtype=np.float64),
        np.ascontiguousarray(beams.angles, dtype=np.float64),
        np.asarray(laser, dtype=np.float64),
        field.padded,
        field.grid_pose,
        field.resolution,
        field.max_dist,
        z_hit,
        z_rand / beams.range_max,
        0.5 / (sigma_hit * sigma_hit),
        product,
    )
    return out
