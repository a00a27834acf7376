"""docs/getting-started.md, walked: each command the page shows is run, its claims checked.

The page's ``bash`` blocks are read from the file, so a command added to the page without a walk
here fails ``test_every_command_of_the_page_is_walked``; the robot of step 7 is the page's own
``xml`` block. Runs use the page's short durations, in a private graph domain, in a temporary
folder (the page's relative ``runs/...`` paths land there).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parents[2] / "docs" / "getting-started.md"

RUN_CAR = "visnav run car --duration 20 --out runs/first"
LOOK = (
    "visnav bag info runs/first/bag",
    "visnav map info runs/first/map.yaml",
    "visnav eval ate runs/first/slam_trajectory.tum runs/first/ground_truth.tum",
    "visnav doctor --bag runs/first/bag",
)
VIEW = "visnav view runs/first/bag --save runs/first/first.rrd"
LAUNCH = "visnav launch car out:=runs/live"
LIVE = (
    "visnav topic list",
    "visnav node list",
    "visnav topic echo /odom --once --field pose.pose.position",
    "visnav topic hz /scan --duration 5",
    "visnav image view /depth_camera/image_raw --snapshot camera.png",
    "visnav doctor",
)
DRONE = "visnav run drone --duration 10 --out runs/drone"
SIM = "visnav sim --world office --robot my_robot.urdf --realtime --duration 60"
DRIVE = (
    "visnav topic hz /scan --duration 5",
    'visnav topic pub -t 20 -r 10 /cmd_vel geometry_msgs/msg/Twist "{linear: {x: 0.3}}"',
    "visnav topic echo /odom --once --field pose.pose.position",
    'visnav topic pub -1 /cmd_vel geometry_msgs/msg/Twist "{}"',
)
NOT_RUN = {"pip install -e .": "the test environment has visnav installed"}


def page() -> str:
    return PAGE.read_text(encoding="utf-8")


def blocks(language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", page(), flags=re.S | re.M)


def page_commands() -> list[str]:
    return [line.strip() for block in blocks("bash") for line in block.splitlines() if line.strip()]


def visnav(command: str, cwd: Path, domain: int, *, timeout: float = 300.0) -> str:
    """Run one page command; return its stdout (stderr goes into the failure message)."""
    argv = shlex.split(command)
    assert argv[0] == "visnav"
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    done = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", *argv[1:]],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    assert done.returncode == 0, f"{command}: exit {done.returncode}\n{done.stderr[-3000:]}"
    return done.stdout


def start(command: str, cwd: Path, domain: int) -> subprocess.Popen[str]:
    argv = shlex.split(command)
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    return subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", *argv[1:]],
        cwd=cwd,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def stop(proc: subprocess.Popen[str]) -> None:
    """Ctrl-C as a terminal sends it (SIGINT to the process group), then make sure."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)


def wait_for_topic(topic: str, cwd: Path, domain: int, proc: subprocess.Popen[str]) -> None:
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            assert proc.stderr is not None
            pytest.fail(f"ended before {topic} appeared: {proc.stderr.read()[-3000:]}")
        if topic in visnav("visnav topic list", cwd, domain).split():
            return
        time.sleep(2)
    pytest.fail(f"{topic} did not appear in 240 s")


def position(text: str) -> tuple[float, float]:
    values = dict(re.findall(r"^(x|y): (\S+)$", text, flags=re.M))
    return float(values["x"]), float(values["y"])


def topic_rows(text: str) -> dict[str, tuple[int, float]]:
    """The summary's topic table: topic -> (count, rate Hz)."""
    rows = re.findall(r"^(/\S+)\s+\S+/msg/\S+\s+(\d+)\s+([\d.]+)$", text, flags=re.M)
    return {topic: (int(count), float(rate)) for topic, count, rate in rows}


@pytest.fixture(scope="module")
def first_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, str]:
    """Step 2, once for the module: the page's short car run."""
    cwd = tmp_path_factory.mktemp("getting_started")
    domain = 90_000_000 + os.getpid() % 1_000_000
    stdout = visnav(RUN_CAR, cwd, domain, timeout=900)
    return cwd, domain, stdout


def test_every_command_of_the_page_is_walked() -> None:
    walked = {RUN_CAR, *LOOK, VIEW, LAUNCH, *LIVE, DRONE, SIM, *DRIVE}
    commands = set(page_commands())
    assert commands - walked == set(NOT_RUN), "commands on the page that no test runs"
    assert walked <= commands, f"walked but no longer on the page: {walked - commands}"
    assert len(blocks("xml")) == 1


