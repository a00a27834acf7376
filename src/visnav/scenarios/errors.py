"""The scenarios' error base."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["ScenarioError"]


class ScenarioError(VisnavError, ValueError):
    """An unknown scenario, bad scenario options, or a world / robot a scenario cannot use."""
