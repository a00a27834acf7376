"""The errors of :mod:`visnav.description`: one base, :class:`DescriptionError`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = [
    "DescriptionError",
    "MeshFileError",
    "QuadrotorParamsError",
    "RobotDescriptionError",
    "WorldError",
    "WorldWarning",
]


class DescriptionError(VisnavError):
    """A robot or world description cannot be read."""


class RobotDescriptionError(DescriptionError, ValueError):
    """A URDF, Xacro or ``<gazebo>`` block is malformed or inconsistent.

    The message names the file (and line), the element, the offending value and
    the fix.
    """


class WorldError(DescriptionError, ValueError):
    """A world file, a world name, a generator parameter or a shape is invalid.

    The message names the file (and line when known), the field, the value,
    what was expected and how to fix it.
    """


class MeshFileError(DescriptionError, ValueError):
    """A mesh file is missing, of another format or malformed."""


class QuadrotorParamsError(DescriptionError, ValueError):
    """A ``libvisnav_quadrotor.so`` parameter is unknown or out of range."""


class WorldWarning(UserWarning):
    """Something in a world (usually SDF) is not supported and was skipped."""
