"""Stamped pose trajectories and the TUM trajectory format.

A TUM trajectory file has one pose per line, ``timestamp tx ty tz qx qy qz qw``
(seconds, metres, a unit quaternion x, y, z, w mapping points from the moving
frame into the fixed one); lines starting with ``#`` are comments. This is what
the TUM RGB-D benchmark tools, evo and ORB-SLAM read and write.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.slam.errors import TrajectoryFormatError
from visnav.textfile import read_text

__all__ = [
    "Trajectory",
    "quaternions_to_matrices",
    "read_tum",
    "write_tum",
]

FloatArray = NDArray[np.float64]

_EPS = np.finfo(float).eps * 4.0
_MIN_QUAT_NORM = 1e-6  # a TUM quaternion shorter than this is no rotation (refused)


def quaternions_to_matrices(quaternions: ArrayLike) -> FloatArray:
    """Return the (N, 3, 3) rotation matrices of (N, 4) quaternions x, y, z, w.

    Quaternions are normalised first (a zero quaternion gives the identity), as the
    TUM tools and evo do when they read a file.
    """
    q = np.asarray(quaternions, dtype=np.float64).reshape(-1, 4)
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    n = np.einsum("ij,ij->i", q, q)
    safe = np.where(n < _EPS, 1.0, n)
    s = np.where(n < _EPS, 0.0, 2.0 / safe)
    xx, yy, zz = s * x * x, s * y * y, s * z * z
    xy, xz, yz = s * x * y, s * x * z, s * y * z
    wx, wy, wz = s * w * x, s * w * y, s * w * z
    out = np.empty((len(q), 3, 3))
    out[:, 0, 0] = 1.0 - yy - zz
    out[:, 0, 1] = xy - wz
    out[:, 0, 2] = xz + wy
    out[:, 1, 0] = xy + wz
    out[:, 1, 1] = 1.0 - xx - zz
    out[:, 1, 2] = yz - wx
    out[:, 2, 0] = xz - wy
    out[:, 2, 1] = yz + wx
    out[:, 2, 2] = 1.0 - xx - yy
    return out


def _matrices_to_quaternions(rotations: FloatArray) -> FloatArray:
    """(N, 3, 3) rotations -> (N, 4) unit quaternions x, y, z, w (Shepperd's method)."""
    r = rotations
    tr = r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]
    diag = np.stack([r[:, 0, 0], r[:, 1, 1], r[:, 2, 2], tr], axis=1)
    k = np.argmax(diag, axis=1)
    quat = np.empty((len(r), 4))
    for case in range(4):
        sel = k == case
        if not sel.any():
            continue
        m = r[sel]
        if case == 3:
            s = 2.0 * np.sqrt(1.0 + diag[sel, 3])
            q = [
                (m[:, 2, 1] - m[:, 1, 2]) / s,
                (m[:, 0, 2] - m[:, 2, 0]) / s,
                (m[:, 1, 0] - m[:, 0, 1]) / s,
                0.25 * s,
            ]
        else:
            i, j, m3 = case, (case + 1) % 3, (case + 2) % 3
            s = 2.0 * np.sqrt(np.maximum(1.0 + m[:, i, i] - m[:, j, j] - m[:, m3, m3], 1e-300))
            q = [np.zeros(len(m))] * 3 + [(m[:, m3, j] - m[:, j, m3]) / s]
            q[i] = 0.25 * s
            q[j] = (m[:, j, i] + m[:, i, j]) / s
            q[m3] = (m[:, m3, i] + m[:, i, m3]) / s
        quat[sel] = np.stack(q, axis=1)
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    # a canonical sign (w >= 0) keeps written files stable
    quat[quat[:, 3] < 0] *= -1.0
    return quat


