"""``visnav run car | drone``: start a built-in scenario, record it and summarise it.

A scenario is a world, a robot and the pipeline built on them (whatever of it
exists), run in lock-step simulation in one :class:`~visnav.graph.Context` (so
every in-process message is zero-copy and the run is deterministic for a seed),
while a recorder writes a bag and a counter measures every topic. The run ends
after ``duration`` seconds of sim time (or when the scenario's task finishes) with
``summary.json`` in the output directory and a printed table.

``summary.json`` keys scripts can rely on: ``scenario``, ``seed``, ``sim_duration_s``,
``wall_duration_s``, ``real_time_factor``, ``bag`` (path), ``topics`` ({name: {type,
count, rate_hz}}), plus the task keys of the pipeline pieces that ran (``goals_total``,
``goals_reached``, ``collisions``, ``path_length_m``, ``shortest_path_m``,
``min_clearance_m``, ``mean_speed_mps``, ``planning_time_ms``, ``slam``). A task with a
``write_outputs(out_dir)`` method writes its files there too (the car's SLAM:
``slam_trajectory.tum``, ``ground_truth.tum``).

Where visnav differs from recording everything with ``ros2 bag record -a``: raw camera
images and point clouds are left out of the scenario bag by default (``record_all=True``
/ ``--record-all`` keeps them): at 640x480 they are ~130 MB per simulated second.
``record_images=True`` / ``--record-images`` keeps the camera images only, so that
``visnav view BAG`` shows them beside the 3D view.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import difflib
import functools
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol, TextIO

from visnav.bag.recorder import BagRecorder
from visnav.errors import VisnavError
from visnav.graph.context import Context
from visnav.graph.introspect import (
    new_published_topics,
    subscription_qos_for,
)
from visnav.graph.node import Node
from visnav.msgs.serde import get_message_class
from visnav.sim.guards import SecondSimulationError, refuse_second_simulation
from visnav.sim.simulator import RobotSpawn, Simulator
from visnav.sim.world import load_world

__all__ = [
    "SCENARIOS",
    "format_summary",
    "ScenarioError",
    "ScenarioTask",
    "TopicCounter",
    "run_scenario",
]

_BULKY_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/PointCloud2")


class ScenarioError(VisnavError, ValueError):
    """An unknown scenario or bad scenario options."""


class ScenarioTask(Protocol):
    """What a scenario's pipeline offers the runner."""

    def done(self) -> bool:
        """True when the task finished before the duration ran out."""

    def results(self) -> dict[str, Any]:
        """The task's summary keys (``goals_reached``, ``slam``, ...)."""


@dataclasses.dataclass(frozen=True)
class ScenarioDef:
    """A built-in scenario: world, robot and default duration."""

    name: str
    world: str
    robot: str
    duration_s: float
    build: Callable[[Context, Simulator, int, bool], list[ScenarioTask]]
    namespace: str = "/"


def _build_car(
    ctx: Context, sim: Simulator, seed: int, slam: bool, *, encoders: bool = True
) -> list[ScenarioTask]:
    from visnav.scenarios.car import build_car_pipeline  # noqa: PLC0415 - only when run

    return build_car_pipeline(ctx, sim, seed, slam=slam, encoders=encoders)


def _build_drone(ctx: Context, sim: Simulator, seed: int, slam: bool) -> list[ScenarioTask]:
    del slam  # the drone runs no SLAM
    from visnav.scenarios.drone import build_drone_pipeline  # noqa: PLC0415 - only when run

    return build_drone_pipeline(ctx, sim, seed)


SCENARIOS: dict[str, ScenarioDef] = {
    "car": ScenarioDef("car", "office", "car", 240.0, _build_car),
    "drone": ScenarioDef("drone", "forest", "quadrotor", 60.0, _build_drone, namespace="/drone"),
}


class TopicCounter:
    """Counts messages and measures the sim-time rate of every (visible) topic.

    Subscribes to each topic of the graph as it appears, with a QoS compatible
    with its publishers; callbacks only count (in-process delivery is zero-copy).
    """

    def __init__(self, ctx: Context, clock_ns: Callable[[], int]) -> None:
        self._ctx = ctx
        self._node = Node("_visnav_topic_counter", context=ctx)
        self._clock_ns = clock_ns
        self._version = -1
        self.counts: dict[str, list[int]] = {}  # topic -> [count, first_ns, last_ns]
        self.types: dict[str, str] = {}

    def poll(self) -> None:
        """Subscribe to topics that appeared since the last poll."""
        if self._ctx.graph.version == self._version:
            return
        self._version = self._ctx.graph.version
        for found in new_published_topics(self._ctx, self.types):
            topic, types = found.name, found.types
            if len(types) != 1:
                continue
            self.types[topic] = types[0]
            stats = self.counts.setdefault(topic, [0, 0, 0])

            def on_msg(_msg: Any, stats: list[int] = stats) -> None:
                now = self._clock_ns()
                if stats[0] == 0:
                    stats[1] = now
                stats[0] += 1
                stats[2] = now

            qos = subscription_qos_for(self._ctx, topic)
            self._node.create_subscription(get_message_class(types[0]), topic, on_msg, qos)

    def summary(self) -> dict[str, dict[str, Any]]:
        """``{topic: {type, count, rate_hz}}`` (rate over sim time; 0 with < 2 messages)."""
        out: dict[str, dict[str, Any]] = {}
        for topic in sorted(self.types):
            count, first, last = self.counts[topic]
            rate = (count - 1) / ((last - first) / 1e9) if count > 1 and last > first else 0.0
            out[topic] = {"type": self.types[topic], "count": count, "rate_hz": round(rate, 3)}
        return out


