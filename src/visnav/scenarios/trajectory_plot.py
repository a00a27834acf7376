"""``trajectory.png``: the picture of one run that ``visnav run`` writes beside summary.json.

A top view (x-y, metres, in the map / world frame) of what happened: the map (the run's
saved ``map.yaml``, else the last map on the observer's map topic in the bag, else the
world's true occupancy; the drone always gets the forest's trees at flight height), the
ground truth, the SLAM estimate (``slam/path`` + later ``slam/pose``), the localisation
(``map -> base`` from TF, when AMCL or another localiser publishes it), the wheel odometry
(anchored at the first ground-truth pose, so its drift shows), the drone's planned paths,
the goals (numbered in the order sent; reached: green star, missed: red cross, still
under way when the run ended: yellow diamond), the start and the end.

Everything comes from the run's bag and files, read with the topic names of the launch
file's ``scenario_observer`` entry (:class:`~visnav.scenarios.observer.ObserverParams`),
so a scenario launch file of the user's gets its picture too, and the observer may run in
any process. :func:`trajectory_png` draws a :class:`RunTracks` (no bag, no graph: tested
on synthetic tracks); :func:`write_trajectory_png` is what :mod:`visnav.scenarios.runner`
calls; it never raises (a picture that cannot be drawn is a warning, not a failed run).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from visnav.scenarios.report_plots import figure_png, new_figure, world_occupancy

if TYPE_CHECKING:
    from collections.abc import Mapping

    from visnav.launch.description import LaunchDescription, NodeSpec
    from visnav.scenarios.observer import ObserverParams

__all__ = [
    "TRAJECTORY_PNG",
    "GoalMark",
    "RunTracks",
    "map_shade",
    "read_run_tracks",
    "trajectory_png",
    "write_trajectory_png",
]

TRAJECTORY_PNG = "trajectory.png"
"""The picture's file name in the run's output directory."""

XY = npt.NDArray[np.float64]
_LOG = logging.getLogger("visnav.scenarios")
_MAX_POINTS = 4000  # per line: more only slows the drawing down
_FREE, _UNKNOWN, _WORLD_OCCUPIED = 1.0, 0.82, 0.45  # grey shades (0 black, 1 white)
_LINES = (  # label prefix -> (colour, width, style)
    ("SLAM", "#1f77b4", 1.3, "-"),
    ("localisation", "#2ca02c", 1.3, "-"),
    ("wheel odometry", "#ff7f0e", 1.2, "--"),
)


@dataclasses.dataclass(frozen=True)
class GoalMark:
    """One goal sent to the robot: where, whether it ended and whether it was reached."""

    x: float
    y: float
    reached: bool
    ended: bool = True


@dataclasses.dataclass
class RunTracks:
    """What :func:`trajectory_png` draws; every track is ``(N, 2)`` x-y in metres.

    Attributes:
        title: the picture's title.
        truth: the ground-truth track.
        estimates: further tracks by legend label, e.g. ``"SLAM (slam/path)"``,
            ``"localisation (amcl)"``, ``"wheel odometry (/odom)"``.
        goals: the goals in the order sent (the first ``goals`` the observer counts).
        plans: planned paths (drawn thin).
        shade: the map as grey shades in ``[0, 1]`` (row 0 at ``extent``'s y0), or None.
        extent: the map's ``(x0, x1, y0, y1)``.
        map_label: what the map is (legend).
    """

    title: str
    truth: XY
    estimates: dict[str, XY] = dataclasses.field(default_factory=dict)
    goals: list[GoalMark] = dataclasses.field(default_factory=list)
    plans: list[XY] = dataclasses.field(default_factory=list)
    shade: npt.NDArray[np.float64] | None = None
    extent: tuple[float, float, float, float] | None = None
    map_label: str = ""


# ---------------------------------------------------------------------------- drawing
def _thin(track: XY) -> XY:
    step = max(1, math.ceil(len(track) / _MAX_POINTS))
    return track if step == 1 else np.vstack([track[::step], track[-1:]])


def _bounds(tracks: RunTracks) -> tuple[float, float, float, float]:
    """``(x0, x1, y0, y1)`` holding the map's known cells, every track and goal, and a margin.

    A map's unknown border is left out (ROBOTIS' 20 m map of a 5 m arena).
    """
    pts = [t for t in (tracks.truth, *tracks.estimates.values(), *tracks.plans) if len(t)]
    if tracks.goals:
        pts.append(np.array([(g.x, g.y) for g in tracks.goals]))
    if tracks.extent is not None and tracks.shade is not None:
        x0, x1, y0, y1 = tracks.extent
        rows, cols = np.nonzero(tracks.shade != _UNKNOWN)
        if len(rows):
            height, width = tracks.shade.shape
            sx, sy = (x1 - x0) / width, (y1 - y0) / height
            x0, x1 = x0 + cols.min() * sx, x0 + (cols.max() + 1) * sx
            y0, y1 = y0 + rows.min() * sy, y0 + (rows.max() + 1) * sy
        pts.append(np.array([(x0, y0), (x1, y1)]))
    allp = np.vstack(pts) if pts else np.zeros((1, 2))
    allp = allp[np.isfinite(allp).all(axis=1)]
    if not len(allp):
        allp = np.zeros((1, 2))
    lo, hi = allp.min(axis=0) - 0.5, allp.max(axis=0) + 0.5
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def trajectory_png(tracks: RunTracks) -> bytes:
    """Draw a run's top view (module docstring) and return it as PNG bytes.

    The same tracks give the same bytes (matplotlib's Agg renderer, no date in the file).
    """
    x0, x1, y0, y1 = _bounds(tracks)
    scale = min(8.0 / (x1 - x0), 7.0 / (y1 - y0))  # inches per metre of the axes
    width_in, height_in = max(3.0, (x1 - x0) * scale), max(3.0, (y1 - y0) * scale)
    fig = new_figure(width_in + 4.0, height_in + 1.0)  # resized once the legend is known
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    if tracks.shade is not None and tracks.extent is not None:
        ax.imshow(
            tracks.shade, origin="lower", extent=tracks.extent, cmap="gray", vmin=0.0,
            vmax=1.0, interpolation="nearest", zorder=0,
        )  # fmt: skip
    for i, plan in enumerate(tracks.plans):
        label = f"planned paths ({len(tracks.plans)})" if i == 0 else None
        ax.plot(plan[:, 0], plan[:, 1], color="#9467bd", lw=1.0, alpha=0.5, label=label)
    for label, track in tracks.estimates.items():
        colour, width, style = next(
            ((c, w, s) for prefix, c, w, s in _LINES if label.startswith(prefix)),
            ("#8c564b", 1.2, "-."),
        )
        t = _thin(track)
        ax.plot(t[:, 0], t[:, 1], color=colour, lw=width, ls=style, label=label, zorder=4)
    if len(tracks.truth):  # wide and under the estimates: a good estimate runs inside it
        t = _thin(tracks.truth)
        ax.plot(t[:, 0], t[:, 1], color="#444444", lw=3.2, alpha=0.55, label="ground truth",
                zorder=3)  # fmt: skip
        ax.plot(*t[0], "o", color="#17becf", mec="black", ms=9, label="start", zorder=6)
        ax.plot(*t[-1], "s", color="white", mec="black", ms=8, mew=1.5, label="end", zorder=6)
    _draw_goals(ax, tracks.goals)
    if tracks.map_label:
        ax.plot([], [], "s", color="#777777", ms=8, label=tracks.map_label)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="datalim")  # a long, thin map keeps 3 in of height
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(visible=True, color="#bbbbbb", lw=0.4, alpha=0.6)
    handles, labels = ax.get_legend_handles_labels()
    order = sorted(range(len(labels)), key=lambda i: labels[i] != "ground truth")
    legend = ax.legend([handles[i] for i in order], [labels[i] for i in order],
                       loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
                       borderaxespad=0.0)  # fmt: skip
    legend_in = legend.get_window_extent().width / fig.dpi
    title = textwrap.fill(tracks.title, max(40, int((width_in + legend_in) * 12)))
    ax.set_title(title, fontsize=10, loc="left")
    # fixed margins in inches (no tight_layout: the legend sits outside the axes)
    left, bottom, top = 0.8, 0.6, 0.3 + 0.18 * (title.count("\n") + 1)
    fig_w, fig_h = left + width_in + legend_in + 0.4, bottom + height_in + top
    fig.set_size_inches(fig_w, fig_h)
    ax.set_position((left / fig_w, bottom / fig_h, width_in / fig_w, height_in / fig_h))
    return figure_png(fig)


def _draw_goals(ax: Any, goals: list[GoalMark]) -> None:
    for state, marker, colour, size, text in (
        ((True, True), "*", "#2ca02c", 16, "goal reached"),
        ((False, True), "X", "#d62728", 11, "goal missed"),
        ((False, False), "D", "#ffbf00", 9, "goal not ended (run over)"),
    ):
        xy = [(g.x, g.y) for g in goals if (g.reached, g.ended) == state]
        if xy:
            pts = np.asarray(xy)
            ax.plot(pts[:, 0], pts[:, 1], marker, color=colour, mec="black", mew=0.7,
                    ms=size, ls="none", label=f"{text} ({len(xy)})", zorder=7)  # fmt: skip
    for number, g in enumerate(goals, start=1):
        ax.annotate(str(number), (g.x, g.y), xytext=(6, 6), textcoords="offset points",
                    fontsize=8, fontweight="bold", zorder=8)  # fmt: skip


# ---------------------------------------------------------------------------- the run
def write_trajectory_png(
    out_dir: Path, description: LaunchDescription, summary: Mapping[str, Any]
) -> Path | None:
    """Write ``trajectory.png`` of a finished run into ``out_dir``; never raises.

    Args:
        out_dir: the run's output directory (``map.yaml`` is read from there).
        description: the run's launch description (its ``scenario_observer`` entry names
            the topics; without one the observer's defaults).
        summary: the run's summary (``bag``, ``scenario``, ``seed``, goal counts).

    Returns:
        The file written; None when nothing could be drawn (logged at warning with the
        reason).
    """
    try:
        tracks = read_run_tracks(out_dir, description, summary)
        if tracks is None:
            return None
        path = out_dir / TRAJECTORY_PNG
        tmp = path.with_suffix(".png.tmp")
        tmp.write_bytes(trajectory_png(tracks))
        tmp.replace(path)
    except Exception as exc:  # noqa: BLE001 - a picture never fails the run
        _LOG.warning("no %s in %s: %s: %s", TRAJECTORY_PNG, out_dir, type(exc).__name__, exc)
        return None
    return path


def _observer(description: LaunchDescription) -> tuple[ObserverParams, str]:
    """The observer's parameters as launched (defaults for the ones not set) and namespace."""
    from visnav.scenarios.observer import ObserverParams  # noqa: PLC0415

    spec: NodeSpec | None = next(
        (n for n in description.nodes if n.executable == "scenario_observer"), None
    )
    if spec is None:
        return ObserverParams(), "/"
    names = {f.name for f in dataclasses.fields(ObserverParams)}
    given = {k: v for k, v in spec.params.items() if k in names}
    return dataclasses.replace(ObserverParams(), **given), spec.namespace


_TOPIC_PARAMS = (
    "ground_truth_topic",
    "odom_topic",
    "goal_topic",
    "status_topic",
    "slam_pose_topic",
    "slam_path_topic",
    "map_topic",
)
"""The observer's topic parameters that :mod:`visnav.scenarios.trajectory_bag` reads."""


def _absolute(topic: str, namespace: str) -> str:
    if not topic or topic.startswith("/"):
        return topic
    return namespace.rstrip("/") + "/" + topic


def read_run_tracks(
    out_dir: Path, description: LaunchDescription, summary: Mapping[str, Any]
) -> RunTracks | None:
    """What :func:`trajectory_png` draws for a finished run (None: no ground truth to draw).

    Raises:
        VisnavError: the bag or the map does not read (the caller logs it).
    """
    from visnav.scenarios.trajectory_bag import read_bag_tracks  # noqa: PLC0415

    params, namespace = _observer(description)
    bag = summary.get("bag")
    if not bag or not Path(bag).exists():
        _nothing_to_draw(out_dir, "the run has no bag to read", summary)
        return None
    topics = {key: _absolute(getattr(params, key), namespace) for key in _TOPIC_PARAMS}
    topics["map_topic"] = topics["map_topic"] or "/map"  # e.g. map_server's, not scored
    found = read_bag_tracks(Path(bag), params, topics, saved_map=out_dir / "map.yaml")
    if found is None:
        where = f"the bag has no ground truth on {topics['ground_truth_topic']}"
        _nothing_to_draw(out_dir, where, summary)
        return None
    tracks, goals = found
    if params.scenario == "drone":  # no goal status: the summary's count (else still flying)
        count = int(summary.get("goals_reached") or 0)
        goals = [
            dataclasses.replace(g, reached=i < count, ended=i < count) for i, g in enumerate(goals)
        ]
    tracks.goals = goals
    if tracks.shade is None or params.scenario == "drone":
        _world_shade(tracks, params)
    tracks.title = _title(summary, params)
    return tracks


def _nothing_to_draw(out_dir: Path, reason: str, summary: Mapping[str, Any]) -> None:
    """A warning for a completed run; debug for one stopped early (Ctrl-C at the start)."""
    level = logging.WARNING if summary.get("status", "completed") == "completed" else logging.DEBUG
    _LOG.log(level, "no %s in %s: %s", TRAJECTORY_PNG, out_dir, reason)


def _world_shade(tracks: RunTracks, params: ObserverParams) -> None:
    from visnav.description.world import load_world  # noqa: PLC0415 - heavy

    packages = dict(item.split("=", 1) for item in params.packages if "=" in item)
    world = load_world(params.world, seed=params.seed, packages=packages)
    grid, extent = world_occupancy(world, flight=params.scenario == "drone")
    tracks.shade = np.where(grid, _WORLD_OCCUPIED, _FREE)
    tracks.extent = extent
    what = "trees at flight height" if params.scenario == "drone" else "walls and furniture"
    tracks.map_label = f"world ({what})"


def map_shade(data: npt.NDArray[np.integer[Any]]) -> npt.NDArray[np.float64]:
    """Grey shades of an occupancy grid: free white, unknown light grey, occupied black."""
    d = np.asarray(data, dtype=np.float64)
    return np.where(d < 0, _UNKNOWN, 1.0 - np.clip(d, 0.0, 100.0) / 100.0)


def _title(summary: Mapping[str, Any], params: ObserverParams) -> str:
    name = summary.get("scenario", params.scenario)
    text = f"{name}, seed {summary.get('seed', params.seed)}"
    if summary.get("goals_total") is not None:
        text += f": {summary.get('goals_reached')}/{summary['goals_total']} goals reached"
    if summary.get("collisions") is not None:
        text += f", {summary['collisions']} collisions"
    text += f", {float(summary.get('sim_duration_s') or 0.0):.1f} s simulated"
    status = summary.get("status")
    return text + (f" ({status})" if status and status != "completed" else "")