@dataclass(frozen=True)
class Trajectory:
    """A stamped pose sequence: ``T_world_body`` at each stamp.

    Attributes:
        stamps: (N,) float seconds.
        positions: (N, 3) metres, the body origin in the world frame.
        quaternions: (N, 4) x, y, z, w, the body orientation in the world frame.
    """

    stamps: FloatArray
    positions: FloatArray
    quaternions: FloatArray

    def __post_init__(self) -> None:
        n = len(self.stamps)
        if self.stamps.shape != (n,) or self.positions.shape != (n, 3):
            text = (
                f"trajectory arrays disagree: stamps {self.stamps.shape}, positions "
                f"{self.positions.shape}, quaternions {self.quaternions.shape}; "
                "expected (N,), (N, 3), (N, 4)"
            )
            raise TrajectoryFormatError(text)
        if self.quaternions.shape != (n, 4):
            text = f"quaternions have shape {self.quaternions.shape}, expected ({n}, 4)"
            raise TrajectoryFormatError(text)

    def __len__(self) -> int:
        return len(self.stamps)

    @classmethod
    def empty(cls) -> Trajectory:
        """A trajectory with no pose."""
        return cls(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)))

    @classmethod
    def from_matrices(cls, stamps: ArrayLike, matrices: ArrayLike) -> Trajectory:
        """Build a trajectory from stamps (s) and (N, 4, 4) ``T_world_body`` matrices."""
        t = np.asarray(stamps, dtype=np.float64).reshape(-1)
        m = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
        quats = _matrices_to_quaternions(m[:, :3, :3]) if len(m) else np.zeros((0, 4))
        return cls(t.copy(), m[:, :3, 3].copy(), quats)

    def matrices(self) -> FloatArray:
        """Return the (N, 4, 4) ``T_world_body`` matrices."""
        out = np.zeros((len(self), 4, 4))
        out[:, :3, :3] = quaternions_to_matrices(self.quaternions)
        out[:, :3, 3] = self.positions
        out[:, 3, 3] = 1.0
        return out

    def subset(self, indices: ArrayLike) -> Trajectory:
        """Return the poses at ``indices`` (repeats allowed)."""
        idx = np.asarray(indices, dtype=np.int64)
        return Trajectory(self.stamps[idx], self.positions[idx], self.quaternions[idx])


def read_tum(path: str | Path) -> Trajectory:
    """Read a TUM trajectory file.

    Args:
        path: the file (``timestamp tx ty tz qx qy qz qw`` per line, ``#`` comments).

    Returns:
        The trajectory, in file order.

    Raises:
        TrajectoryFormatError: the file is missing, not UTF-8, empty, or has a
            malformed line (not 8 numbers, a non-finite value, a zero quaternion).
    """
    p = Path(path)
    if not p.is_file():
        text = (
            f"trajectory file {p} does not exist (expected a TUM file: stamp tx ty tz qx qy qz qw)"
        )
        raise TrajectoryFormatError(text)
    rows: list[list[float]] = []
    content = read_text(p, what="the TUM trajectory", error=TrajectoryFormatError)
    for lineno, line in enumerate(content.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        parts = stripped.replace(",", " ").split()
        if len(parts) != 8:
            text = (
                f"{p}:{lineno}: {len(parts)} values in {stripped!r}; a TUM trajectory line "
                "has 8: timestamp tx ty tz qx qy qz qw"
            )
            raise TrajectoryFormatError(text)
        try:
            values = [float(v) for v in parts]
        except ValueError:
            text = f"{p}:{lineno}: non-numeric value in {stripped!r}"
            raise TrajectoryFormatError(text) from None
        if not all(math.isfinite(v) for v in values):
            text = f"{p}:{lineno}: non-finite value in {stripped!r}"
            raise TrajectoryFormatError(text)
        if math.sqrt(sum(v * v for v in values[4:8])) < _MIN_QUAT_NORM:
            text = (
                f"{p}:{lineno}: quaternion qx qy qz qw = {' '.join(parts[4:8])} has (near) zero "
                "length and is no rotation; fix: write a unit quaternion (0 0 0 1 for none)"
            )
            raise TrajectoryFormatError(text)
        rows.append(values)
    if not rows:
        text = f"trajectory file {p} has no poses (only comments or blank lines)"
        raise TrajectoryFormatError(text)
    mat = np.asarray(rows, dtype=np.float64)
    return Trajectory(mat[:, 0].copy(), mat[:, 1:4].copy(), mat[:, 4:8].copy())


def write_tum(path: str | Path, trajectory: Trajectory, *, header: str | None = None) -> Path:
    """Write a trajectory as a TUM file (stamps with 9 decimals, poses with 9).

    Args:
        path: output file; its folder is created.
        trajectory: the poses.
        header: optional comment written first (each line prefixed with ``# ``).

    Returns:
        The path written.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    lines: list[str] = []
    if header:
        lines.extend(f"# {h}" for h in header.splitlines())
    for t, pos, q in zip(
        trajectory.stamps, trajectory.positions, trajectory.quaternions, strict=True
    ):
        values = " ".join(f"{v:.9f}" for v in (*pos, *q))
        lines.append(f"{t:.9f} {values}")
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return p