class _Progress:
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
        if self.console.is_terminal:
            self._bar.start()

    def update(self, sim_s: float, rtf: float, *, final: bool = False) -> None:
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
            self.console.print(text, markup=False, highlight=False)

    def close(self) -> None:
        """Stop the live bar (idempotent)."""
        self._bar.stop()


def _out_dir(out: str | Path | None) -> Path:
    if out is not None:
        return Path(out)
    stamp = _dt.datetime.now(tz=_dt.timezone.utc).strftime("%Y%m%d-%H%M%S")
    return Path("runs") / stamp


def run_scenario(
    name: str,
    *,
    seed: int = 0,
    duration_s: float | None = None,
    out: str | Path | None = None,
    record_all: bool = False,
    record_images: bool = False,
    realtime: bool = False,
    view: bool = False,
    slam: bool = True,
    ideal_sensors: bool = True,
    context: Context | None = None,
    progress: TextIO | None = sys.stderr,
) -> dict[str, Any]:
    """Run a built-in scenario and return its summary (also written to ``summary.json``).

    Args:
        name: ``car`` or ``drone``.
        seed: seeds the world, the sensors and the task.
        duration_s: simulated seconds (default: the scenario's, 60 s for the car).
        out: output directory (default ``runs/<UTC timestamp>``); must not hold a bag yet.
        record_all: also record raw images and point clouds.
        record_images: also record the camera images (not the point clouds).
        realtime: pace the simulation to the wall clock.
        view: stream the run to the Rerun viewer (needs ``visnav[viz]``).
        slam: run the car's visual SLAM and score it (``slam`` summary key); off makes
            ``visnav run car`` about 2.5x faster.
        ideal_sensors: car: ground-truth odometry and noise-free cameras (the robot's
            Xacro ``ideal_sensors:=true``; the default until SLAM publishes ``map -> odom``:
            with the static ``map -> odom`` the odometry drift goes straight into
            navigation); False: drifting wheel-encoder odometry and the camera / depth
            noise models (summary key ``odometry.source``).
        context: the graph context (default: a new one, with the Zenoh transport so other
            processes see the run).
        progress: where the progress bar goes (None: no progress output).

    Returns:
        The summary dictionary.

    Raises:
        ScenarioError: unknown scenario, a negative duration, or another simulation
            publishing ``/clock`` in the same graph domain.
    """
    sdef = SCENARIOS.get(name)
    if sdef is None:
        close = difflib.get_close_matches(name, list(SCENARIOS), n=2)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        msg = f"unknown scenario {name!r}: expected one of {', '.join(SCENARIOS)}{hint}"
        raise ScenarioError(msg)
    duration = sdef.duration_s if duration_s is None else float(duration_s)
    if not (math.isfinite(duration) and duration > 0):
        msg = f"duration is {duration_s!r}: expected a positive number of seconds"
        raise ScenarioError(msg)
    out_dir = _out_dir(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    bag_path = out_dir / "bag"
    own_ctx = context is None
    ctx = context if context is not None else Context()
    try:
        _refuse_a_second_simulation(ctx)
        world = load_world(sdef.world, seed=seed)
        robot_args = {"ideal_sensors": "true"} if ideal_sensors and sdef.robot == "car" else {}
        if sdef.build is _build_car and ideal_sensors:
            sdef = dataclasses.replace(sdef, build=functools.partial(_build_car, encoders=False))
        spawn = RobotSpawn(source=sdef.robot, args=robot_args, namespace=sdef.namespace)
        sim = Simulator(world, [spawn], context=ctx, seed=seed, realtime=realtime)
        try:
            return _run(
                sdef,
                ctx,
                sim,
                seed,
                duration,
                out_dir,
                bag_path,
                "all" if record_all else "images" if record_images else "",
                view,
                slam,
                progress,
            )
        finally:
            sim.close()
    finally:
        if own_ctx:
            ctx.shutdown()


def _refuse_a_second_simulation(ctx: Context) -> None:
    """Two simulations in one domain would mix their clocks, TF and commands: refuse."""
    try:
        refuse_second_simulation(ctx, command="visnav run")
    except SecondSimulationError as exc:
        raise ScenarioError(str(exc)) from None


def _run(
    sdef: ScenarioDef,
    ctx: Context,
    sim: Simulator,
    seed: int,
    duration: float,
    out_dir: Path,
    bag_path: Path,
    record: str,
    view: bool,
    slam: bool,
    progress: TextIO | None,
) -> dict[str, Any]:
    tasks = sdef.build(ctx, sim, seed, slam)
    counter = TopicCounter(ctx, lambda: sim.now_ns)
    exclude = None if record == "all" else _bulky_exclusion(ctx, keep_images=record == "images")
    recorder = BagRecorder(
        ctx, None, bag_path, compression="zstd", exclude=exclude, use_sim_time=True
    )
    recorder.start()
    feed = _ViewFeed(ctx, out_dir, progress or sys.stderr) if view else None
    bar = _Progress(sdef.name, duration, progress) if progress is not None else None
    start_sim = sim.sim_time_s
    wall0 = time.perf_counter()
    step_s = 0.1
    try:
        while sim.sim_time_s - start_sim < duration - 1e-9 and ctx.ok:
            counter.poll()
            if feed is not None:
                feed.poll()
            chunk = min(step_s, duration - (sim.sim_time_s - start_sim))
            sim.run(chunk, until=lambda: bool(tasks) and all(t.done() for t in tasks))
            if bar is not None:
                wall = time.perf_counter() - wall0
                bar.update(
                    sim.sim_time_s - start_sim, (sim.sim_time_s - start_sim) / max(wall, 1e-9)
                )
            if tasks and all(t.done() for t in tasks):
                break
    except BaseException:
        if bar is not None:
            bar.close()
        raise
    finally:
        recorder.stop()
        if feed is not None:
            feed.close()
    wall = time.perf_counter() - wall0
    sim_s = sim.sim_time_s - start_sim
    if bar is not None:
        bar.update(sim_s, sim_s / max(wall, 1e-9), final=True)
    summary: dict[str, Any] = {
        "scenario": sdef.name,
        "seed": seed,
        "sim_duration_s": round(sim_s, 6),
        "wall_duration_s": round(wall, 3),
        "real_time_factor": round(sim_s / wall, 4) if wall > 0 else None,
        "bag": str(bag_path),
        "topics": counter.summary(),
    }
    for task in tasks:
        summary.update(task.results())
        write_outputs = getattr(task, "write_outputs", None)
        if callable(write_outputs):  # optional: files of the task (SLAM trajectories)
            write_outputs(out_dir)
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def _bulky_exclusion(ctx: Context, *, keep_images: bool = False) -> str | None:
    left_out = set(_BULKY_TYPES) - ({"sensor_msgs/msg/Image"} if keep_images else set())
    bulky = sorted(
        topic for topic, types in ctx.graph.topic_names_and_types() if set(types) & left_out
    )
    if not bulky:
        return r"^$"
    return "^(" + "|".join(t.replace(".", r"\.") for t in bulky) + ")$"


class _ViewFeed:
    """``--view``: stream the run to Rerun's web viewer (127.0.0.1) and save ``run.rrd``."""

    def __init__(self, ctx: Context, out_dir: Path, stream: TextIO) -> None:
        from visnav.viz import LiveFeed, RerunSink, open_viewer  # noqa: PLC0415 - optional extra

        self._viewer = open_viewer(web=True, save=out_dir / "run.rrd")
        self._feed = LiveFeed(RerunSink(self._viewer.recording), ctx)
        stream.write(f"viewer: {self._viewer.url}\n")
        stream.flush()

    def poll(self) -> None:
        self._feed.scan()
        self._feed.sink.poll()

    def close(self) -> None:
        self._feed.close()
        self._viewer.close()


def format_summary(summary: dict[str, Any]) -> str:
    """Return the summary as the table ``visnav run`` prints."""
    lines = [
        f"scenario {summary['scenario']}  seed {summary['seed']}",
        f"sim {summary['sim_duration_s']:.1f} s in {summary['wall_duration_s']:.1f} s wall "
        f"(real-time factor {summary['real_time_factor']})",
        f"bag {summary['bag']}",
    ]
    for key in (
        "goals_total",
        "goals_reached",
        "collisions",
        "path_length_m",
        "shortest_path_m",
        "path_ratio",
        "min_clearance_m",
        "mean_speed_mps",
        "planning_time_ms",
        "slam",
    ):
        if key in summary:
            lines.append(f"{key:<18} {summary[key]}")
    lines.append("")
    lines.append(f"{'topic':<40} {'type':<32} {'count':>7} {'rate Hz':>9}")
    for topic, t in summary["topics"].items():
        lines.append(f"{topic:<40} {t['type']:<32} {t['count']:>7} {t['rate_hz']:>9.2f}")
    return "\n".join(lines)
