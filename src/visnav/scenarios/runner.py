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
/ ``--record-all`` keeps them, as published): at 640x480 they are ~130 MB per simulated
second. The simulator's ``/gazebo/model_states`` and ``/gazebo/link_states`` (every body's
state at every physics step, 500-1000 Hz) are left out too: they were over half of a car
bag's bytes before compression and ~10 % of a TurtleBot3 run's CPU (the simulator
publishes them only while subscribed, as gazebo_ros_api_plugin does), and the run's
ground truth is already in ``ground_truth.tum`` and the robot's ground-truth odometry.
``record_images=True`` / ``--record-images`` keeps the camera images only, so that
``visnav view BAG`` shows them beside the 3D view, stored as image_transport's compressed
transports publish them (``<image topic>/compressed`` JPEG, depth as
``<image topic>/compressedDepth`` PNG; :mod:`visnav.bag.image_compression`): the car's bag
is ~6x smaller (5.7 vs 34 MB per simulated second; ~9x with ideal sensors, whose depth has
no noise to store); ``raw_images=True`` / ``--raw-images`` stores them raw instead.
``summary.json`` gives the bag's size (``bag_bytes``, ``bag_mb_per_sim_s``) and how images
were stored (``bag_images``: ``compressed``, ``raw`` or ``none``). What the bag leaves out the topic
counter does not subscribe to either (its ``topics`` entry has count and rate None): a
camera renders only while one of its topics has a subscriber, as gazebo_ros_camera does.
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib.resources
import json
import logging
import math
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from visnav.bag.image_compression import ImageCompression
from visnav.bag.recorder import BagRecorder
from visnav.graph.context import Context
from visnav.launch.description import LaunchDescription
from visnav.launch.loader import load_launch
from visnav.launch.supervisor import Launcher
from visnav.logsetup import add_log_file, kernel_compilation_notice, remove_log_file
from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.run_control import (
    RunInterrupt,
    default_output_dir,
    remove_refused_output,
)
from visnav.scenarios.run_display import RunProgress, ViewFeed
from visnav.scenarios.topic_counter import TopicCounter
from visnav.sim.guards import SecondSimulationError, refuse_second_simulation

if TYPE_CHECKING:
    from visnav.viz.view_process import ViewPorts

__all__ = [
    "LOG_NAME",
    "SCENARIOS",
    "ScenarioDef",
    "ScenarioError",
    "TopicCounter",
    "format_summary",
    "launch_file",
    "run_scenario",
]

