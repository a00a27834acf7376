"""Errors of :mod:`visnav.perception`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = [
    "CameraModelError",
    "DepthImageError",
    "DepthToScanError",
    "ImageProcError",
    "PerceptionError",
]


class PerceptionError(VisnavError):
    """Base class of the errors raised by :mod:`visnav.perception`."""


class CameraModelError(PerceptionError, ValueError):
    """A ``CameraInfo`` cannot make a usable camera model, or the model was misused.

    The text names the field, its value, what was expected and how to fix it.
    """


class DepthImageError(PerceptionError, ValueError):
    """A depth (or colour) image cannot be converted: wrong encoding, dtype or size."""


class DepthToScanError(PerceptionError, ValueError):
    """A depth image cannot be turned into a laser scan with the given parameters."""


class ImageProcError(PerceptionError, ValueError):
    """An image cannot be debayered, converted or rectified (encoding, calibration)."""
