"""Shared fixtures of the mapping tests: a small synthetic world for AMCL."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from numpy.typing import NDArray

RES = 0.05
ORIGIN = (-1.0, -1.0, 0.0)


def office_grid() -> NDArray[np.int8]:
    """A 12 m x 9 m walled floor with an inner wall, a door and boxes (asymmetric)."""
    h, w = int(9 / RES), int(12 / RES)
    g = np.zeros((h, w), dtype=np.int8)
    g[:3, :] = g[-3:, :] = 100
    g[:, :3] = g[:, -3:] = 100
    g[: int(5 / RES), int(6 / RES) : int(6 / RES) + 3] = 100  # inner wall x = 5 m
    g[int(6.5 / RES) : int(7 / RES), int(2 / RES) : int(3.2 / RES)] = 100  # box
    g[int(1.5 / RES) : int(2.3 / RES), int(9 / RES) : int(9.4 / RES)] = 100  # pillar
    g[int(3.5 / RES) : int(4.0 / RES), int(1.5 / RES) : int(2.0 / RES)] = 100
    g[int(8.3 / RES) :, int(10 / RES) :] = -1  # an unknown corner
    return g


def raycast(
    grid: NDArray[np.int8],
    pose: tuple[float, float, float],
    angles: NDArray[np.float64],
    *,
    range_max: float = 10.0,
    step: float = 0.01,
) -> NDArray[np.float64]:
    """Ranges from ``pose`` along ``angles`` to the first occupied cell (inf: none)."""
    t = np.arange(step, range_max, step)
    theta = pose[2] + angles
    x = pose[0] + np.cos(theta)[:, None] * t[None, :] - ORIGIN[0]
    y = pose[1] + np.sin(theta)[:, None] * t[None, :] - ORIGIN[1]
    col = np.floor(x / RES).astype(int)
    row = np.floor(y / RES).astype(int)
    inside = (col >= 0) & (col < grid.shape[1]) & (row >= 0) & (row < grid.shape[0])
    hit = np.zeros(col.shape, dtype=bool)
    hit[inside] = grid[row[inside], col[inside]] >= 65
    first = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)
    return np.where(first >= 0, t[np.maximum(first, 0)], math.inf)


def square_drive(steps: int = 160, speed: float = 0.05) -> list[tuple[float, float, float]]:
    """Ground-truth poses of a loop through the floor's left room (every ``speed`` m)."""
    poses: list[tuple[float, float, float]] = []
    x, y, yaw = 1.0, 1.0, 0.0
    corners = [(4.0, 1.0), (4.0, 5.5), (1.0, 5.5), (1.0, 1.0)]
    k = 0
    while len(poses) < steps:
        tx, ty = corners[k % len(corners)]
        dx, dy = tx - x, ty - y
        dist = math.hypot(dx, dy)
        want = math.atan2(dy, dx)
        turn = math.remainder(want - yaw, 2 * math.pi)
        if abs(turn) > 0.15:
            yaw += math.copysign(0.15, turn)
        elif dist < speed:
            x, y, k = tx, ty, k + 1
        else:
            yaw = want
            x += speed * math.cos(yaw)
            y += speed * math.sin(yaw)
        poses.append((x, y, yaw))
    return poses


@pytest.fixture(scope="session")
def amcl_world() -> SimpleNamespace:
    """The synthetic floor: ``RES``, ``ORIGIN``, ``office_grid``, ``raycast``, ``square_drive``."""
    return SimpleNamespace(
        RES=RES, ORIGIN=ORIGIN, office_grid=office_grid, raycast=raycast, square_drive=square_drive
    )
