"""Errors of :mod:`visnav.mapping`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["CostmapError", "MappingError", "ObservationError"]


class MappingError(VisnavError):
    """Base class of the errors raised by :mod:`visnav.mapping`."""


class CostmapError(MappingError, ValueError):
    """A costmap was given a bad size, resolution, footprint or layer parameter.

    The text names the parameter, its value, what was expected and how to fix it.
    """


class ObservationError(MappingError, ValueError):
    """A sensor message cannot be turned into an observation (bad shape, frame or field)."""
