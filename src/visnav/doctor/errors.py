"""Errors of :mod:`visnav.doctor` (bad ``--expect`` files, unusable inputs)."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["DoctorError", "ExpectError"]


class DoctorError(VisnavError, ValueError):
    """doctor cannot run on the given input (nothing to observe, a bad argument)."""


class ExpectError(DoctorError):
    """An ``--expect`` file is malformed: the message names the file, key, value and fix."""
