"""Errors of :mod:`visnav.bag`: each names the bag (file or directory) and the fix."""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = [
    "BagError",
    "BagExistsError",
    "BagNotFoundError",
    "CorruptBagError",
    "RecordError",
    "TopicNotInBagError",
    "UnknownStorageError",
]


class BagError(VisnavError):
    """Base class of the bag errors."""


class BagNotFoundError(BagError, FileNotFoundError):
    """The bag path does not exist."""


class BagExistsError(BagError, FileExistsError):
    """The output of a recording or conversion exists already (bags are never overwritten)."""


class UnknownStorageError(BagError, ValueError):
    """The path is no bag visnav can read, or a format/compression name is unknown."""


class CorruptBagError(BagError, ValueError):
    """The bag's bytes do not decode (damaged, or truncated before its first complete chunk)."""


class TopicNotInBagError(BagError, LookupError):
    """A topic asked for is not in the bag (the message suggests the closest names)."""


class RecordError(BagError, ValueError):
    """A recording cannot start (bad option) or cannot go on (the bag cannot be written)."""
