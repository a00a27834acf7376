"""Errors of :mod:`visnav.launch`.

Every message names the launch file and line where it can, the offending value,
what was expected and the fix; the CLI prints it as one ``error: ...`` line.
"""

from __future__ import annotations

from visnav.errors import VisnavError

__all__ = [
    "LaunchArgError",
    "LaunchError",
    "LaunchParseError",
    "LaunchProcessError",
    "RoslaunchImportError",
    "where",
]


def where(file: str | None, line: int | None) -> str:
    """Return ``"file:line: "`` (or the parts that are known) as a message prefix."""
    if file is None:
        return ""
    return f"{file}:{line}: " if line is not None else f"{file}: "


class LaunchError(VisnavError):
    """Base class of the errors raised by :mod:`visnav.launch`."""


class LaunchParseError(LaunchError, ValueError):
    """A launch file does not parse, or an entry has a wrong key, type or value."""


class LaunchArgError(LaunchError, LookupError):
    """A launch argument is missing, unknown or given twice (the closest name is suggested)."""


class LaunchProcessError(LaunchError, RuntimeError):
    """A node process could not be started or a shared node could not be built."""


class RoslaunchImportError(LaunchError, ValueError):
    """A roslaunch XML file uses elements visnav cannot map (all listed in one message)."""
