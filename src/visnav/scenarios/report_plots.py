"""The sweep report's plots (matplotlib, Agg): PNG bytes for :mod:`visnav.scenarios.report`.

Trajectories are the ground-truth odometry recorded in each run's bag (car:
``/ground_truth/odom``, drone: ``/drone/odom``), drawn over the true occupancy of the
run's own world (the seed shapes the world): the office's floor plan for the car, the
forest's top view at flight height for the drone. Failed runs are drawn in red with
their reason.
"""

from __future__ import annotations

import io
import math
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from visnav.scenarios.runner import SCENARIOS

if TYPE_CHECKING:
    from visnav.description.worldmodel import WorldDescription

__all__ = [
    "TRAJECTORY_TOPICS",
    "distribution_png",
    "figure_png",
    "fit_title",
    "new_figure",
    "read_trajectory",
    "success_png",
    "trajectories_png",
    "world_map",
    "world_occupancy",
]

TRAJECTORY_TOPICS = {"car": "/ground_truth/odom", "drone": "/drone/odom"}
"""The ground-truth odometry topic of each scenario's bag."""

_DPI = 100
_MAX_POINTS = 2000


def new_figure(width_in: float, height_in: float) -> Any:
    """A matplotlib Figure of that size in inches (Agg, no pyplot)."""
    from matplotlib.figure import Figure  # noqa: PLC0415 - no pyplot: no global state

    return Figure(figsize=(width_in, height_in), dpi=_DPI)


def fit_title(fig: Any, ax: Any, text: str, **kwargs: Any) -> None:
    """Set the axes' title and lay the figure out, the title wrapped until it fits.

    A title is centred over its axes, which the y label pushes right: on a narrow figure
    (one setting) a one-line title ran past the right edge and was cut.
    """
    per_line = len(text)
    for _ in range(4):
        ax.set_title(textwrap.fill(text, per_line, break_long_words=False), **kwargs)
        fig.tight_layout()
        box = ax.title.get_window_extent()
        centre = (box.x0 + box.x1) / 2
        room = 2 * min(centre, fig.bbox.width - centre) - 4  # px a centred line may span
        if box.width <= room:
            return
        longest = max(len(line) for line in ax.get_title().splitlines())
        per_line = max(8, min(per_line - 1, math.floor(longest * room / box.width)))


def figure_png(fig: Any) -> bytes:
    """The figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    return buf.getvalue()


def success_png(
    labels: Sequence[str], rates: Sequence[float], intervals: Sequence[tuple[float, float]]
) -> bytes:
    """Bar chart of the success rate per setting with its 95 % Wilson interval."""
    fig = new_figure(max(4.0, 1.2 * len(labels) + 2.0), 3.2)
    ax = fig.add_subplot()
    x = np.arange(len(labels))
    lo = [max(0.0, r - i[0]) for r, i in zip(rates, intervals, strict=True)]
    hi = [max(0.0, i[1] - r) for r, i in zip(rates, intervals, strict=True)]
    ax.bar(
        x,
        [100 * r for r in rates],
        color="#4c72b0",
        yerr=[[100 * v for v in lo], [100 * v for v in hi]],
        capsize=6,
    )
    ax.set_xticks(x, [textwrap.fill(lbl, 18) for lbl in labels], fontsize=8)
    ax.set_ylim(0, 105)
    ax.set_ylabel("successful runs (%)")
    fit_title(fig, ax, "success per setting (95 % Wilson interval)")
    return figure_png(fig)


def distribution_png(
    title: str, unit: str, labels: Sequence[str], values: Sequence[Sequence[float]]
) -> bytes:
    """Box plot per setting with every run's value drawn over it."""
    fig = new_figure(max(4.0, 1.2 * len(labels) + 2.0), 3.2)
    ax = fig.add_subplot()
    data = [list(v) for v in values]
    ax.boxplot(data, showfliers=False)
    rng = np.random.default_rng(0)  # jitter only; seeded so the report is reproducible
    for i, vals in enumerate(data, start=1):
        ax.scatter(i + rng.uniform(-0.12, 0.12, len(vals)), vals, s=12, color="#dd8452", zorder=3)
    ax.set_xticks(
        np.arange(1, len(labels) + 1), [textwrap.fill(lb, 18) for lb in labels], fontsize=8
    )
    ax.set_ylabel(unit)
    fit_title(fig, ax, title)
    return figure_png(fig)


