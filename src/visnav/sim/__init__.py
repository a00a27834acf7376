"""Simulation: worlds, robot descriptions, vehicles and sensors on MuJoCo.

Submodules are imported explicitly (for example :mod:`visnav.sim.world`); importing
this package has no side effects.
"""

from __future__ import annotations

__all__: list[str] = []