_BULKY_TYPES = (
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/PointCloud2",
    "gazebo_msgs/msg/ModelStates",
    "gazebo_msgs/msg/LinkStates",
)
_SLICE_S = 0.1  # sim seconds between progress updates, topic polls and child supervision
_LOG = logging.getLogger("visnav.scenarios")
LOG_NAME = "run.log"
"""The run's log file in its output directory: every record, DEBUG included."""


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
    "tb3-nav": ScenarioDef(
        "tb3-nav", "turtlebot3_world", "turtlebot3_burger", 400.0, "tb3-nav.launch.yaml"
    ),
    "tb3-slam": ScenarioDef(
        "tb3-slam", "turtlebot3_world", "turtlebot3_burger", 300.0, "tb3-slam.launch.yaml"
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


def _out_dir(out: str | Path | None) -> Path:
    return Path(out) if out is not None else default_output_dir()


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
    raw_images: bool = False,
    image_transport: ImageCompression | None = None,
    realtime: bool = False,
    view: bool | ViewPorts = False,
    slam: bool = True,
    ideal_sensors: bool = False,
    launch_args: Mapping[str, str] | None = None,
    context: Context | None = None,
    progress: TextIO | None = sys.stderr,
    interrupt: RunInterrupt | None = None,
    log_file: bool = True,
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
        record_images: also record the camera images (not the point clouds), compressed
            (``<topic>/compressed``, depth ``<topic>/compressedDepth``).
        raw_images: with ``record_images``, store the images raw instead.
        image_transport: how compressed images are stored (image_transport's plugin
            parameters); None: the plugins' defaults.
        realtime: pace the simulation to the wall clock.
        view: stream the run to the Rerun viewer (needs ``visnav[viz]``), in a process of
            its own; a :class:`~visnav.viz.view_process.ViewPorts` sets its ports.
        slam: run the car's visual SLAM and score it (``slam`` summary key).
        ideal_sensors: car: ground-truth odometry and noise-free cameras (the robot's
            Xacro ``ideal_sensors:=true``), SLAM beside the navigation; False (default):
            drifting wheel-encoder odometry, the camera / depth noise models and, with
            ``slam``, SLAM in the loop (it publishes ``map -> odom``).
        launch_args: more ``name: value`` launch arguments (``map``, ``goals``, ...).
        context: the graph context of the shared nodes (default: a new one, with the
            Zenoh transport so other processes see the run).
        progress: where the progress bar goes (None: no progress output).
        interrupt: the run's Ctrl-C and SIGTERM handler (:class:`RunInterrupt`, installed
            by the caller): once it is requested the run stops at the next step and returns its
            summary with ``status`` ``interrupted``. Without one a KeyboardInterrupt
            still writes that summary, then goes on.
        log_file: write every log record of the run, DEBUG included, to ``run.log`` in
            the output directory (False: the caller keeps its own log there, as a sweep
            worker does).

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
    existed = out_dir.exists()
    out_dir.mkdir(parents=True, exist_ok=True)
    log_handler = add_log_file(out_dir / LOG_NAME) if log_file else None
    own_ctx = context is None
    state = _RunState(
        label=sdef.name if sdef is not None else path.name,
        seed=seed,
        out_dir=out_dir,
        launch_file=None if sdef is not None else str(path),
        interrupt=interrupt,
        raw_images=raw_images,
        image_transport=image_transport or ImageCompression(),
    )
    try:
        with kernel_compilation_notice():
            ctx = context if context is not None else Context()
            try:
                launcher = _start(description, ctx, state)
                if launcher is None:  # refused: nothing ran
                    if log_handler is not None:
                        remove_log_file(log_handler)
                    remove_refused_output(out_dir, existed=existed)
                    assert state.refusal is not None  # _start sets it
                    raise state.refusal
                return _run(launcher, state, record_all, record_images, view, progress)
            finally:
                if own_ctx:
                    ctx.shutdown()
    finally:
        if log_handler is not None:
            remove_log_file(log_handler)


@dataclasses.dataclass
class _RunState:
    """What a run knows about itself while it goes (for the summary, whatever happens)."""

    label: str
    seed: int
    out_dir: Path
    launch_file: str | None
    interrupt: RunInterrupt | None
    raw_images: bool = False
    image_transport: ImageCompression = dataclasses.field(default_factory=ImageCompression)
    bag_images: str = "none"
    status: str = "completed"
    error: str = ""
    sim_s: float = 0.0
    wall0: float = dataclasses.field(default_factory=time.perf_counter)
    topics: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)
    bag: Path | None = None
    refusal: BaseException | None = None
    late_failure: BaseException | None = None
    ran_out: bool = False  # the simulation ended by itself (duration, task done)

    @property
    def interrupted(self) -> bool:
        return self.interrupt is not None and self.interrupt.requested

    @property
    def end_reason(self) -> str:
        """Why an interrupted run ended: the signal (``SIGTERM``, ``SIGINT (Ctrl-C)``)."""
        if self.interrupt is not None and self.interrupt.signum:
            return self.interrupt.reason
        return "KeyboardInterrupt"  # a library caller without a handler, or request()


