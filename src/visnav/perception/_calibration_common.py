"""Shared pieces of the calibration modules: the error type and the logger protocol."""

from __future__ import annotations

import logging
from typing import Protocol

from visnav.perception.errors import PerceptionError

__all__ = ["CalibrationError", "WarningLogger", "default_logger"]


class CalibrationError(PerceptionError, ValueError):
    """Calibration failed or a calibration file is unreadable (names the file/field)."""


class WarningLogger(Protocol):
    """What the calibration code needs from a logger (``logging.Logger`` fits)."""

    def warning(self, msg: str, /) -> None:
        """Log a warning."""


def default_logger() -> logging.Logger:
    """Return the ``visnav.perception.calibration`` standard-library logger."""
    return logging.getLogger("visnav.perception.calibration")
