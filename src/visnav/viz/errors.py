"""Errors of :mod:`visnav.viz`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["RERUN_MISSING_TEXT", "RerunMissingError", "VizError"]

RERUN_MISSING_TEXT = (
    "the viewer needs the Rerun SDK, which is not installed: install the viewer extra with "
    "pip install 'visnav[viz]' (or pip install rerun-sdk)"
)
"""The one message shown when ``rerun-sdk`` is missing."""


class VizError(VisnavError, ValueError):
    """The viewer cannot show something: a bad option, image or viewer set-up."""


class RerunMissingError(VizError, ImportError):
    """``rerun-sdk`` (the optional ``visnav[viz]`` extra) is not installed."""

    def __init__(self, detail: str = "") -> None:
        super().__init__(RERUN_MISSING_TEXT + (f" ({detail})" if detail else ""))
