"""The root of visnav's exceptions.

Every error visnav raises on purpose derives from :class:`VisnavError`, so one
``except VisnavError`` catches them all. Subpackages define narrower classes
(for example :class:`visnav.msgs.MessageError`) that also derive from the
matching built-in (``ValueError``, ``LookupError``) where that helps callers.
"""

from __future__ import annotations

__all__ = ["VisnavError"]


class VisnavError(Exception):
    """Base class of every error raised by visnav."""