def _start(description: LaunchDescription, ctx: Context, state: _RunState) -> Launcher | None:
    """Start the launch; None when it was refused (``state.refusal``) before anything ran.

    A Ctrl-C during the start-up stops the start (the run then ends at once, interrupted).
    """
    launcher = Launcher(description, domain=ctx.domain, context=ctx)
    if state.interrupt is not None:
        state.interrupt.attach(launcher)
    try:
        _refuse_a_second_simulation(ctx)
        launcher.start()
        if not state.interrupted:
            _driver(launcher, description)
    except KeyboardInterrupt:  # a second Ctrl-C (or one without a handler) while starting
        state.status = "interrupted"
        launcher.request_stop()
    except Exception as exc:  # noqa: BLE001 - a refusal: raised by the caller
        launcher.shutdown()
        state.refusal = exc
        return None
    return launcher


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
    state: _RunState,
    record_all: bool,
    record_images: bool,
    view: bool | ViewPorts,
    progress: TextIO | None,
) -> dict[str, Any]:
    """Run the started launch to its end, then write and return the summary.

    Ctrl-C (``state.interrupt``, or a KeyboardInterrupt) ends it as ``interrupted``; an
    error after the start as ``failed`` (the summary is written, then the error raised).
    """
    failure: BaseException | None = None
    try:
        if state.status != "interrupted" and not state.interrupted:
            _loop(launcher, state, record_all, record_images, view, progress)
    except KeyboardInterrupt:
        state.status = "interrupted"
    except Exception as exc:  # noqa: BLE001 - written into the summary, then raised
        state.status, state.error, failure = "failed", f"{type(exc).__name__}: {exc}", exc
    if state.interrupted and not state.ran_out:  # a signal in the wrap-up: still completed
        state.status = "interrupted"
    if state.status == "interrupted":
        _LOG.info(
            "interrupted (%s): stopping the nodes and writing the summary "
            "(Ctrl-C again to stop at once)",
            "Ctrl-C" if state.end_reason.startswith("SIGINT") else state.end_reason,
        )
    try:
        launcher.shutdown()  # the observer writes summary.json when it ends (if not yet)
    except KeyboardInterrupt:
        state.status = "interrupted"
    except Exception as exc:  # noqa: BLE001 - the summary is written first
        if failure is None:
            state.status, state.error, failure = "failed", f"{type(exc).__name__}: {exc}", exc
    if state.status == "completed" and launcher.exit_code != 0:
        state.status = "failed"
        state.error = (
            f"the launch ended with exit code {launcher.exit_code} (a required node exited)"
        )
    summary = _write_summary(launcher.description, state)
    failure = failure or state.late_failure
    if failure is not None:
        raise failure
    if state.status == "interrupted" and state.interrupt is None:
        raise KeyboardInterrupt  # a library caller without a handler: the interrupt goes on
    return summary


def _loop(
    launcher: Launcher,
    state: _RunState,
    record_all: bool,
    record_images: bool,
    view: bool | ViewPorts,
    progress: TextIO | None,
) -> None:
    driver = launcher.lockstep_driver()
    sim = driver.sim
    ctx = launcher.context
    bag_path = state.out_dir / "bag"
    record = "all" if record_all else "images" if record_images else ""
    left_out = () if record == "all" else _left_out_types(keep_images=record == "images")
    counter = TopicCounter(ctx, lambda: sim.now_ns, skip_types=left_out)
    exclude = None if record == "all" else _bulky_exclusion(ctx, keep_images=record == "images")
    compressed = record == "images" and not state.raw_images
    state.bag_images = "compressed" if compressed else "raw" if record else "none"
    recorder = BagRecorder(
        ctx,
        None,
        bag_path,
        compression="zstd",
        exclude=exclude,
        use_sim_time=True,
        topic_log_level=logging.DEBUG,
        image_transport=state.image_transport if compressed else None,
    )
    recorder.start()
    state.bag = bag_path
    feed = ViewFeed(ctx, state.out_dir, progress or sys.stderr, view) if view else None
    duration = float(driver.duration_s)
    bar = RunProgress(state.label, duration, progress) if progress is not None else None
    start_sim = sim.sim_time_s
    state.wall0 = time.perf_counter()
    stop: Callable[[], bool] = state.interrupt if state.interrupt is not None else _never
    try:
        while ctx.ok and not launcher.stopping and not stop():
            counter.poll()
            if feed is not None:
                feed.poll()
            try:
                more = driver.run_lockstep(_SLICE_S, until=stop)
            except SystemExit:  # the observer: the task is done
                more = False
            launcher.poll()
            state.sim_s = sim.sim_time_s - start_sim
            if bar is not None:
                wall = time.perf_counter() - state.wall0
                bar.update(state.sim_s, state.sim_s / max(wall, 1e-9))
            if not more:
                state.ran_out = True
                break
    finally:
        state.sim_s = sim.sim_time_s - start_sim
        if bar is not None:
            if stop():
                bar.close()
            else:
                wall = time.perf_counter() - state.wall0
                bar.update(state.sim_s, state.sim_s / max(wall, 1e-9), final=True)
                bar.close()
        state.topics = counter.summary()
        recorder.stop()
        if feed is not None:
            feed.close()


