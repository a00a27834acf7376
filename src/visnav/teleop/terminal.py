"""Single keys from a real terminal, as the teleop nodes read them.

:class:`TerminalKeys` puts standard input in raw input mode (no line buffering, no
echo, no signal keys: Ctrl-C arrives as a character, ETX, as with
``tty.setraw`` in the ROS nodes) while it is open and restores the saved settings on
:meth:`~TerminalKeys.close` (also on an exception or KeyboardInterrupt when used as a
context manager). Output processing is left on, so text printed meanwhile (the nodes'
status lines, other nodes' logs in the same process) still starts on a new line; the
ROS nodes get the same by restoring the terminal after each key.

A standard input that is not a terminal (a pipe, a file, ``/dev/null``, a test
runner's capture) is refused with :class:`~visnav.teleop.errors.NotATerminalError`.
"""

from __future__ import annotations

import codecs
import contextlib
import io
import os
import select
import sys
from typing import IO, Any, Protocol

from visnav.teleop.errors import NotATerminalError

__all__ = ["KeySource", "TerminalKeys"]


class KeySource(Protocol):
    """Where a teleop node gets its keys (a terminal, or a test's script)."""

    def read_keys(self, timeout_s: float) -> list[str]:
        """Return the keys typed so far, waiting up to ``timeout_s`` for the first."""

    def close(self) -> None:
        """Give the input back (restore the terminal)."""


def _fileno(stream: IO[str] | IO[bytes] | Any) -> int | None:
    try:
        return int(stream.fileno())
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        return None


class TerminalKeys:
    """Raw keys from a terminal (module docstring).

    Args:
        stream: The input (default ``sys.stdin``).
        who: The program named in the not-a-terminal message.

    Raises:
        NotATerminalError: ``stream`` is not a terminal.
    """

    def __init__(self, stream: IO[str] | None = None, *, who: str = "visnav teleop") -> None:
        stream = sys.stdin if stream is None else stream
        fd = None if stream is None else _fileno(stream)
        if fd is None or not os.isatty(fd):
            what = "closed" if stream is None else "not a terminal (a pipe, file or capture)"
            msg = (
                f"{who} reads single keys from the keyboard, but standard input is {what}. "
                "Fix: run it in an interactive terminal (not through a pipe, nohup or a test "
                "runner's capture); to send velocities without a keyboard use "
                "`visnav topic pub cmd_vel geometry_msgs/msg/Twist ...`"
            )
            raise NotATerminalError(msg)
        import termios  # noqa: PLC0415 - POSIX only

        self._fd = fd
        self._saved: list[Any] | None = termios.tcgetattr(fd)
        mode = termios.tcgetattr(fd)
        mode[0] &= ~(termios.BRKINT | termios.ICRNL | termios.INPCK | termios.ISTRIP | termios.IXON)
        mode[3] &= ~(termios.ECHO | termios.ICANON | termios.IEXTEN | termios.ISIG)
        mode[6][termios.VMIN] = 1
        mode[6][termios.VTIME] = 0
        termios.tcsetattr(fd, termios.TCSAFLUSH, mode)
        self._decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")

    def read_keys(self, timeout_s: float) -> list[str]:
        """Keys typed so far (one string per character), waiting up to ``timeout_s``."""
        if self._saved is None:
            return []
        ready, _, _ = select.select([self._fd], [], [], max(0.0, timeout_s))
        if not ready:
            return []
        try:
            data = os.read(self._fd, 256)
        except OSError:
            return []
        if not data:  # the terminal hung up: read as Ctrl-C, so the node stops the robot
            return ["\x03"]
        return list(self._decoder.decode(data))

    def close(self) -> None:
        """Restore the terminal settings saved at start (idempotent)."""
        if self._saved is None:
            return
        import termios  # noqa: PLC0415

        with contextlib.suppress(termios.error, OSError):
            termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
        self._saved = None

    def __enter__(self) -> TerminalKeys:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
