"""Collision events between a robot and the world, from MuJoCo contacts (scenario metrics)."""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import Any

import mujoco

__all__ = ["ContactCounter"]


class ContactCounter:
    """Counts contact events between ``bodies`` and anything else.

    Call :meth:`update` at a fixed rate of sim time. A new event starts when the robot
    touches something after a sample without contact and more than ``gap_s`` after
    the last touching sample; a run of touching samples is one event.

    Args:
        sim: the simulator (its ``model`` and ``data`` are read).
        bodies: MuJoCo body ids of the robot.
        ignore_planes: contacts with plane geoms (the floor) do not count.
        gap_s: contacts closer together than this are one event.
    """

    def __init__(
        self, sim: Any, bodies: Collection[int], *, ignore_planes: bool, gap_s: float = 0.0
    ) -> None:
        self._sim = sim
        self._bodies = set(bodies)
        self._ignore_planes = ignore_planes
        self._gap_s = gap_s
        self._touching = False
        self._last_touch = -math.inf
        self.events = 0

    def touching(self) -> bool:
        """Whether the robot touches anything (but the floor, if ignored) now."""
        model, data = self._sim.model, self._sim.data
        for c in data.contact[: data.ncon]:
            b1, b2 = model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]
            if (b1 in self._bodies) == (b2 in self._bodies):
                continue
            other = c.geom2 if b1 in self._bodies else c.geom1
            if self._ignore_planes and model.geom_type[other] == mujoco.mjtGeom.mjGEOM_PLANE:
                continue
            return True
        return False

    def update(self, now_s: float) -> None:
        """Sample the contacts at sim time ``now_s``."""
        touching = self.touching()
        if touching and not self._touching and now_s - self._last_touch > self._gap_s:
            self.events += 1
        if touching:
            self._last_touch = now_s
        self._touching = touching
