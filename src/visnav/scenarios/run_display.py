"""What a scenario run shows while it goes: the progress bar and the ``--view`` feed."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from visnav.graph.context import Context

if TYPE_CHECKING:
    from visnav.viz.view_process import ViewPorts

__all__ = ["RunProgress", "ViewFeed"]

_LOG = logging.getLogger("visnav.scenarios")


class RunProgress:
    """The run's progress bar (rich): sim seconds done, real-time factor, ETA.

    On a terminal it is a live bar; otherwise (a log file, a pipe) one line per tenth.
    """

    def __init__(self, name: str, total_s: float, stream: TextIO) -> None:
        from rich.console import Console  # noqa: PLC0415 - only with progress output
        from rich.progress import (  # noqa: PLC0415
            BarColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.name, self.total = name, total_s
        self.console = Console(file=stream)
        self._last_decile = -1
        self._bar = Progress(
            TextColumn("[{task.description}]", markup=False),
            BarColumn(),
            TextColumn("sim {task.completed:6.1f}/{task.total:g} s  RTF {task.fields[rtf]:4.2f}"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            console=self.console,
            auto_refresh=self.console.is_terminal,
        )
        self._task = self._bar.add_task(name, total=total_s, rtf=0.0)
        self._live = self.console.is_terminal
        self._last_text = ""
        if self._live:
            self._bar.start()

    def update(self, sim_s: float, rtf: float, *, final: bool = False) -> None:
        """Show ``sim_s`` simulated seconds done at real-time factor ``rtf``."""
        self._bar.update(self._task, completed=min(sim_s, self.total), rtf=rtf)
        if self.console.is_terminal:
            if final:
                self._bar.refresh()
                self.close()
            return
        frac = min(1.0, sim_s / self.total) if self.total > 0 else 1.0
        decile = int(frac * 10)
        if decile != self._last_decile or final:
            self._last_decile = decile
            text = f"[{self.name}] sim {sim_s:.1f}/{self.total:g} s  RTF {rtf:.2f}"
            if text != self._last_text:
                self._last_text = text
                self.console.print(text, markup=False, highlight=False)

    def close(self) -> None:
        """Stop the live bar (idempotent; nothing to stop when not on a terminal)."""
        if self._live:
            self._live = False
            self._bar.stop()


class ViewFeed:
    """``--view``: stream the run to Rerun's web viewer (127.0.0.1:9090), write no recording.

    The viewer runs in a process of its own (:class:`visnav.viz.view_process.ViewProcess`)
    that subscribes to the run's topics over Zenoh; its log, and the web viewer's, go to
    ``OUT/viewer.log``. A context without Zenoh (``VISNAV_TRANSPORT=local``) keeps the
    viewer in this process (:class:`visnav.viz.live_view.LiveView`).

    Args:
        ctx: the run's graph context.
        out_dir: the run's output directory (``viewer.log`` goes there).
        stream: where the page's address is printed.
        view: the viewer's ports (True: the defaults, 9090 and 9876).

    Raises:
        VizError: the viewer could not start (a port in use: the port and the option).
    """

    def __init__(
        self, ctx: Context, out_dir: Path, stream: TextIO, view: ViewPorts | bool = True
    ) -> None:
        from visnav.viz.view_process import ViewPorts, ViewProcess  # noqa: PLC0415

        ports = view if isinstance(view, ViewPorts) else ViewPorts()
        log = out_dir / "viewer.log"
        self._process: ViewProcess | None = None
        self._view: Any = None
        self._warned = False
        if ctx.zenoh is not None:
            self._process = ViewProcess(ctx.domain, log, ports=ports)
            url = self._process.url
        else:  # no other process sees this graph
            from visnav.viz.live_view import LiveView  # noqa: PLC0415 - optional extra

            self._view = LiveView(
                ctx,
                port=ports.port,
                grpc_port=ports.grpc_port,
                log_path=log,
                sensors_in_use_only=True,
            )
            url = self._view.url
        stream.write(f"viewer: {url}\n")
        stream.flush()

    def poll(self) -> None:
        """Subscribe to new topics (in-process viewer); say once if the viewer process ended."""
        if self._view is not None:
            self._view.poll()
        elif self._process is not None and not self._warned and not self._process.alive():
            self._warned = True
            _LOG.warning(
                "the viewer process ended (exit code %s) and the run goes on without it; see %s",
                self._process.process.returncode,
                self._process.log_path,
            )

    def close(self) -> None:
        """Stop the viewer (its process ends, its ports are free again)."""
        if self._process is not None:
            self._process.close()
        if self._view is not None:
            self._view.close()
