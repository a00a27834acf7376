"""Fixtures of the gmapping tests: the recorded TurtleBot3 drive and a synthetic room."""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from numpy.typing import NDArray

FIXTURE = Path(__file__).resolve().parent / "data" / "tb3_world_loop.npz"


def drifting_odometry(truth: NDArray[np.float64], seed: int) -> NDArray[np.float64]:
    """Wheel odometry from the true increments: +2 % distance, +3 % turn, 0.01 rad/m yaw bias."""
    rng = np.random.default_rng(seed)
    odo = truth[0].copy()
    out = [odo.copy()]
    for a, b in itertools.pairwise(truth):
        c, s = math.cos(a[2]), math.sin(a[2])
        dx = c * (b[0] - a[0]) + s * (b[1] - a[1])
        dy = -s * (b[0] - a[0]) + c * (b[1] - a[1])
        dx2 = dx * 1.02 + rng.normal(0, 0.002)
        dt2 = (b[2] - a[2]) * 1.03 + 0.01 * abs(dx) + rng.normal(0, 0.002)
        c, s = math.cos(odo[2]), math.sin(odo[2])
        odo = odo + np.array([c * dx2 - s * dy, s * dx2 + c * dy, dt2])
        out.append(odo.copy())
    return np.array(out)


def segment_distance(points: NDArray[np.float64], segs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance of each (N, 2) point to the nearest of the (S, 4) segments."""
    best = np.full(len(points), np.inf)
    a, ab = segs[:, :2], segs[:, 2:] - segs[:, :2]
    for j in range(0, len(a), 400):
        aa, bb = a[j : j + 400], ab[j : j + 400]
        t = ((points[:, None, :] - aa[None]) * bb[None]).sum(-1)
        t = np.clip(t / np.maximum((bb * bb).sum(-1)[None], 1e-12), 0.0, 1.0)
        near = aa[None] + t[..., None] * bb[None]
        best = np.minimum(best, np.linalg.norm(points[:, None, :] - near, axis=-1).min(1))
    return best


@pytest.fixture(scope="session")
def tb3_drive() -> SimpleNamespace:
    """333 scans of a burger's loop in turtlebot3_world (record_tb3_drive.py), with truth."""
    d = np.load(FIXTURE)
    n = d["ranges"].shape[1]
    return SimpleNamespace(
        ranges=d["ranges"].astype(np.float64),
        stamps=d["stamps"],
        truth=d["truth"],
        T_base_laser=d["T_base_laser"],
        angles=float(d["angle_min"]) + float(d["angle_increment"]) * np.arange(n),
        angle_min=float(d["angle_min"]),
        angle_increment=float(d["angle_increment"]),
        range_min=float(d["range_min"]),
        range_max=float(d["range_max"]),
        frame_id=str(d["frame_id"]),
        walls=d["walls"],
        odometry=drifting_odometry,
        distance=segment_distance,
    )


def room() -> NDArray[np.float64]:
    """A 6 m square room with three boxes and a stub wall: (S, 4) segments."""
    segs: list[tuple[float, float, float, float]] = []
    for x0, y0, x1, y1 in [(-3, -3, 3, 3), (-1.2, -0.4, -0.6, 0.2), (0.8, 0.9, 1.4, 1.3)]:
        segs += [(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)]
    segs.append((-3.0, 2.0, -2.5, 2.0))
    return np.array(segs, dtype=np.float64)


def cast(
    segs: NDArray[np.float64], x: float, y: float, angles: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Exact ranges from (x, y) along world angles to the segments (inf beyond 3.5 m)."""
    d = np.stack([np.cos(angles), np.sin(angles)], 1)
    p, e = segs[:, :2], segs[:, 2:] - segs[:, :2]
    ox, oy = p[None, :, 0] - x, p[None, :, 1] - y
    den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (ox * e[None, :, 1] - oy * e[None, :, 0]) / den
        u = (ox * d[:, None, 1] - oy * d[:, None, 0]) / den
    ok = (np.abs(den) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
    r = np.where(ok, t, np.inf).min(1)
    return np.where(r <= 3.5, r, np.inf)


@pytest.fixture
def synthetic_room() -> SimpleNamespace:
    """The synthetic room and its exact ray caster."""
    return SimpleNamespace(segments=room(), cast=cast)
