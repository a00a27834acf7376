"""Trajectory evaluation: absolute (ATE) and relative (RPE) pose error.

The definitions follow the TUM RGB-D benchmark as implemented by evo
(``evo_ape`` / ``evo_rpe``), and the defaults are evo's, so the numbers agree
with evo on the same files:

* association: each pose of the shorter trajectory is paired with the pose of
  the other whose stamp is nearest, if within ``max_diff`` (0.01 s) after adding
  ``offset`` (0 s) to the estimate's stamps;
* alignment (``align``): the Umeyama least-squares rigid transform (with
  ``scale``: similarity) mapping the estimated positions onto the reference;
  ``scale`` alone corrects only the scale, as ``evo_ape -s`` does;
* ATE ``trans_part``: the distance between aligned estimated and reference positions;
* RPE: the error of the relative motion between pose pairs ``delta`` frames (or
  metres) apart on the estimate, ``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``.

Statistics are over the per-pose (per-pair) errors: RMSE, mean, median, std
(population), min, max and the sum of squares.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.slam.errors import AssociationError, EvaluationError
from visnav.slam.trajectory import Trajectory

__all__ = [
    "POSE_RELATIONS",
    "Alignment",
    "ErrorStats",
    "PoseRelation",
    "align_trajectory",
    "associate",
    "ate",
    "rpe",
    "umeyama",
]

FloatArray = NDArray[np.float64]
PoseRelation = Literal["trans_part", "angle_deg", "angle_rad", "full"]
POSE_RELATIONS: tuple[str, ...] = ("trans_part", "angle_deg", "angle_rad", "full")


@dataclass(frozen=True)
class Alignment:
    """A similarity ``p_ref = scale * rotation @ p_est + translation``."""

    rotation: FloatArray
    translation: FloatArray
    scale: float

    def matrix(self) -> FloatArray:
        """Return the 4x4 Sim(3) matrix."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.rotation
        m[:3, 3] = self.translation
        return m


@dataclass(frozen=True)
class ErrorStats:
    """Per-pose errors of a metric and their statistics (evo's names).

    Attributes:
        metric: ``"ate"`` or ``"rpe"``.
        pose_relation: what each error measures (``trans_part`` in metres, ...).
        errors: the per-pose (ATE) or per-pair (RPE) errors.
        stamps: the reference stamps the errors belong to (RPE: the pair's second pose).
        alignment: the alignment applied to the estimate, if any.
        matched: how many pose pairs the association found.
    """

    metric: str
    pose_relation: str
    errors: FloatArray
    stamps: FloatArray
    alignment: Alignment | None = None
    matched: int = 0
    settings: dict[str, object] = field(default_factory=dict)

    @property
    def rmse(self) -> float:
        """Root mean square error."""
        return math.sqrt(float(np.mean(np.power(self.errors, 2))))

    @property
    def mean(self) -> float:
        """Mean error."""
        return float(np.mean(self.errors))

    @property
    def median(self) -> float:
        """Median error."""
        return float(np.median(self.errors))

    @property
    def std(self) -> float:
        """Population standard deviation of the errors."""
        return float(np.std(self.errors))

    @property
    def min(self) -> float:
        """Smallest error."""
        return float(np.min(self.errors))

    @property
    def max(self) -> float:
        """Largest error."""
        return float(np.max(self.errors))

    @property
    def sse(self) -> float:
        """Sum of squared errors."""
        return float(np.sum(np.power(self.errors, 2)))

    def stats(self) -> dict[str, float]:
        """Return the statistics as a dict (``rmse``, ``mean``, ``median``, ``std``, ...)."""
        return {
            "rmse": self.rmse,
            "mean": self.mean,
            "median": self.median,
            "std": self.std,
            "min": self.min,
            "max": self.max,
            "sse": self.sse,
        }

    def summary(self) -> str:
        """Return a human-readable multi-line report."""
        unit = {"trans_part": "m", "angle_deg": "deg", "angle_rad": "rad"}.get(
            self.pose_relation, ""
        )
        head = f"{self.metric.upper()} w.r.t. {self.pose_relation}"
        head += f" ({unit})" if unit else ""
        if self.alignment is not None:
            head += f", aligned (scale {self.alignment.scale:.6f})"
        lines = [head, f"       pairs  {len(self.errors)} (of {self.matched} associated poses)"]
        lines += [f"{k:>12}  {v:.6f}" for k, v in self.stats().items()]
        return "\n".join(lines)


