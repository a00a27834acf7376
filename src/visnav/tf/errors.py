"""Errors of :mod:`visnav.tf`, named as tf2 names them.

tf2 raises ``LookupException`` (a frame is unknown), ``ConnectivityException``
(the frames are in two unconnected trees), ``ExtrapolationException`` (the
requested time is outside the stored data) and ``InvalidArgumentException``
(a malformed frame id or argument), all derived from ``TransformException``.
visnav keeps those names so code written against ``tf2_ros`` reads the same,
derives them from :class:`visnav.errors.VisnavError`, and attaches the facts of
the failure as attributes (``frame``, ``requested_ns``, ...) so tools such as
``visnav doctor`` need not parse the message text.
"""

from __future__ import annotations

from collections.abc import Sequence

from visnav.errors import VisnavError

__all__ = [
    "ConnectivityException",
    "ExtrapolationException",
    "InvalidArgumentException",
    "LookupException",
    "TransformException",
]


class TransformException(VisnavError):  # noqa: N818
    """Base class of every TF error (tf2's ``TransformException``)."""


class LookupException(TransformException, LookupError):  # noqa: N818
    """A frame is not known to the buffer, or the tree is malformed (a loop).

    Attributes:
        frame: the unknown frame id, when the error is about one frame.
        suggestions: known frame ids closest to ``frame`` (best first).
    """

    def __init__(
        self, message: str, *, frame: str | None = None, suggestions: Sequence[str] = ()
    ) -> None:
        super().__init__(message)
        self.frame = frame
        self.suggestions: tuple[str, ...] = tuple(suggestions)


class ConnectivityException(TransformException):
    """Both frames are known but lie in different trees (no chain of transforms links them).

    Attributes:
        target_frame: the frame transformed into.
        source_frame: the frame transformed from.
        target_root: the root of the tree holding ``target_frame``.
        source_root: the root of the tree holding ``source_frame``.
    """

    def __init__(
        self,
        message: str,
        *,
        target_frame: str = "",
        source_frame: str = "",
        target_root: str = "",
        source_root: str = "",
    ) -> None:
        super().__init__(message)
        self.target_frame = target_frame
        self.source_frame = source_frame
        self.target_root = target_root
        self.source_root = source_root


class ExtrapolationException(TransformException):
    """A link of the chain has no data at the requested time (before, after or between samples).

    Attributes:
        direction: ``"future"`` (after the newest sample), ``"past"`` (before the oldest),
            or ``"single"`` (the link holds one sample at another time).
        frame: the child frame of the link that failed.
        requested_ns: the requested time in nanoseconds.
        earliest_ns: the oldest stamp stored for ``frame``.
        latest_ns: the newest stamp stored for ``frame``.
        target_frame: the frame of the whole lookup transformed into.
        source_frame: the frame of the whole lookup transformed from.
    """

    def __init__(
        self,
        message: str,
        *,
        direction: str = "",
        frame: str = "",
        requested_ns: int = 0,
        earliest_ns: int = 0,
        latest_ns: int = 0,
        target_frame: str = "",
        source_frame: str = "",
    ) -> None:
        super().__init__(message)
        self.direction = direction
        self.frame = frame
        self.requested_ns = requested_ns
        self.earliest_ns = earliest_ns
        self.latest_ns = latest_ns
        self.target_frame = target_frame
        self.source_frame = source_frame


class InvalidArgumentException(TransformException, ValueError):  # noqa: N818
    """An argument is malformed: an empty frame id, a leading ``/``, a non-finite value, ..."""
