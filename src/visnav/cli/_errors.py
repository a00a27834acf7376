"""The CLI's error boundary: any exception that reaches ``main`` becomes one line.

visnav's own errors (:class:`~visnav.errors.VisnavError`) already name the file,
the value and the fix. The errors of the libraries underneath (the OS, codecs,
PyYAML, OpenCV, the rosbags serializer, memory) are translated here into the same
shape, with the file name when the exception carries one and a fix per kind; a
bug in visnav itself says so and asks for ``--debug``. Tracebacks appear only
with ``--debug`` (the boundary in :mod:`visnav.cli.main` prints them).
"""

from __future__ import annotations

import errno
import sys

from visnav.errors import VisnavError

__all__ = ["describe_error"]

_OS_FIXES: dict[int, str] = {
    errno.ENOENT: "check the path",
    errno.EACCES: "check the permissions (ls -l) or choose another path",
    errno.EPERM: "check the permissions (ls -l) or choose another path",
    errno.EISDIR: "give a file, not a directory",
    errno.ENOTDIR: "a part of the path is a file, not a directory; check the path",
    errno.EEXIST: "remove it or choose another path",
    errno.ENOSPC: "free disk space or write elsewhere",
    errno.EDQUOT: "free disk space (quota) or write elsewhere",
    errno.EFBIG: "the file is too large for this filesystem; write to another filesystem",
    errno.EROFS: "the filesystem is read-only; write elsewhere",
    errno.ENAMETOOLONG: "use a shorter name",
    errno.EMFILE: "too many open files; raise the limit (ulimit -n)",
    errno.EADDRINUSE: "another process uses this address; stop it or choose another port",
    errno.ECONNREFUSED: "nothing listens there; start the other side first",
}


def _os_error(exc: OSError) -> str:
    names = [str(n) for n in (exc.filename, exc.filename2) if n is not None]
    where = f"{' -> '.join(names)}: " if names else ""
    reason = exc.strerror or str(exc) or type(exc).__name__
    fix = _OS_FIXES.get(exc.errno or -1, "check the path and that the device works")
    return f"{where}{reason}; fix: {fix}"


def _cv2_error(exc: BaseException) -> str:
    func = getattr(exc, "func", None) or "?"
    err = getattr(exc, "err", None) or " ".join(str(exc).split())
    return (
        f"OpenCV could not process the data in {func}(): {err}; fix: check the image "
        "(size, encoding, step) or the file it came from; run with --debug for the traceback"
    )


def _module_of(exc: BaseException) -> str:
    return type(exc).__module__.split(".", 1)[0]


def describe_error(exc: BaseException) -> str:
    """One line (without ``error: ``) for an exception that reached the CLI boundary.

    Args:
        exc: the exception.

    Returns:
        The message: the file and value where the exception carries them, and a fix.
    """
    if isinstance(exc, VisnavError):
        return " ".join(str(exc).split("\n"))
    if isinstance(exc, UnicodeDecodeError):
        bad = exc.object[exc.start : exc.start + 1].hex()
        return (
            f"a file is not {exc.encoding} text (byte 0x{bad} at offset {exc.start}); "
            "fix: save it as UTF-8; run with --debug to see which file"
        )
    if isinstance(exc, OSError):
        return _os_error(exc)
    if isinstance(exc, MemoryError):
        return (
            "out of memory; fix: give a smaller input (image size, duration, number of "
            "messages) or free memory"
        )
    module = _module_of(exc)
    detail = " ".join(str(exc).split())[:300]
    if module == "cv2" or (type(exc).__name__ == "error" and "OpenCV" in str(exc)):
        return _cv2_error(exc)
    if module == "yaml":
        return f"invalid YAML: {detail}; fix the syntax of the YAML file or value"
    if module in ("struct", "_struct"):
        return (
            f"binary data ends early or is corrupt ({detail}); fix: check the file or message "
            "(is it complete, and of the expected type?)"
        )
    if module == "zenoh":
        return (
            f"the graph transport (zenoh) failed: {detail}; fix: check VISNAV_LISTEN / "
            "VISNAV_CONNECT and that the port is free"
        )
    if module == "rosbags":
        return (
            f"a message could not be (de)serialized: {detail}; fix: check the message type "
            "and that the data was written with that type"
        )
    return (
        f"internal error {type(exc).__name__}: {detail}; this is a bug in visnav: please "
        f"report it with the output of 'visnav --debug {' '.join(sys.argv[1:])}'"
    )