def associate(
    stamps_ref: ArrayLike,
    stamps_est: ArrayLike,
    *,
    max_diff: float = 0.01,
    offset: float = 0.0,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Pair two stamp sequences by nearest stamp (evo's ``associate_trajectories``).

    The shorter sequence drives: each of its stamps is paired with the nearest stamp
    of the other (after adding ``offset`` to the estimate's stamps) if the difference
    is at most ``max_diff``. A stamp of the longer sequence may be used twice.

    Args:
        stamps_ref: reference stamps (s).
        stamps_est: estimate stamps (s).
        max_diff: largest accepted difference (s).
        offset: added to the estimate's stamps before matching (s).

    Returns:
        Index arrays ``(i_ref, i_est)`` of equal length, in the driving sequence's order.

    Raises:
        AssociationError: no stamp pairs within ``max_diff``.
    """
    ref = np.asarray(stamps_ref, dtype=np.float64).reshape(-1)
    est = np.asarray(stamps_est, dtype=np.float64).reshape(-1)
    est_longer = len(est) > len(ref)
    short, long_ = (ref, est) if est_longer else (est, ref)
    shift = offset if est_longer else -offset
    i_short, i_long = _matching_indices(short, long_ + shift, max_diff)
    if not i_short:
        text = (
            f"no timestamps associate between the reference ({len(ref)} poses, "
            f"{_span(ref)}) and the estimate ({len(est)} poses, {_span(est)}) within "
            f"max_diff {max_diff} s with offset {offset} s; check that both use the same "
            "clock, or pass a larger max_diff / an offset"
        )
        raise AssociationError(text)
    a = np.asarray(i_short, dtype=np.int64)
    b = np.asarray(i_long, dtype=np.int64)
    return (a, b) if est_longer else (b, a)


def _span(stamps: FloatArray) -> str:
    if len(stamps) == 0:
        return "empty"
    return f"stamps {stamps.min():.6f} .. {stamps.max():.6f} s"


def _matching_indices(
    short: FloatArray, long_: FloatArray, max_diff: float
) -> tuple[list[int], list[int]]:
    out_s: list[int] = []
    out_l: list[int] = []
    if len(long_) == 0:
        return out_s, out_l
    if not np.all(np.diff(long_) >= 0):
        for i, s in enumerate(short):
            diffs = np.abs(long_ - s)
            j = int(np.argmin(diffs))
            if diffs[j] <= max_diff:
                out_s.append(i)
                out_l.append(j)
        return out_s, out_l
    for i, s in enumerate(short):
        if s < long_[0] - max_diff or s > long_[-1] + max_diff:
            continue
        j = int(np.searchsorted(long_, s, side="right"))
        j = min(j, len(long_) - 1)
        diff_ub = long_[j] - s
        diff_lb = s - long_[j - 1] if j > 0 else math.inf
        if diff_ub <= max_diff and diff_ub < diff_lb:
            best = j
        elif diff_lb <= max_diff and diff_lb <= diff_ub:
            best = j - 1
        else:
            continue
        out_s.append(i)
        out_l.append(best)
    return out_s, out_l


def umeyama(x: ArrayLike, y: ArrayLike, *, with_scale: bool = False) -> Alignment:
    """Least-squares similarity mapping points ``x`` onto ``y`` (Umeyama 1991).

    Args:
        x: (N, 3) source points.
        y: (N, 3) target points.
        with_scale: also estimate the scale (else 1).

    Returns:
        The alignment with ``y ~ scale * R @ x + t``.

    Raises:
        EvaluationError: shapes differ or the points are degenerate (all on one point).
    """
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    if xa.shape != ya.shape or xa.ndim != 2 or xa.shape[1] != 3:
        text = f"umeyama needs two (N, 3) arrays of equal shape, got {xa.shape} and {ya.shape}"
        raise EvaluationError(text)
    n = len(xa)
    mean_x = xa.mean(axis=0)
    mean_y = ya.mean(axis=0)
    dx = xa - mean_x
    dy = ya - mean_y
    sigma_x = float(np.linalg.norm(dx) ** 2) / n
    cov = dy.T @ dx / n
    u, d, vt = np.linalg.svd(cov)
    if np.count_nonzero(d > np.finfo(d.dtype).eps) < 2:
        text = (
            f"alignment impossible: the {n} associated positions are degenerate (a point "
            "or fewer than two distinct directions); evaluate without --align"
        )
        raise EvaluationError(text)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:
        s[2, 2] = -1.0
    r = u @ s @ vt
    c = float(np.trace(np.diag(d) @ s)) / sigma_x if with_scale else 1.0
    t = mean_y - c * (r @ mean_x)
    return Alignment(r, t, c)


def align_trajectory(
    est: Trajectory, ref: Trajectory, *, align: bool = True, scale: bool = False
) -> tuple[FloatArray, Alignment]:
    """Return the aligned (N, 4, 4) estimated poses and the alignment (poses paired 1:1).

    ``align`` applies the rigid (with ``scale``: similarity) Umeyama transform;
    ``scale`` without ``align`` only rescales the translations.
    """
    if len(est) != len(ref):
        text = f"align_trajectory needs paired poses, got {len(est)} and {len(ref)}"
        raise EvaluationError(text)
    al = umeyama(est.positions, ref.positions, with_scale=scale)
    poses = est.matrices()
    poses[:, :3, 3] *= al.scale
    if align:
        t = np.eye(4)
        t[:3, :3] = al.rotation
        t[:3, 3] = al.translation
        poses = np.einsum("ij,njk->nik", t, poses)
        return poses, al
    return poses, Alignment(np.eye(3), np.zeros(3), al.scale)


def _inv(poses: FloatArray) -> FloatArray:
    out = np.zeros_like(poses)
    rt = np.transpose(poses[:, :3, :3], (0, 2, 1))
    out[:, :3, :3] = rt
    out[:, :3, 3] = -np.einsum("nij,nj->ni", rt, poses[:, :3, 3])
    out[:, 3, 3] = 1.0
    return out


def _rotation_angles(rotations: FloatArray) -> FloatArray:
    """Rotation angles of (N, 3, 3) matrices, accurate near 0 (atan2 of sin and cos)."""
    r = rotations
    v = np.stack(
        [r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], axis=1
    )
    sin = 0.5 * np.linalg.norm(v, axis=1)
    cos = 0.5 * (r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2] - 1.0)
    angles: FloatArray = np.arctan2(sin, cos)
    return angles


def _pose_errors(e: FloatArray, relation: str) -> FloatArray:
    if relation == "trans_part":
        out: FloatArray = np.linalg.norm(e[:, :3, 3], axis=1)
        return out
    if relation == "angle_rad":
        return _rotation_angles(e[:, :3, :3])
    if relation == "angle_deg":
        return np.rad2deg(_rotation_angles(e[:, :3, :3]))
    full: FloatArray = np.linalg.norm((e - np.eye(4)).reshape(len(e), -1), axis=1)
    return full


def _check_relation(pose_relation: str) -> None:
    if pose_relation not in POSE_RELATIONS:
        text = f"pose_relation {pose_relation!r} unknown; expected one of {POSE_RELATIONS}"
        raise EvaluationError(text)


def _paired(
    est: Trajectory, ref: Trajectory, max_diff: float, offset: float
) -> tuple[Trajectory, Trajectory]:
    if len(est) == 0 or len(ref) == 0:
        text = f"cannot evaluate: the estimate has {len(est)} poses, the reference {len(ref)}"
        raise EvaluationError(text)
    i_ref, i_est = associate(ref.stamps, est.stamps, max_diff=max_diff, offset=offset)
    return est.subset(i_est), ref.subset(i_ref)


def ate(
    est: Trajectory,
    ref: Trajectory,
    *,
    align: bool = False,
    scale: bool = False,
    pose_relation: PoseRelation = "trans_part",
    max_diff: float = 0.01,
    offset: float = 0.0,
) -> ErrorStats:
    """Absolute trajectory error of ``est`` against ``ref`` (``evo_ape tum REF EST``).

    Args:
        est: estimated trajectory.
        ref: reference (ground truth) trajectory.
        align: apply the Umeyama rigid alignment (``-a``).
        scale: also correct the scale (``-s``; alone: scale only).
        pose_relation: ``trans_part`` (m, default), ``angle_deg``, ``angle_rad`` or ``full``.
        max_diff: association tolerance in seconds.
        offset: added to the estimate's stamps for association (s).

    Returns:
        The per-pose errors and their statistics.
    """
    _check_relation(pose_relation)
    e, r = _paired(est, ref, max_diff, offset)
    poses_est, al = _aligned(e, r, align, scale)
    poses_ref = r.matrices()
    if pose_relation == "trans_part":
        errors: FloatArray = np.linalg.norm(poses_est[:, :3, 3] - poses_ref[:, :3, 3], axis=1)
    else:
        errors = _pose_errors(np.einsum("nij,njk->nik", _inv(poses_est), poses_ref), pose_relation)
    return ErrorStats(
        "ate",
        pose_relation,
        errors,
        r.stamps.copy(),
        al,
        len(e),
        {"align": align, "scale": scale, "max_diff": max_diff, "offset": offset},
    )


def _aligned(
    e: Trajectory, r: Trajectory, align: bool, scale: bool
) -> tuple[FloatArray, Alignment | None]:
    if align or scale:
        return align_trajectory(e, r, align=align, scale=scale)
    return e.matrices(), None


def _pairs(
    poses: FloatArray, delta: float, unit: str, all_pairs: bool, rel_tol: float
) -> list[tuple[int, int]]:
    n = len(poses)
    if unit == "frames":
        step = int(delta)
        if all_pairs:
            return [(i, i + step) for i in range(n) if i + step < n]
        ids = list(range(0, n, step))
        return list(itertools.pairwise(ids))
    positions = poses[:, :3, 3]
    if all_pairs:
        dist = np.concatenate(
            ([0.0], np.cumsum(np.linalg.norm(positions[:-1] - positions[1:], axis=1)))
        )
        out: list[tuple[int, int]] = []
        tol = delta * rel_tol
        for i in range(n - 1):
            from_here = dist[i + 1 :] - dist[i]
            k = int(np.argmin(np.abs(from_here - delta)))
            if abs(from_here[k] - delta) > tol:
                continue
            out.append((i, k + i + 1))
        return out
    ids = [0]
    travelled = 0.0
    for i in range(1, n):
        travelled += float(np.linalg.norm(positions[i] - positions[i - 1]))
        if travelled >= delta:
            ids.append(i)
            travelled = 0.0
    return list(itertools.pairwise(ids))


def rpe(
    est: Trajectory,
    ref: Trajectory,
    *,
    delta: float = 1,
    delta_unit: Literal["frames", "meters"] = "frames",
    all_pairs: bool = False,
    rel_delta_tol: float = 0.1,
    align: bool = False,
    scale: bool = False,
    pose_relation: PoseRelation = "trans_part",
    max_diff: float = 0.01,
    offset: float = 0.0,
) -> ErrorStats:
    """Relative pose error of ``est`` against ``ref`` (``evo_rpe tum REF EST``).

    Pairs are chosen on the (associated, aligned) estimate: every ``delta`` frames
    (``delta_unit="frames"``) or every ``delta`` metres travelled (``"meters"``);
    with ``all_pairs`` every pose starts a pair.

    Args:
        est: estimated trajectory.
        ref: reference trajectory.
        delta: pair distance (frames: an integer >= 1; meters: > 0).
        delta_unit: ``"frames"`` or ``"meters"``.
        all_pairs: use every pose as a pair start instead of consecutive pairs.
        rel_delta_tol: relative tolerance of the metre distance with ``all_pairs``.
        align: Umeyama rigid alignment first (RPE is invariant to it unless ``scale``).
        scale: also correct the scale.
        pose_relation: ``trans_part`` (m, default), ``angle_deg``, ``angle_rad`` or ``full``.
        max_diff: association tolerance in seconds.
        offset: added to the estimate's stamps for association (s).

    Returns:
        The per-pair errors and their statistics.

    Raises:
        EvaluationError: bad ``delta``, or no pair at that distance.
    """
    _check_relation(pose_relation)
    if delta_unit not in ("frames", "meters"):
        text = f"delta_unit {delta_unit!r} unknown; expected 'frames' or 'meters'"
        raise EvaluationError(text)
    if delta <= 0 or (delta_unit == "frames" and float(delta) != int(delta)):
        kind = "integer " if delta_unit == "frames" else ""
        text = f"delta {delta} invalid: expected a positive {kind}number of {delta_unit}"
        raise EvaluationError(text)
    e, r = _paired(est, ref, max_diff, offset)
    poses_est, al = _aligned(e, r, align, scale)
    poses_ref = r.matrices()
    pairs = _pairs(poses_est, delta, delta_unit, all_pairs, rel_delta_tol)
    if not pairs:
        text = (
            f"delta = {delta} {delta_unit} gives no pose pair among {len(e)} associated "
            "poses; use a smaller delta"
        )
        raise EvaluationError(text)
    i = np.asarray([p[0] for p in pairs])
    j = np.asarray([p[1] for p in pairs])
    q_rel = np.einsum("nij,njk->nik", _inv(poses_ref[i]), poses_ref[j])
    p_rel = np.einsum("nij,njk->nik", _inv(poses_est[i]), poses_est[j])
    err = np.einsum("nij,njk->nik", _inv(q_rel), p_rel)
    return ErrorStats(
        "rpe",
        pose_relation,
        _pose_errors(err, pose_relation),
        r.stamps[j].copy(),
        al,
        len(e),
        {
            "delta": delta,
            "delta_unit": delta_unit,
            "all_pairs": all_pairs,
            "align": align,
            "scale": scale,
            "max_diff": max_diff,
            "offset": offset,
        },
    )
