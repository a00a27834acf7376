"""Errors of :mod:`visnav.message_filters`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["MessageFilterError"]


class MessageFilterError(VisnavError, ValueError):
    """A filter or synchronizer was built or queried with invalid arguments.

    Bad *messages* (no header, stamps going backwards) are not errors: the
    filters log a warning and drop or keep them as their ROS counterparts do.
    """
