"""Where a recording goes: an ``.rrd`` file, the web viewer on 127.0.0.1, a native viewer.

:func:`open_viewer` makes a ``rerun.RecordingStream`` with the chosen sinks:

* ``save``: a ``FileSink`` (the ``.rrd`` opens in any Rerun viewer of the same version);
* ``web``: the ``rerun`` executable of the wheel, started with ``--serve-web --bind
  127.0.0.1``, serves Rerun's bundled web viewer (HTML + WebAssembly) on port
  :data:`DEFAULT_WEB_PORT` (9090) and its gRPC server on :data:`DEFAULT_GRPC_PORT` (9876),
  and this process streams to that server. The server keeps at most ``memory_limit``
  (default :data:`DEFAULT_MEMORY_LIMIT`, 512 MB) for pages that connect late, dropping the
  oldest data beyond it; its own log lines (Rerun's warnings, e.g. "Sender has been
  blocked") go to ``log_path``, never to the terminal. Nothing is written to disk but that
  log unless ``save`` is given. (The Python ``rerun.serve_web_viewer`` has no bind address
  in rerun-sdk 0.41 and listens on 0.0.0.0, which is why the executable serves the page.);
* ``connect``: stream to a running viewer (``rerun+http://HOST:PORT/proxy``);
* none of these: spawn the native viewer (needs a display).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import uuid
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from visnav.viz._rerun import rr
from visnav.viz.errors import VizError
from visnav.viz.ports import (
    DEFAULT_GRPC_PORT,
    DEFAULT_MEMORY_LIMIT,
    DEFAULT_WEB_PORT,
    LOOPBACK,
    check_ports,
    die_with_parent,
    free_port,
)

__all__ = [
    "DEFAULT_GRPC_PORT",
    "DEFAULT_MEMORY_LIMIT",
    "DEFAULT_WEB_PORT",
    "LOOPBACK",
    "die_with_parent",
    "Viewer",
    "free_port",
    "open_viewer",
    "rerun_executable",
]


def rerun_executable() -> Path:
    """Return the ``rerun`` executable shipped in the rerun-sdk wheel (``$RERUN_CLI_PATH`` wins).

    Raises:
        VizError: the executable is missing.
    """
    override = os.environ.get("RERUN_CLI_PATH")
    if override:
        path = Path(override)
    else:
        spec = importlib.util.find_spec("rerun_cli")  # part of the rerun-sdk wheel
        if spec is None or spec.origin is None:
            raise VizError(
                "the rerun-sdk wheel has no rerun_cli package: reinstall the viewer extra "
                "(pip install --force-reinstall 'visnav[viz]')"
            )
        name = "rerun.exe" if os.name == "nt" else "rerun"
        path = Path(spec.origin).parent / name
    if not path.is_file():
        text = (
            f"the rerun executable {str(path)!r} is missing: reinstall the viewer extra "
            "(pip install --force-reinstall 'visnav[viz]')"
        )
        raise VizError(text)
    return path


def _wait_listening(port: int, proc: subprocess.Popen[bytes], log: Path, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            tail = log.read_text(errors="replace")[-2000:]
            text = f"the Rerun web viewer exited with code {proc.returncode}: {tail}"
            raise VizError(text)
        with contextlib.suppress(OSError), socket.create_connection((LOOPBACK, port), timeout=0.2):
            return
        time.sleep(0.05)
    text = f"the Rerun web viewer did not listen on {LOOPBACK}:{port} within {timeout_s} s"
    raise VizError(text)


class Viewer:
    """A Rerun recording and the outputs it streams to; close it (or use ``with``).

    Attributes:
        recording: the ``rerun.RecordingStream`` to log to (give it to a
            :class:`~visnav.viz.RerunSink`).
        url: the web viewer's address (``--web``), else None.
        grpc_url: the gRPC address viewers connect to (``--web``), else None.
        save: the ``.rrd`` file written, else None.
        web_process: the process serving the web viewer page, else None.
        log_path: the web viewer's log (Rerun's own messages), else None.
    """

    def __init__(
        self,
        recording: rr.RecordingStream,
        *,
        url: str | None = None,
        grpc_url: str | None = None,
        save: Path | None = None,
        web_process: subprocess.Popen[bytes] | None = None,
        web_log: IO[bytes] | None = None,
        log_path: Path | None = None,
    ) -> None:
        self.log_path = log_path
        self.recording = recording
        self.url = url
        self.grpc_url = grpc_url
        self.save = save
        self.web_process = web_process
        self._web_log = web_log
        self._closed = False

    def close(self) -> None:
        """Flush the recording, finish the file, stop the servers (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            self.recording.flush()
            self.recording.disconnect()
        finally:
            if self.web_process is not None:
                self.web_process.terminate()
                try:
                    self.web_process.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    self.web_process.kill()
                    self.web_process.wait()
            if self._web_log is not None:
                self._web_log.close()

    def __enter__(self) -> Viewer:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _has_display() -> bool:
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def _start_web(
    web_port: int, grpc_port: int, memory_limit: str, log_path: Path, timeout_s: float
) -> tuple[subprocess.Popen[bytes], IO[bytes]]:
    log_file = log_path.open("ab")
    cmd = [
        str(rerun_executable()),
        "--serve-web",
        "--bind",
        LOOPBACK,
        "--web-viewer-port",
        str(web_port),
        "--port",
        str(grpc_port),
        "--server-memory-limit",
        memory_limit,
    ]
    env = {**os.environ, "RERUN_ANALYTICS": "0", "NO_COLOR": "1"}  # a plain-text log
    process = subprocess.Popen(
        cmd,
        stdout=log_file,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        env=env,
        preexec_fn=die_with_parent(),  # noqa: PLW1509 - one prctl call, looked up before
    )
    try:
        _wait_listening(web_port, process, log_path, timeout_s)
        _wait_listening(grpc_port, process, log_path, timeout_s)
    except VizError:
        process.kill()
        process.wait()
        log_file.close()
        raise
    return process, log_file


def open_viewer(
    *,
    application_id: str = "visnav",
    save: str | Path | None = None,
    web: bool = False,
    port: int | None = DEFAULT_WEB_PORT,
    grpc_port: int | None = DEFAULT_GRPC_PORT,
    connect: str | None = None,
    spawn: bool | None = None,
    memory_limit: str = DEFAULT_MEMORY_LIMIT,
    log_path: str | Path | None = None,
    startup_timeout_s: float = 20.0,
) -> Viewer:
    """Create a recording streaming to the chosen outputs.

    Args:
        application_id: Rerun's application id (groups recordings in the viewer).
        save: write the recording to this ``.rrd`` file (nothing is written otherwise).
        web: serve the web viewer and a gRPC server, both on 127.0.0.1 only.
        port: port of the web viewer page (0 or None: a free one).
        grpc_port: port of the gRPC server (0 or None: a free one).
        connect: stream to a running viewer at this ``rerun+http://.../proxy`` URL.
        spawn: start the native viewer; default: when nothing else is asked for.
        memory_limit: what the gRPC server keeps for late viewers ("512MB", "10%").
        log_path: the web viewer's log file (default: ``visnav-viewer-<port>.log`` in
            the temporary directory).
        startup_timeout_s: how long to wait for the web viewer to listen.

    Returns:
        The :class:`Viewer`; its ``url`` is the page to open with ``web``.

    Raises:
        VizError: a bad path, a port in use, no display for the native viewer, a viewer
            that fails to start.
    """
    rec = rr.RecordingStream(application_id, recording_id=uuid.uuid4())
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    sinks: list[Any] = []
    save_path: Path | None = None
    if save is not None:
        save_path = Path(save)
        if save_path.suffix != ".rrd":
            text = f"--save {str(save_path)!r}: a Rerun recording file must end in .rrd"
            raise VizError(text)
        if not save_path.parent.is_dir():
            text = f"--save {str(save_path)!r}: directory {str(save_path.parent)!r} does not exist"
            raise VizError(text)
    url = grpc_url = None
    process: subprocess.Popen[bytes] | None = None
    log_file: IO[bytes] | None = None
    log: Path | None = None
    if web:
        wport = port or free_port()
        gport = grpc_port or free_port()
        check_ports(wport, gport)
        default_log = Path(tempfile.gettempdir()) / f"visnav-viewer-{wport}.log"
        log = Path(log_path) if log_path is not None else default_log
        process, log_file = _start_web(wport, gport, memory_limit, log, startup_timeout_s)
        grpc_url = f"rerun+http://{LOOPBACK}:{gport}/proxy"
        url = f"http://{LOOPBACK}:{wport}/?url={urllib.parse.quote(grpc_url, safe='')}"
        sinks.append(rr.GrpcSink(grpc_url))
    if save_path is not None:
        sinks.append(rr.FileSink(save_path))
    if connect is not None:
        sinks.append(rr.GrpcSink(connect))
    want_spawn = spawn if spawn is not None else not sinks
    if want_spawn and not _has_display():
        if process is not None:
            process.kill()
            process.wait()
        text = (
            "no display for the native Rerun viewer: use --web (browser at 127.0.0.1) "
            "or --save FILE.rrd"
        )
        raise VizError(text)
    if sinks:
        rec.set_sinks(*sinks)
    if want_spawn:
        rec.spawn()
    return Viewer(
        rec,
        url=url,
        grpc_url=grpc_url,
        save=save_path,
        web_process=process,
        web_log=log_file,
        log_path=log,
    )
