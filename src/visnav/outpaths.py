"""Checks of output paths made before a run starts, so a long run never fails at its end.

``visnav slam -o DIR`` used to run the whole sequence and then fail to write the
trajectory onto a directory; ``visnav run --out /dev/null`` failed deep inside
the recorder. :func:`check_output_file` and :func:`check_output_dir` refuse
such paths up front with one line naming the path, what is wrong and the fix.
They check what can be known before writing (the kind of the path, the parent
being a directory, write permission); a full disk still shows up when writing.

This module sits at the root of the package (beside ``errors.py``) so that every
layer may use it.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from visnav.errors import VisnavError

__all__ = ["OutputPathError", "check_output_dir", "check_output_file"]


class OutputPathError(VisnavError, ValueError):
    """An output path that cannot be written (the message names it and the fix)."""


def _existing_ancestor(path: Path) -> Path:
    p = path.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _check_parent(path: Path, what: str, error: Callable[[str], Exception]) -> None:
    ancestor = _existing_ancestor(path.parent)
    if not ancestor.is_dir():
        msg = (
            f"{path}: cannot write {what}: {ancestor} is a file, not a directory; "
            "fix: choose another path"
        )
        raise error(msg)
    if not os.access(ancestor, os.W_OK | os.X_OK):
        msg = (
            f"{path}: cannot write {what}: no write permission in {ancestor}; "
            "fix: choose a path you can write"
        )
        raise error(msg)


def check_output_file(
    path: str | Path,
    *,
    what: str = "the output file",
    error: Callable[[str], Exception] = OutputPathError,
) -> Path:
    """Refuse an output file path that cannot be written, before any work is done.

    An existing regular file is fine (it is replaced, as ROS tools do); a
    directory, a device or a FIFO is not, nor a path under a file or in a
    directory without write permission.

    Args:
        path: the file to be written.
        what: what it is, for the message (``"the trajectory"``).
        error: the exception class raised (the caller's VisnavError subclass).

    Returns:
        The path.

    Raises:
        OutputPathError: (or ``error``) the path cannot be written as a file.
    """
    p = Path(path)
    if p.is_dir():
        msg = (
            f"{p}: is a directory; {what} is a file; fix: give a file name "
            f"(e.g. {p / 'trajectory.txt'})"
        )
        raise error(msg)
    if p.exists() and not p.is_file():
        msg = f"{p}: is not a regular file (a device or pipe); fix: give a file path for {what}"
        raise error(msg)
    if p.exists() and not os.access(p, os.W_OK):
        msg = f"{p}: no write permission for {what}; fix: choose another path or chmod u+w"
        raise error(msg)
    _check_parent(p, what, error)
    return p


def check_output_dir(
    path: str | Path,
    *,
    what: str = "the output directory",
    error: Callable[[str], Exception] = OutputPathError,
) -> Path:
    """Refuse an output directory path that cannot be created or written.

    Args:
        path: the directory (created later by the caller if missing).
        what: what it is, for the message.
        error: the exception class raised.

    Returns:
        The path.

    Raises:
        OutputPathError: (or ``error``) the path exists and is not a directory, or
            it cannot be created or written.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        msg = f"{p}: is not a directory ({what} must be one); fix: give a directory path"
        raise error(msg)
    if p.is_dir():
        if not os.access(p, os.W_OK | os.X_OK):
            msg = f"{p}: no write permission for {what}; fix: choose another directory"
            raise error(msg)
        return p
    _check_parent(p / "x", what, error)
    return p
