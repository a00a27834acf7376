"""The one place that imports the optional Rerun SDK, turning its absence into one clear error."""

from __future__ import annotations

from visnav.viz.errors import RerunMissingError

try:
    import rerun as rr
except ImportError as exc:
    raise RerunMissingError(str(exc)) from exc

__all__ = ["rr"]
