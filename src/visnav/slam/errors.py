"""Errors of :mod:`visnav.slam`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = [
    "AssociationError",
    "EvaluationError",
    "SlamError",
    "SlamInputError",
    "TrajectoryFormatError",
]


class SlamError(VisnavError):
    """Base class of the errors raised by :mod:`visnav.slam`."""


class SlamInputError(SlamError, ValueError):
    """An input of the SLAM system is unusable (camera_info, image, depth, TUM folder).

    The text names the source (topic, file, field), the value, what was expected and
    the fix.
    """


class TrajectoryFormatError(SlamError, ValueError):
    """A trajectory file is not in TUM format (``stamp tx ty tz qx qy qz qw`` per line)."""


class AssociationError(SlamError, ValueError):
    """Two timestamp sequences have no (or too few) pairs within the allowed difference."""


class EvaluationError(SlamError, ValueError):
    """A trajectory metric cannot be computed (too few poses, degenerate alignment, ...)."""
