"""Errors of :mod:`visnav.msgs`."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = ["MessageError", "UnknownMessageTypeError"]


class MessageError(VisnavError, ValueError):
    """A message or a conversion input is malformed (the text names field, value, expectation)."""


class UnknownMessageTypeError(MessageError, LookupError):
    """A message type name is not in the type store."""
