"""Reading user-supplied text files: UTF-8 only, every failure one clear line.

Every file a user hands to visnav (launch files, trajectories, ``rgb.txt``,
camera_info YAML, ``--expect`` files, worlds, URDF / Xacro) is read through
:func:`read_text`, so a missing file, a directory, a permission problem or bytes
that are not UTF-8 become a :class:`TextFileError` naming the file, what it was
meant to be, the offending value and the fix, never a ``UnicodeDecodeError``
traceback. Like ROS 2's tools the files are UTF-8; a UTF-8 byte-order mark is
accepted and dropped.

This module sits at the root of the package (beside ``errors.py``) so that every
layer may use it.
"""

from __future__ import annotations

import errno
from collections.abc import Callable
from pathlib import Path

from visnav.errors import VisnavError

__all__ = ["TextFileError", "decode_text", "read_text"]

_BOM = "\ufeff"


class TextFileError(VisnavError, ValueError):
    """A user file that cannot be read as UTF-8 text (the message names it and the fix)."""


def _line_col(data: bytes, offset: int) -> tuple[int, int]:
    line = data.count(b"\n", 0, offset) + 1
    start = data.rfind(b"\n", 0, offset) + 1
    return line, offset - start + 1


def decode_text(
    data: bytes,
    *,
    source: str,
    what: str = "the file",
    error: Callable[[str], Exception] = TextFileError,
) -> str:
    """Decode UTF-8 bytes (a leading byte-order mark is dropped).

    Args:
        data: the file's bytes.
        source: the file name used in the error message.
        what: what the file is meant to be (e.g. ``"the launch file"``).
        error: the exception class raised (the caller's VisnavError subclass).

    Returns:
        The text.

    Raises:
        TextFileError: (or ``error``) the bytes are not UTF-8; the message gives the line, column
            and the offending byte.
    """
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _line_col(data, exc.start)
        bad = data[exc.start : exc.start + 1].hex()
        msg = (
            f"{source}:{line}: {what} is not UTF-8 text (byte 0x{bad} at column {col}); "
            "fix: save it as UTF-8 (e.g. iconv -f latin1 -t utf-8), or check that it is "
            "the right file"
        )
        raise error(msg) from None
    return text.removeprefix(_BOM)


def read_text(
    path: str | Path,
    *,
    what: str = "the file",
    error: Callable[[str], Exception] = TextFileError,
) -> str:
    """Read a UTF-8 text file given by the user.

    Args:
        path: the file.
        what: what the file is meant to be, for the message (``"the launch file"``).
        error: the exception class raised (the caller's VisnavError subclass).

    Returns:
        The text (without a UTF-8 byte-order mark).

    Raises:
        TextFileError: (or ``error``) the file is missing, a directory, unreadable, or not UTF-8.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        msg = f"{p}: {what} does not exist; fix: check the path"
        raise error(msg) from None
    except IsADirectoryError:
        msg = f"{p}: {what} is a directory, expected a file; fix: name the file inside it"
        raise error(msg) from None
    except PermissionError:
        msg = f"{p}: permission denied reading {what}; fix: check its permissions (ls -l)"
        raise error(msg) from None
    except OSError as exc:
        reason = exc.strerror or errno.errorcode.get(exc.errno or 0, str(exc))
        msg = f"{p}: cannot read {what}: {reason}"
        raise error(msg) from None
    return decode_text(data, source=str(p), what=what, error=error)