def _never() -> bool:
    return False


def _write_summary(description: LaunchDescription, state: _RunState) -> dict[str, Any]:
    """Merge the run's figures and the observer's, write ``summary.json``, return them."""
    wall = time.perf_counter() - state.wall0
    sim_s = state.sim_s
    try:
        task = _observer_summary(state.out_dir, description)
    except ScenarioError as exc:
        _LOG.debug("no task summary: %s", exc)
        task = {}
        if state.status == "completed":  # the run went well but its observer did not
            state.status, state.error, state.late_failure = "failed", str(exc), exc
    summary: dict[str, Any] = {
        "scenario": task.pop("scenario", state.label) if state.launch_file else state.label,
        "seed": state.seed,
        "status": state.status,
        "sim_duration_s": round(sim_s, 6),
        "wall_duration_s": round(wall, 3),
        "real_time_factor": round(sim_s / wall, 4) if wall > 0 else None,
        "bag": str(state.bag) if state.bag is not None else None,
        **_bag_size(state.bag, sim_s, state.bag_images),
        "topics": state.topics,
    }
    if state.error:
        summary["error"] = state.error
    if state.status == "interrupted":  # as `visnav launch` of a scenario says it
        summary["end_reason"] = state.end_reason
    if state.launch_file is not None:
        summary["launch_file"] = state.launch_file
    for key in ("scenario", "seed", "sim_duration_s", "status"):
        task.pop(key, None)
    summary.update(task)
    tmp = state.out_dir / "summary.json.tmp"
    tmp.write_text(json.dumps(summary, indent=2) + "\n")
    tmp.replace(state.out_dir / "summary.json")
    from visnav.scenarios.trajectory_plot import write_trajectory_png  # noqa: PLC0415 - cycle

    write_trajectory_png(state.out_dir, description, summary)  # logs a failure, never raises
    return summary


def _bag_size(path: Path | None, sim_s: float, images: str) -> dict[str, Any]:
    """``bag_bytes``, ``bag_mb_per_sim_s`` (MB = 1e6 bytes) and ``bag_images`` of a run."""
    if path is None or not path.exists():
        return {"bag_bytes": None, "bag_mb_per_sim_s": None, "bag_images": images}
    files = [path] if path.is_file() else [f for f in path.rglob("*") if f.is_file()]
    size = sum(f.stat().st_size for f in files)
    per_s = round(size / 1e6 / sim_s, 3) if sim_s > 0 else None
    return {"bag_bytes": size, "bag_mb_per_sim_s": per_s, "bag_images": images}


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


def _bag_line(summary: dict[str, Any]) -> str:
    if summary.get("bag_bytes") is None:
        return ""
    text = f"  ({summary['bag_bytes'] / 1e6:.1f} MB"
    if summary.get("bag_mb_per_sim_s") is not None:
        text += f", {summary['bag_mb_per_sim_s']:.2f} MB per simulated second"
    images = summary.get("bag_images")
    return text + (f", images {images})" if images and images != "none" else ")")


def format_summary(summary: dict[str, Any]) -> str:
    """Return the summary as the table ``visnav run`` prints."""
    lines = [
        f"scenario {summary['scenario']}  seed {summary['seed']}",
        f"sim {summary['sim_duration_s']:.1f} s in {summary['wall_duration_s']:.1f} s wall "
        f"(real-time factor {summary['real_time_factor']})",
        f"bag {summary['bag']}" + _bag_line(summary),
    ]
    if summary.get("status", "completed") != "completed":  # interrupted, failed: say so
        lines.insert(
            1,
            f"status {summary['status']}"
            + (f": {summary['error']}" if summary.get("error") else ""),
        )
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