@pytest.mark.slow
@pytest.mark.timeout(1200)
@pytest.mark.ci
def test_run_car_prints_and_writes_what_the_page_says(first_run: tuple[Path, int, str]) -> None:
    cwd, _, stdout = first_run
    assert stdout.startswith("scenario car  seed 0\n")
    assert re.search(r"^sim 20\.0 s in [\d.]+ s wall \(real-time factor [\d.]+\)$", stdout, re.M)
    assert re.search(r"^bag runs/first/bag\b", stdout, re.M)
    assert re.search(r"^goals_total +4$", stdout, re.M)
    assert re.search(r"^collisions +0$", stdout, re.M)
    # lock-step and deterministic: the same goals and path as the page shows, at any load
    for key in ("goals_reached", "path_length_m", "shortest_path_m"):
        line = re.search(rf"^{key} .*$", page(), re.M)
        assert line is not None
        assert line.group(0) in stdout.splitlines(), key
    # the topic rows the page shows: same counts (+-1) and rates
    shown = topic_rows(page())
    assert set(shown) == {"/clock", "/odom", "/scan"}
    printed = topic_rows(stdout)
    for topic, (count, rate) in shown.items():
        assert printed[topic][0] == pytest.approx(count, abs=1), topic
        assert printed[topic][1] == pytest.approx(rate, abs=0.5), topic
    # the files of the page's table
    out = cwd / "runs" / "first"
    table = page().split("`runs/first/` now holds:")[1].split("\n\n")[1]
    names = re.findall(r"^\| `([^`]+)`(?:, `([^`]+)`)?", table, flags=re.M)
    files = [name for pair in names for name in pair if name]
    assert len(files) == 10
    for name in files:
        assert (out / name).exists(), name
    assert (out / "bag" / "bag_0.mcap").is_file()
    assert (out / "bag" / "metadata.yaml").is_file()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed"
    for key in ("goals_reached", "collisions", "path_ratio", "real_time_factor", "odometry"):
        assert key in summary
    assert {"rmse_m", "max_m"} <= set(summary["localization"])
    assert {"ate_rmse_m", "keyframes", "loop_closures"} <= set(summary["slam"])
    assert "/scan" in summary["topics"]


@pytest.mark.slow
@pytest.mark.timeout(1200)
@pytest.mark.ci
def test_look_at_what_it_wrote(first_run: tuple[Path, int, str]) -> None:
    cwd, domain, _ = first_run
    bag_info, map_info, ate, doctor = (visnav(c, cwd, domain) for c in LOOK)
    assert re.search(r"Topic: /scan\s+\| Type: sensor_msgs/msg/LaserScan", bag_info)
    assert not re.search(r"Type: sensor_msgs/msg/Image\s", bag_info)  # only with --record-images
    for word in ("resolution:", "origin:", "free:", "occupied:", "unknown:"):
        assert word in map_info
    rmse = float(re.search(r"^\s*rmse\s+(\S+)$", ate, flags=re.M).group(1))  # type: ignore[union-attr]
    assert rmse < 0.02  # "a few millimetres on a short run"
    assert re.search(r"\b0 errors\b", doctor)


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_view_the_bag(first_run: tuple[Path, int, str]) -> None:
    pytest.importorskip("rerun")
    cwd, domain, _ = first_run
    visnav(VIEW, cwd, domain)
    assert (cwd / "runs" / "first" / "first.rrd").stat().st_size > 10_000


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_a_live_graph(tmp_path: Path, domain: int) -> None:
    launch = start(LAUNCH, tmp_path, domain)
    try:
        wait_for_topic("/scan", tmp_path, domain, launch)
        topics, nodes, echo, hz, _, doctor = (visnav(c, tmp_path, domain) for c in LIVE)
        for topic in ("/clock", "/tf", "/odom", "/scan", "/map", "/depth_camera/image_raw"):
            assert topic in topics.split(), topic
        assert "/move_base" in nodes.split()
        position(echo)
        rate = float(re.findall(r"average rate: ([\d.]+)", hz)[-1])
        assert rate == pytest.approx(20.0, abs=1.0)
        assert "in sim time" in hz
        png = tmp_path / "camera.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert re.search(r"\d+ errors?\b", doctor)
    finally:
        stop(launch)
    assert launch.returncode is not None


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_fly_the_drone(tmp_path: Path, domain: int) -> None:
    stdout = visnav(DRONE, tmp_path, domain, timeout=900)
    assert stdout.startswith("scenario drone  seed 0\n")
    for key in ("goals_reached", "collisions", "mean_speed_mps", "min_clearance_m"):
        assert re.search(rf"^{key} ", stdout, re.M), key
    summary = json.loads((tmp_path / "runs" / "drone" / "summary.json").read_text())
    assert summary["collisions"] == 0


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_your_own_robot(tmp_path: Path, domain: int) -> None:
    (tmp_path / "my_robot.urdf").write_text(blocks("xml")[0], encoding="utf-8")
    sim = start(SIM, tmp_path, domain)
    try:
        wait_for_topic("/scan", tmp_path, domain, sim)
        hz, drive, echo, halt = DRIVE
        rate = float(re.findall(r"average rate: ([\d.]+)", visnav(hz, tmp_path, domain))[-1])
        assert rate == pytest.approx(10.0, abs=0.5)
        before = position(visnav(echo, tmp_path, domain))
        visnav(drive, tmp_path, domain)
        after = position(visnav(echo, tmp_path, domain))
        assert abs(after[0] - before[0]) + abs(after[1] - before[1]) > 0.3  # 2 s at 0.3 m/s
        visnav(halt, tmp_path, domain)  # the zero twist stops it
        time.sleep(1.0)
        first = position(visnav(echo, tmp_path, domain))
        time.sleep(1.0)
        second = position(visnav(echo, tmp_path, domain))
        assert abs(second[0] - first[0]) + abs(second[1] - first[1]) < 0.03
        topics = visnav("visnav topic list", tmp_path, domain).split()
        for topic in ("/odom", "/tf", "/joint_states", "/clock"):
            assert topic in topics, topic
    finally:
        stop(sim)
