"""The errors of :mod:`visnav.sim`: one base, :class:`SimError`.

Each error is also importable from the module that raises it (``SimulatorError`` from
:mod:`visnav.sim.simulator`, ``QuadrotorError`` from :mod:`visnav.sim.vehicles.quadrotor`,
...). Errors of robot and world files are :mod:`visnav.description.errors`.
"""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = [
    "CameraSensorError",
    "DiffDriveError",
    "QuadrotorError",
    "RenderingUnavailableError",
    "SecondSimulationError",
    "SensorTimingError",
    "SimError",
    "SimulationUnstableError",
    "SimulatorError",
    "SimulatorNodeError",
    "SpawnPoseError",
]


class SimError(VisnavError):
    """The simulator cannot be built or run as asked."""


class SimulatorError(SimError, ValueError):
    """The simulation cannot be built from the given world and robots."""


class SimulatorNodeError(SimError, ValueError):
    """A simulator node parameter is malformed."""


class SpawnPoseError(SimError, ValueError):
    """A spawn pose that is not finite or lies outside the world."""


class SimulationUnstableError(SimError, RuntimeError):
    """MuJoCo found NaN, Inf or huge values in the state: the run was stopped."""


class SecondSimulationError(SimError, RuntimeError):
    """Another simulation already publishes ``/clock`` in the graph domain."""


class RenderingUnavailableError(SimError, RuntimeError):
    """No headless OpenGL backend (EGL or OSMesa) could be used."""


class CameraSensorError(SimError, ValueError):
    """A camera's MuJoCo camera, canvas or lens model does not fit its spec."""


class SensorTimingError(SimError, ValueError):
    """A sensor update rate that is negative or not finite."""


class QuadrotorError(SimError, ValueError):
    """A MuJoCo model that does not fit the quadrotor controller."""


class DiffDriveError(SimError, ValueError):
    """A diff-drive configuration does not match the MuJoCo model."""
