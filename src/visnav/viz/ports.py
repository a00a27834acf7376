"""The viewer's ports on 127.0.0.1, checked before anything starts (no Rerun import).

The web viewer's page listens on :data:`DEFAULT_WEB_PORT` (9090, ``--port``) and its gRPC
data server on :data:`DEFAULT_GRPC_PORT` (9876, ``--grpc-port``), Rerun's own defaults,
so a page stays bookmarked across runs; 0 asks for a free port. A port already taken
(another ``visnav view --web`` or ``visnav run --view``) is refused with
:func:`check_ports` before a run starts, naming the port and the option that changes it.
"""

from __future__ import annotations

import signal
import socket
import sys
import threading
from collections.abc import Callable

from visnav.viz.errors import VizError

__all__ = [
    "DEFAULT_GRPC_PORT",
    "DEFAULT_MEMORY_LIMIT",
    "DEFAULT_WEB_PORT",
    "LOOPBACK",
    "check_port",
    "check_ports",
    "die_with_parent",
    "free_port",
]

LOOPBACK = "127.0.0.1"
"""The only address the web viewer and its gRPC server listen on."""

DEFAULT_WEB_PORT = 9090
"""The web viewer page's port (Rerun's own default; ``--port`` changes it)."""

DEFAULT_GRPC_PORT = 9876
"""The gRPC server's port (Rerun's own default; ``--grpc-port`` changes it)."""

DEFAULT_MEMORY_LIMIT = "512MB"
"""What the gRPC server keeps for late viewers; the oldest data beyond it are dropped."""

_MAX_PORT = 65535


def free_port(host: str = LOOPBACK) -> int:
    """Return a TCP port that is free on ``host`` right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


def check_port(port: int, what: str, option: str, *, node: str | None = None) -> None:
    """Refuse a port that is out of range or taken on 127.0.0.1 (0: a free one, accepted).

    Args:
        port: the port.
        what: what listens there, for the message (``web viewer``).
        option: the command-line option that sets it (``--port``), or with ``node`` the
            node's parameter (``port``).
        node: the viewer node whose parameter ``option`` is (None: a command's option).

    Raises:
        VizError: the port is out of range or in use.
    """
    name = option if node is None else f"{node}'s parameter {option}"
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= _MAX_PORT:
        text = f"{name} is {port!r}: expected a TCP port 1-{_MAX_PORT} (0: a free one)"
        raise VizError(text)
    if port == 0:
        return
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind((LOOPBACK, port))
        except OSError as exc:
            fix = f"give {option} N" if node is None else f"set {name} to another port"
            text = (
                f"the {what} port {LOOPBACK}:{port} is in use ({exc.strerror}): "
                f"another viewer (visnav view, visnav run --view) may be serving there; stop "
                f"it or {fix} (0: a free one)"
            )
            raise VizError(text) from None


def check_ports(
    port: int,
    grpc_port: int,
    *,
    port_option: str = "--port",
    grpc_option: str = "--grpc-port",
    node: str | None = None,
) -> None:
    """Refuse the web viewer's two ports if equal, out of range or taken (see :func:`check_port`).

    Raises:
        VizError: what is wrong, the port and the option (or ``node``'s parameter) to change.
    """
    check_port(port, "web viewer", port_option, node=node)
    check_port(grpc_port, "viewer's gRPC", grpc_option, node=node)
    if port and port == grpc_port:
        where = "" if node is None else f" (parameters of {node})"
        text = f"{port_option} and {grpc_option}{where} are both {port}: give two different ports"
        raise VizError(text)


def die_with_parent() -> Callable[[], None] | None:
    """A ``preexec_fn`` that makes the child get SIGTERM when this thread ends (Linux).

    ``subprocess.Popen(..., preexec_fn=die_with_parent())`` from a process's main thread:
    a viewer's server (and the viewer process of ``visnav run --view``) then ends with the
    process that started it, even one killed with SIGKILL, and leaves no port bound.
    The C function is looked up here, before the fork: the child only calls it. None
    (nothing to do) off Linux or off the main thread, whose end would signal the child
    while the process lives on.
    """
    if not sys.platform.startswith("linux"):
        return None
    if threading.current_thread() is not threading.main_thread():
        return None
    import ctypes  # noqa: PLC0415 - Linux only

    prctl = ctypes.CDLL(None).prctl
    pr_set_pdeathsig = 1
    sigterm = int(signal.SIGTERM)

    def preexec() -> None:
        prctl(pr_set_pdeathsig, sigterm, 0, 0, 0)

    return preexec
