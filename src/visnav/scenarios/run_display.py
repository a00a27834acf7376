"""What a scenario run shows while it goes: the progress bar and the ``--view`` feed."""

from __future__ import annotations

from pathlib import Path
from typing import TextIO

from visnav.graph.context import Context

__all__ = ["RunProgress", "ViewFeed"]


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

    The viewer's own log goes to ``OUT/viewer.log``; see :class:`visnav.viz.live_view.LiveView`.
    """

    def __init__(self, ctx: Context, out_dir: Path, stream: TextIO) -> None:
        from visnav.viz.live_view import LiveView  # noqa: PLC0415 - optional extra

        # the images and clouds the run's nodes use: none rendered for display alone
        self._view = LiveView(ctx, log_path=out_dir / "viewer.log", sensors_in_use_only=True)
        stream.write(f"viewer: {self._view.url}\n")
        stream.flush()

    def poll(self) -> None:
        """Subscribe to new topics (the worker thread logs what arrives)."""
        self._view.poll()

    def close(self) -> None:
        """Stop the feed and the viewer."""
        self._view.close()
