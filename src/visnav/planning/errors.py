"""Errors of :mod:`visnav.planning`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["PlanningError"]


class PlanningError(VisnavError, ValueError):
    """A planner or controller was given a bad parameter or input.

    The text names the parameter, its value, what was expected and how to fix it.
    """
