"""``visnav run car | drone | FILE``: launch a scenario, record it and summarise it.

A scenario is a YAML launch file (the built-in ones are ``car.launch.yaml`` and
``drone.launch.yaml`` in ``visnav/scenarios/launch``): the ``sim`` node (with
``lockstep: true``), the robot's stack, a mission node that sends the goals and the
observer node (:mod:`visnav.scenarios.observer`) that computes the summary from topics.
:func:`run_scenario` launches it with :class:`~visnav.launch.supervisor.Launcher`: the
shared nodes run lock-step with the simulation in one :class:`~visnav.graph.Context` (so
every in-process message is zero-copy and the run is deterministic for a seed; a node
given ``process: own`` runs in its own process and talks over Zenoh), while a recorder
writes a bag and a counter measures every topic. The run ends after ``duration`` seconds
of sim time or when the observer says the task is done, with ``summary.json`` in the
output directory and a printed table. ``visnav launch car seed:=4 out:=DIR`` runs the
same nodes the same way (without the bag and the topic counts).

``summary.json`` keys scripts can rely on: ``scenario``, ``seed``, ``sim_duration_s``,
``wall_duration_s``, ``real_time_factor``, ``bag`` (path), ``topics`` ({name: {type,
count, rate_hz}}), plus the observer's task keys (``goals_total``, ``goals_reached``,
``collisions``, ``path_length_m``, ``shortest_path_m``, ``path_ratio``,
``goal_times_s``, ``odometry``, ``odometry_drift_m``, ``localization``, ``slam`` for the
car; ``min_clearance_m``, ``mean_speed_mps``, ``planning_time_ms`` for the drone; how
each is measured, ``path_ratio`` and the ``slam`` counts included, is in
:mod:`visnav.scenarios.observer`). The
observer writes its files there too (the car's ``map.yaml`` / ``map.pgm`` and SLAM
``slam_trajectory.tum``, ``ground_truth.tum``). A launch file given as the scenario gets
``launch_file`` (its path) as well.

Where visnav differs from recording everything with ``ros2 bag record -a``: raw camera
images and point clouds are left out of the scenario bag by default (``record_all=True``
/ ``--record-all`` keeps them): at 640x480 they are ~130 MB per simulated second.
``record_images=True`` / ``--record-images`` keeps the camera images only, so that
``visnav view BAG`` shows them beside the 3D view. What the bag leaves out the topic
counter does not subscribe to either (its ``topics`` entry has count and rate None): a
camera renders only while one of its topics has a subscriber, as gazebo_ros_camera does.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import difflib
import importlib.resources
import json
import math
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TextIO

from visnav.bag.recorder import BagRecorder
from visnav.graph.context import Context
from visnav.graph.introspect import (
    new_published_topics,
    subscription_qos_for,
)
from visnav.graph.node import Node
from visnav.launch.description import LaunchDescription
from visnav.launch.loader import load_launch
from visnav.launch.supervisor import Launcher
from visnav.msgs.serde import get_message_class
from visnav.scenarios.errors import ScenarioError
from visnav.sim.guards import SecondSimulationError, refuse_second_simulation

__all__ = [
    "SCENARIOS",
    "ScenarioDef",
    "ScenarioError",
    "TopicCounter",
    "format_summary",
    "launch_file",
    "run_scenario",
]

_BULKY_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/PointCloud2")
_SLICE_S = 0.1  # sim seconds between progress updates, topic polls and child supervision


@dataclasses.dataclass(frozen=True)
class ScenarioDef:
    """A built-in scenario: its launch file, world, robot and default duration."""

    name: str
    world: str
    robot: str
    duration_s: float
    launch: str
    namespace: str = "/"


SCENARIOS: dict[str, ScenarioDef] = {
    "car": ScenarioDef("car", "office", "car", 240.0, "car.launch.yaml"),
    "drone": ScenarioDef(
        "drone", "forest", "quadrotor", 60.0, "drone.launch.yaml", namespace="/drone"
    ),
}


def launch_file(name: str) -> Path:
    """The launch file of built-in scenario ``name`` (shipped in ``visnav/scenarios/launch``).

    Raises:
        ScenarioError: not a built-in scenario (the closest name is suggested).
    """
    sdef = SCENARIOS.get(name)
    if sdef is None:
        close = difflib.get_close_matches(name, list(SCENARIOS), n=2)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        msg = (
            f"unknown scenario {name!r}: expected one of {', '.join(SCENARIOS)} or a YAML "
            f"launch file (path ending in .yaml){hint}"
        )
        raise ScenarioError(msg)
    return Path(str(importlib.resources.files("visnav.scenarios") / "launch" / sdef.launch))


def _is_file(name: str) -> bool:
    return name.endswith((".yaml", ".yml")) or "/" in name


class TopicCounter:
    """Counts messages and measures the sim-time rate of every (visible) topic.

    Subscribes to each topic of the graph as it appears, with a QoS compatible
    with its publishers; callbacks only count (in-process delivery is zero-copy).
    Topics of ``skip_types`` are listed with count None but not subscribed to: the
    simulator renders a camera only while its topics have subscribers.
    """

    def __init__(
        self, ctx: Context, clock_ns: Callable[[], int], *, skip_types: tuple[str, ...] = ()
    ) -> None:
        self._ctx = ctx
        self._skip_types = skip_types
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
            if types[0] in self._skip_types:
                continue  # not subscribed: a camera renders only for subscribers

            def on_msg(_msg: Any, stats: list[int] = stats) -> None:
                now = self._clock_ns()
                if stats[0] == 0:
                    stats[1] = now
                stats[0] += 1
                stats[2] = now

            qos = subscription_qos_for(self._ctx, topic)
            self._node.create_subscription(get_message_class(types[0]), topic, on_msg, qos)

    def summary(self) -> dict[str, dict[str, Any]]:
        """``{topic: {type, count, rate_hz}}`` (rate over sim time; 0 with < 2 messages).

        A topic of ``skip_types`` has ``count`` and ``rate_hz`` None (not counted).
        """
        out: dict[str, dict[str, Any]] = {}
        for topic in sorted(self.types):
            if self.types[topic] in self._skip_types:
                out[topic] = {"type": self.types[topic], "count": None, "rate_hz": None}
                continue
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


def _bool(value: bool) -> str:
    return "true" if value else "false"


def scenario_args(
    description_args: Mapping[str, Any],
    options: Mapping[str, str],
    *,
    where: str,
    required: tuple[str, ...] = ("seed", "out"),
) -> dict[str, str]:
    """The launch arguments of a run: the options the file declares (``required`` must be).

    Raises:
        ScenarioError: the file does not declare a required argument.
    """
    missing = [name for name in required if name not in description_args]
    if missing:
        msg = (
            f"{where}: the launch file declares no arg {', '.join(missing)}: a scenario file "
            "needs `- arg: {name: seed}` and `- arg: {name: out}` (passed to its observer's "
            "output_dir), like visnav/scenarios/launch/car.launch.yaml"
        )
        raise ScenarioError(msg)
    return {k: v for k, v in options.items() if k in description_args}


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
    ideal_sensors: bool = False,
    launch_args: Mapping[str, str] | None = None,
    context: Context | None = None,
    progress: TextIO | None = sys.stderr,
) -> dict[str, Any]:
    """Launch a scenario and return its summary (also written to ``summary.json``).

    Args:
        name: ``car``, ``drone`` or a YAML scenario launch file (it must declare the
            args ``seed`` and ``out``; ``duration``, ``realtime``, ``slam`` and
            ``ideal_sensors`` are passed when it declares them).
        seed: seeds the world, the sensors and the task.
        duration_s: simulated seconds (default: the scenario's, 240 s for the car).
        out: output directory (default ``runs/<UTC timestamp>``); must not hold a bag yet.
        record_all: also record raw images and point clouds.
        record_images: also record the camera images (not the point clouds).
        realtime: pace the simulation to the wall clock.
        view: stream the run to the Rerun viewer (needs ``visnav[viz]``).
        slam: run the car's visual SLAM and score it (``slam`` summary key).
        ideal_sensors: car: ground-truth odometry and noise-free cameras (the robot's
            Xacro ``ideal_sensors:=true``), SLAM beside the navigation; False (default):
            drifting wheel-encoder odometry, the camera / depth noise models and, with
            ``slam``, SLAM in the loop (it publishes ``map -> odom``).
        launch_args: more ``name: value`` launch arguments (``map``, ``goals``, ...).
        context: the graph context of the shared nodes (default: a new one, with the
            Zenoh transport so other processes see the run).
        progress: where the progress bar goes (None: no progress output).

    Returns:
        The summary dictionary.

    Raises:
        ScenarioError: unknown scenario, a negative duration, a launch file without a
            lock-step ``sim`` node, or another simulation publishing ``/clock`` in the same
            graph domain.
        LaunchError: the launch file or an argument is bad.
    """
    is_file = _is_file(name)
    sdef = None if is_file else SCENARIOS.get(name)
    path = Path(name) if is_file else launch_file(name)
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0):
        msg = f"duration is {duration_s!r}: expected a positive number of seconds"
        raise ScenarioError(msg)
    out_dir = _out_dir(out)
    options = {
        "seed": str(int(seed)),
        "out": str(out_dir.absolute()),
        "realtime": _bool(realtime),
        "slam": _bool(slam),
        "ideal_sensors": _bool(ideal_sensors),
    }
    if duration_s is not None:
        options["duration"] = repr(float(duration_s))
    declared = None
    if is_file:  # which of the options the file declares
        first = {"seed": options["seed"], "out": options["out"], **dict(launch_args or {})}
        declared = load_launch(path, first).args
    args = options if declared is None else scenario_args(declared, options, where=str(path))
    if sdef is not None and sdef.name == "drone":
        for key in ("slam", "ideal_sensors"):  # the drone has no SLAM and only ideal sensors
            args.pop(key, None)
    description = load_launch(path, {**args, **dict(launch_args or {})})
    out_dir.mkdir(parents=True, exist_ok=True)
    own_ctx = context is None
    ctx = context if context is not None else Context()
    try:
        _refuse_a_second_simulation(ctx)
        launcher = Launcher(description, domain=ctx.domain, context=ctx)
        try:
            launcher.start()
            label = sdef.name if sdef is not None else path.name
            return _run(
                launcher,
                label,
                seed,
                out_dir,
                record_all,
                record_images,
                view,
                progress,
                launch_file=None if sdef is not None else str(path),
            )
        finally:
            launcher.shutdown()
    finally:
        if own_ctx:
            ctx.shutdown()


def _refuse_a_second_simulation(ctx: Context) -> None:
    """Two simulations in one domain would mix their clocks, TF and commands: refuse."""
    try:
        refuse_second_simulation(ctx, command="visnav run")
    except SecondSimulationError as exc:
        raise ScenarioError(str(exc)) from None


def _driver(launcher: Launcher, description: LaunchDescription) -> Any:
    driver = launcher.lockstep_driver()
    if driver is None:
        msg = (
            f"{description.source}: no shared `sim` node with `lockstep: true`: a scenario "
            "is driven by its simulation; add `lockstep: true` to the sim node's params "
            "(and leave it in the launch process)"
        )
        raise ScenarioError(msg)
    if not driver.duration_s > 0:
        msg = (
            f"{description.source}: the sim node's duration is {driver.duration_s}: a "
            "scenario must end; give the sim node a duration (e.g. `duration: $(arg duration)`)"
        )
        raise ScenarioError(msg)
    return driver


def _run(
    launcher: Launcher,
    label: str,
    seed: int,
    out_dir: Path,
    record_all: bool,
    record_images: bool,
    view: bool,
    progress: TextIO | None,
    *,
    launch_file: str | None,
) -> dict[str, Any]:
    driver = _driver(launcher, launcher.description)
    sim = driver.sim
    ctx = launcher.context
    bag_path = out_dir / "bag"
    record = "all" if record_all else "images" if record_images else ""
    left_out = () if record == "all" else _left_out_types(keep_images=record == "images")
    counter = TopicCounter(ctx, lambda: sim.now_ns, skip_types=left_out)
    exclude = None if record == "all" else _bulky_exclusion(ctx, keep_images=record == "images")
    recorder = BagRecorder(
        ctx, None, bag_path, compression="zstd", exclude=exclude, use_sim_time=True
    )
    recorder.start()
    feed = _ViewFeed(ctx, out_dir, progress or sys.stderr) if view else None
    duration = float(driver.duration_s)
    bar = _Progress(label, duration, progress) if progress is not None else None
    start_sim = sim.sim_time_s
    wall0 = time.perf_counter()
    try:
        while ctx.ok and not launcher.stopping:
            counter.poll()
            if feed is not None:
                feed.poll()
            try:
                more = driver.run_lockstep(_SLICE_S)
            except SystemExit:  # the observer: the task is done
                more = False
            launcher.poll()
            if bar is not None:
                wall = time.perf_counter() - wall0
                done_s = sim.sim_time_s - start_sim
                bar.update(done_s, done_s / max(wall, 1e-9))
            if not more:
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
    topics = counter.summary()
    launcher.shutdown()  # the observer writes summary.json when it ends (if not yet)
    task = _observer_summary(out_dir, launcher.description)
    summary: dict[str, Any] = {
        "scenario": task.pop("scenario", label) if launch_file else label,
        "seed": seed,
        "sim_duration_s": round(sim_s, 6),
        "wall_duration_s": round(wall, 3),
        "real_time_factor": round(sim_s / wall, 4) if wall > 0 else None,
        "bag": str(bag_path),
        "topics": topics,
    }
    if launch_file is not None:
        summary["launch_file"] = launch_file
    for key in ("scenario", "seed", "sim_duration_s"):
        task.pop(key, None)
    summary.update(task)
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def _observer_summary(out_dir: Path, description: LaunchDescription) -> dict[str, Any]:
    """The observer's ``summary.json`` (its task keys); {} without an observer."""
    path = out_dir / "summary.json"
    if not any(n.executable == "scenario_observer" for n in description.nodes):
        return {}
    if not path.is_file():
        msg = (
            f"{description.source}: the scenario_observer wrote no {path}: give it "
            "`output_dir: $(arg out)` (or read its log for the error)"
        )
        raise ScenarioError(msg)
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        msg = f"{path}: the scenario_observer's summary does not read: {exc}; rerun the scenario"
        raise ScenarioError(msg) from exc
    return dict(data) if isinstance(data, dict) else {}


def _left_out_types(*, keep_images: bool) -> tuple[str, ...]:
    return tuple(t for t in _BULKY_TYPES if not (keep_images and t == "sensor_msgs/msg/Image"))


def _bulky_exclusion(ctx: Context, *, keep_images: bool = False) -> str | None:
    left_out = set(_left_out_types(keep_images=keep_images))
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
        if t["count"] is None:  # left out of the bag: not counted
            lines.append(f"{topic:<40} {t['type']:<32} {'-':>7} {'-':>9}")
            continue
        lines.append(f"{topic:<40} {t['type']:<32} {t['count']:>7} {t['rate_hz']:>9.2f}")
    return "\n".join(lines)
