"""Synthetic RGB-D sequences (textured box room, exact depth) shared by the SLAM tests."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from visnav.slam.camera import CameraIntrinsics
from visnav.slam.synthetic import SyntheticRoom, circle_trajectory

SMALL = CameraIntrinsics(125.0, 125.0, 79.5, 59.5, 160, 120)


@dataclass(frozen=True)
class Sequence:
    camera: CameraIntrinsics
    poses: np.ndarray
    stamps_ns: np.ndarray
    rgb: list[np.ndarray]
    depth: list[np.ndarray]

    @property
    def stamps_s(self) -> np.ndarray:
        return self.stamps_ns.astype(np.float64) * 1e-9


def make_sequence(
    n: int, *, turns: float, seed: int = 1, cam: CameraIntrinsics = SMALL
) -> Sequence:
    room = SyntheticRoom(seed=seed)
    poses = circle_trajectory(n, turns=turns)
    frames = [room.render(cam, p) for p in poses]
    stamps = (1_000_000_000 + np.arange(n) * 33_333_333).astype(np.int64)
    return Sequence(cam, poses, stamps, [f[0] for f in frames], [f[1] for f in frames])


@pytest.fixture(scope="session")
def short_sequence() -> Sequence:
    """40 frames along a sixth of the loop."""
    return make_sequence(40, turns=40 / 130)


@pytest.fixture(scope="session")
def loop_sequence() -> Sequence:
    """A full loop and a bit (150 frames): the end revisits the start."""
    return make_sequence(150, turns=1.15)
