"""Logging of visnav's processes: a quiet terminal, everything in a run's log file.

The terminal (stderr) shows visnav's own records at INFO and above and other libraries'
records at WARNING and above: a library's INFO line (PyOpenGL's "No OpenGL_accelerate
module loaded", matplotlib's "generated new fontManager") is not visnav's news. Python
warnings raised by other libraries (numba's ``NumbaPerformanceWarning``, deprecations)
become DEBUG records of the ``py.warnings`` logger; visnav's own warning categories
(a world's ``WorldWarning``) stay warnings, as one line each. With ``debug`` everything
is shown.

A log file (:func:`add_log_file`, ``visnav run`` writes ``OUT/run.log``) gets every
record, the terminal's filter aside: visnav's and Python warnings' from DEBUG up (start-up
conditions logged at debug level, the recorder's topic list), other libraries' from INFO.

:func:`kernel_compilation_notice` says once, when numba starts compiling a kernel that
its cache does not hold, that the first run compiles them (numba's ``numba:compile``
event fires only on a cache miss).
"""

from __future__ import annotations

import contextlib
import logging
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

__all__ = [
    "COMPILE_NOTICE",
    "CONSOLE_FORMAT",
    "FILE_FORMAT",
    "ConsoleFilter",
    "add_log_file",
    "configure_logging",
    "kernel_compilation_notice",
    "remove_log_file",
    "route_warnings",
]

CONSOLE_FORMAT = "[%(levelname)s] %(message)s"
FILE_FORMAT = "%(asctime)s [%(levelname)s] %(name)s: %(message)s"
COMPILE_NOTICE = "compiling kernels (first run only, about a minute; cached afterwards)"

_OWN = "_visnav_console"
_DEBUG_IN_FILE = ("visnav", "py.warnings")


def _is_visnav(name: str) -> bool:
    return name in ("root", "visnav") or name.startswith("visnav.")


class ConsoleFilter(logging.Filter):
    """Lets visnav's records through, and other libraries' at WARNING and above."""

    def filter(self, record: logging.LogRecord) -> bool:
        """True for a record the terminal shows."""
        return record.levelno >= logging.WARNING or _is_visnav(record.name)


def configure_logging(
    *, debug: bool = False, stream: TextIO | None = None, force: bool = False
) -> logging.Handler | None:
    """Log to ``stream`` (default stderr) as ``[LEVEL] message``, library noise filtered.

    Like :func:`logging.basicConfig`, this does nothing when the root logger already has
    handlers that are not this function's (a test harness's, an embedding program's),
    unless ``force``. Python warnings are routed into logging (:func:`route_warnings`)
    when a handler is installed.

    Args:
        debug: show DEBUG records and every library's lines.
        stream: where the terminal lines go (default ``sys.stderr``).
        force: replace the root logger's handlers.

    Returns:
        The console handler, or None when the root logger was left as it was.
    """
    root = logging.getLogger()
    foreign = [h for h in root.handlers if not getattr(h, _OWN, False)]
    if foreign and not force:
        return None
    for handler in list(root.handlers):
        root.removeHandler(handler)
    handler = logging.StreamHandler(sys.stderr if stream is None else stream)
    setattr(handler, _OWN, True)
    handler.setFormatter(logging.Formatter(CONSOLE_FORMAT))
    handler.setLevel(logging.DEBUG if debug else logging.INFO)
    if not debug:
        handler.addFilter(ConsoleFilter())
    root.addHandler(handler)
    root.setLevel(logging.DEBUG if debug else logging.INFO)
    if debug:  # numba's compiler logs megabytes per kernel at DEBUG
        logging.getLogger("numba").setLevel(logging.INFO)
    route_warnings()
    return handler


def route_warnings() -> None:
    """Show Python warnings through logging (visnav's at WARNING, others' at DEBUG)."""

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        del file, line
        if _is_visnav(getattr(category, "__module__", "")):
            logging.getLogger("visnav.warnings").warning("%s: %s", category.__name__, message)
            return
        text = " ".join(str(message).split())
        logging.getLogger("py.warnings").debug(
            "%s:%d: %s: %s", filename, lineno, category.__name__, text
        )

    warnings.showwarning = show


def add_log_file(path: str | Path) -> logging.Handler:
    """Write every record to ``path`` too: visnav's and Python warnings' from DEBUG up.

    visnav's loggers (and ``py.warnings``) go to DEBUG; other libraries keep theirs (numba
    at DEBUG would write megabytes per compiled kernel). The terminal's handler keeps its
    own level. Undo with :func:`remove_log_file`.

    Raises:
        OSError: the file cannot be opened.
    """
    handler = logging.FileHandler(path, encoding="utf-8")
    handler.setFormatter(logging.Formatter(FILE_FORMAT))
    handler.setLevel(logging.DEBUG)
    previous = {name: logging.getLogger(name).level for name in _DEBUG_IN_FILE}
    handler._visnav_previous_levels = previous  # type: ignore[attr-defined]
    logging.getLogger().addHandler(handler)
    for name in _DEBUG_IN_FILE:
        logging.getLogger(name).setLevel(logging.DEBUG)
    return handler


def remove_log_file(handler: logging.Handler) -> None:
    """Close a handler of :func:`add_log_file` and restore the loggers' levels (idempotent)."""
    root = logging.getLogger()
    if handler not in root.handlers:
        return
    root.removeHandler(handler)
    handler.close()
    previous = getattr(handler, "_visnav_previous_levels", {})
    for name, level in previous.items():
        logging.getLogger(name).setLevel(level)


@contextlib.contextmanager
def kernel_compilation_notice(text: str = COMPILE_NOTICE) -> Iterator[None]:
    """Log ``text`` (INFO, logger ``visnav.kernels``) once, when numba first compiles.

    Loading a kernel from numba's cache is silent; without numba nothing happens.
    """
    try:
        from numba.core import event  # noqa: PLC0415 - only where kernels may run
    except ImportError:  # pragma: no cover - numba is a dependency
        yield
        return

    class _Notice(event.Listener):
        said = False

        def on_start(self, ev: Any) -> None:
            del ev
            if not self.said:
                self.said = True
                logging.getLogger("visnav.kernels").info("%s", text)

        def on_end(self, ev: Any) -> None:
            del ev

    with event.install_listener("numba:compile", _Notice()):
        yield
