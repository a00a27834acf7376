"""Simulation on MuJoCo: the model built from :mod:`visnav.description` specs, sensors, vehicles.

Robot and world files are parsed in :mod:`visnav.description`; here they become one MuJoCo
model (:mod:`visnav.sim.world_spec`, :mod:`visnav.sim.robot`), whose Gazebo sensors and
plugins are built through the registry of :mod:`visnav.sim.plugin_factories` and stepped
by :class:`visnav.sim.simulator.Simulator`. Submodules are imported explicitly (for
example :mod:`visnav.sim.simulator`); importing this package has no side effects.
"""

from __future__ import annotations

__all__: list[str] = []
