"""SIGTERM handled as Ctrl-C by every ``visnav`` command, and their exit codes.

A ``kill PID``, a CI job's timeout, ``docker stop`` and systemd stop a program with
SIGTERM, where a terminal sends SIGINT. Python's default for SIGTERM is to die at once:
no ``finally`` block runs, so children are left behind, a bag is not closed and a run
writes no summary. :class:`TerminateAsInterrupt` makes a SIGTERM do whatever a SIGINT
would do at that moment: call the SIGINT handler the command installed (a scenario
run's :class:`~visnav.scenarios.run_control.RunInterrupt`, ``bag record``'s stop flag),
or raise ``KeyboardInterrupt`` where Python's default handler is in place. The command
then ends as after Ctrl-C, and exits ``128 + 15 = 143`` instead of ``130``: the codes a
shell gives a program killed by that signal, which CI systems and supervisors read.

A command that handles SIGTERM itself (``visnav launch``, ``visnav run``) replaces this
handler while it runs and returns its own ``128 + signal`` code.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["STARTUP_INTERRUPTED", "StartupInterrupted", "TerminateAsInterrupt", "exit_code_for"]

STARTUP_INTERRUPTED = "interrupted during start-up"
"""The one line printed when a stop signal arrives while the command's modules load."""


class StartupInterrupted(KeyboardInterrupt):
    """Ctrl-C (or SIGTERM) while a verb still loads, before it started anything.

    A verb raises it from the KeyboardInterrupt of its start-up (its own modules, its
    files); ``main`` prints :data:`STARTUP_INTERRUPTED` and exits 130 (143).
    """


def exit_code_for(signum: int) -> int:
    """``128 + signum``: 130 after SIGINT, 143 after SIGTERM (as a shell reports them)."""
    return 128 + int(signum)


class TerminateAsInterrupt:
    """Route SIGTERM to the SIGINT handler in place when it arrives (see the module doc).

    Attributes:
        signals: the stop signals seen so far, in order: every SIGTERM, and the SIGINTs
            that came during :meth:`watch_sigint` while no command had its own handler.
    """

    def __init__(self) -> None:
        self.signals: list[int] = []

    @property
    def terminated(self) -> bool:
        """True when the first stop signal was a SIGTERM."""
        return bool(self.signals) and self.signals[0] == signal.SIGTERM

    def exit_code(self, code: int = 130) -> int:
        """``code``, or 143 for an interrupted exit (130 or 0 from an interrupt) after SIGTERM."""
        if self.terminated and code in (0, 130):
            return exit_code_for(signal.SIGTERM)
        return code

    def _on_sigterm(self, signum: int, frame: FrameType | None) -> None:
        self.signals.append(signum)
        handler = signal.getsignal(signal.SIGINT)
        if callable(handler):  # the command's handler, or Python's default_int_handler
            handler(signum, frame)
            return
        raise KeyboardInterrupt  # SIGINT ignored (a background job) or default: stop anyway

    def _on_startup_sigint(self, signum: int, frame: FrameType | None) -> None:
        del frame
        if signum == signal.SIGINT:  # a SIGTERM routed here is recorded already
            self.signals.append(signum)
        raise KeyboardInterrupt

    @contextlib.contextmanager
    def installed(self) -> Iterator[TerminateAsInterrupt]:
        """Handle SIGTERM with this object inside the block (main thread only; else as is)."""
        if threading.current_thread() is not threading.main_thread():  # main() in a thread
            yield self
            return
        previous = signal.signal(signal.SIGTERM, self._on_sigterm)
        try:
            yield self
        finally:
            signal.signal(signal.SIGTERM, previous)

    @contextlib.contextmanager
    def watch_sigint(self) -> Iterator[TerminateAsInterrupt]:
        """Note the SIGINTs that come inside the block, in Python's default handler's place.

        They still raise ``KeyboardInterrupt``. An interrupt inside a C extension can come
        out as another exception (numpy's import: ``ImportError: PyCapsule_Import could
        not import module "datetime"``); with the signal noted, ``main`` still knows it
        was an interrupt. A command that installs its own SIGINT handler replaces this one
        while it runs. A SIGINT that is ignored (a background job) stays ignored.
        """
        in_main = threading.current_thread() is threading.main_thread()
        if not in_main or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
            yield self
            return
        previous = signal.signal(signal.SIGINT, self._on_startup_sigint)
        try:
            yield self
        finally:
            signal.signal(signal.SIGINT, previous)