def read_trajectory(bag: Path, scenario: str) -> npt.NDArray[np.float64] | None:
    """The ``(N, 2)`` x-y ground-truth track of a run's bag (None: no readable bag)."""
    from visnav.bag import BagError, read_bag  # noqa: PLC0415

    topic = TRAJECTORY_TOPICS.get(scenario)
    if topic is None or not bag.exists():
        return None
    xy: list[tuple[float, float]] = []
    try:
        for m in read_bag(bag, [topic]):
            p = m.msg.pose.pose.position
            xy.append((p.x, p.y))
    except (BagError, OSError, ValueError, RuntimeError):  # a killed run's bag ends early
        if not xy:
            return None
    if not xy:
        return None
    track = np.asarray(xy, dtype=np.float64)
    step = max(1, len(track) // _MAX_POINTS)
    return track[::step]


def world_map(
    scenario: str, seed: int
) -> tuple[npt.NDArray[np.bool_], tuple[float, float, float, float]]:
    """The true occupancy of the scenario's world for ``seed`` and its extent (x0, x1, y0, y1)."""
    from visnav.description.world import load_world  # noqa: PLC0415 - heavy

    sdef = SCENARIOS[scenario]
    return world_occupancy(load_world(sdef.world, seed=seed), flight=scenario == "drone")


def world_occupancy(
    world: WorldDescription, *, flight: bool = False
) -> tuple[npt.NDArray[np.bool_], tuple[float, float, float, float]]:
    """The true occupancy of a loaded world and its extent (x0, x1, y0, y1).

    Args:
        world: the world.
        flight: the top view at the drone's flight height (0.5-1.5 m, 20 cm cells)
            instead of the floor plan (5-200 cm above the ground, 5 cm cells).
    """
    from visnav.sim.world_geometry import true_occupancy_grid  # noqa: PLC0415 - heavy

    # the flight height band: take-off to 1 m
    res, band = (0.2, (0.5, 1.5)) if flight else (0.05, (0.05, 2.0))
    grid, origin = true_occupancy_grid(world, res, band)
    ny, nx = grid.shape
    return grid, (origin[0], origin[0] + nx * res, origin[1], origin[1] + ny * res)


def trajectories_png(scenario: str, runs: Sequence[dict[str, Any]], *, cols: int = 5) -> bytes:
    """One panel per run: its ground-truth track over its world's map; failures in red.

    Args:
        scenario: the sweep's scenario.
        runs: dicts with ``seed``, ``status``, ``reason``, ``track`` ((N, 2) or None),
            ``ok_task`` (True when every goal was reached without collision).
        cols: panels per row.
    """
    cols = max(1, min(cols, len(runs)))
    rows = math.ceil(len(runs) / cols)
    fig = new_figure(3.0 * cols, 3.2 * rows)
    maps: dict[int, Any] = {}
    for i, run in enumerate(runs):
        ax = fig.add_subplot(rows, cols, i + 1)
        seed = int(run["seed"])
        if seed not in maps:
            maps[seed] = world_map(scenario, seed)
        grid, extent = maps[seed]
        ax.imshow(
            grid,
            origin="lower",
            extent=extent,
            cmap="Greys",
            vmin=0,
            vmax=1.5,
            interpolation="nearest",
        )
        track = run.get("track")
        failed = run["status"] != "ok"
        colour = "#d62728" if failed else ("#2ca02c" if run.get("ok_task") else "#ff7f0e")
        if track is not None and len(track):
            ax.plot(track[:, 0], track[:, 1], color=colour, lw=1.2)
            ax.plot(track[0, 0], track[0, 1], "o", color="#1f77b4", ms=4)
            ax.plot(track[-1, 0], track[-1, 1], "x", color=colour, ms=6)
        title = f"seed {seed}"
        if failed:
            title += "\nFAILED: " + textwrap.shorten(str(run.get("reason")), 60)
        elif not run.get("ok_task"):
            title += "\ngoal missed or collision"
        ax.set_title(title, fontsize=7, color="#d62728" if failed else "black")
        ax.set_xticks([])
        ax.set_yticks([])
        if failed:
            for side in ax.spines.values():
                side.set_color("#d62728")
                side.set_linewidth(2.5)
    fig.tight_layout()
    return figure_png(fig)
