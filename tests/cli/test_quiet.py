"""A healthy run's terminal says what it does and nothing else.

``visnav run car`` / ``run drone`` in a fresh process: stderr has no Python warning, no
WARNING or ERROR line, no other library's line (PyOpenGL's "No OpenGL_accelerate",
matplotlib's "generated new fontManager": a fresh ``MPLCONFIGDIR`` makes matplotlib say it),
no per-topic recorder line, and at most :data:`MAX_INFO` INFO lines. Everything else is in
the run's ``run.log``.

Why at most 12 INFO lines: one "started N shared node(s)" line, the kernel compilation
notice of the launch process and of the SLAM worker process (first run only), a "new goal"
and a "goal succeeded" line for each of the car's 4 goals, and the SLAM map's "saved"
line. Anything more is noise a new user has to read past.
"""

from __future__ import annotations

import json
import logging
import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from visnav.description.errors import WorldWarning
from visnav.logsetup import ConsoleFilter, kernel_compilation_notice, route_warnings
from visnav.mapping import Footprint, LayeredCostmap, StaticLayer
from visnav.planning import DWAPlanner, GlobalPlanner, Navigator
from visnav.planning.navigator import STARTUP_GRACE_S

MAX_INFO = 12
_WARNING_RE = re.compile(r"\b\w*Warning\b|^\[(WARNING|ERROR|CRITICAL)\]")
_PROGRESS_RE = re.compile(r"^\[(car|drone)\] sim ")


def _visnav(args: list[str], tmp_path: Path, domain: int, *, timeout: float = 800) -> str:
    env = {
        **os.environ,
        "VISNAV_DOMAIN": str(domain),
        "MPLCONFIGDIR": str(tmp_path / "mpl"),  # fresh: matplotlib would build its font cache
    }
    done = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", *args],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return done.stderr


def _check_quiet(stderr: str) -> list[str]:
    lines = [line for line in stderr.splitlines() if line.strip()]
    noisy = [line for line in lines if _WARNING_RE.search(line)]
    assert not noisy, stderr
    assert "OpenGL_accelerate" not in stderr
    assert "fontManager" not in stderr
    assert "recording '" not in stderr  # the recorder's topic list is in run.log
    assert "Traceback" not in stderr
    other = [line for line in lines if not (line.startswith("[INFO] ") or _PROGRESS_RE.match(line))]
    assert not other, stderr
    info = [line for line in lines if line.startswith("[INFO] ")]
    assert len(info) <= MAX_INFO, stderr
    return info


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(900)
def test_a_short_car_run_is_quiet(tmp_path: Path, domain: int) -> None:
    stderr = _visnav(["run", "car", "--duration", "2", "--out", "run"], tmp_path, domain)
    info = _check_quiet(stderr)
    assert any("started" in line for line in info)
    log = (tmp_path / "run" / "run.log").read_text()
    assert "recording '/clock'" in log  # at debug level, in the log file only
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["status"] == "completed"


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_a_30_s_car_run_is_quiet(tmp_path: Path, domain: int) -> None:
    stderr = _visnav(
        ["run", "car", "--duration", "30", "--out", "run"], tmp_path, domain, timeout=1700
    )
    _check_quiet(stderr)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_short_drone_run_is_quiet(tmp_path: Path, domain: int) -> None:
    stderr = _visnav(["run", "drone", "--duration", "8", "--out", "run"], tmp_path, domain)
    _check_quiet(stderr)


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_a_default_drone_run_is_quiet(tmp_path: Path, domain: int) -> None:
    # `visnav run drone` as the acceptance names it: its default 60 s, every goal's lines
    stderr = _visnav(["run", "drone", "--out", "run"], tmp_path, domain, timeout=1700)
    _check_quiet(stderr)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_launch_car_says_why_it_ended_and_writes_a_summary(tmp_path: Path, domain: int) -> None:
    stderr = _visnav(["launch", "car", "duration:=1.5"], tmp_path, domain)
    _check_quiet(stderr)
    assert "launch ended: duration reached" in stderr
    summaries = list((tmp_path / "runs").glob("*/summary.json"))  # where `visnav run` writes
    assert len(summaries) == 1
    summary = json.loads(summaries[0].read_text())
    assert summary["status"] == "completed"
    assert summary["end_reason"].startswith("duration reached")
    assert f"summary: {summaries[0].absolute()}" in stderr


# ---------------------------------------------------------------------- the parts, fast


def test_the_console_shows_visnav_lines_and_library_warnings_only() -> None:
    keep = ConsoleFilter()

    def record(name: str, level: int) -> logging.LogRecord:
        return logging.LogRecord(name, level, __file__, 1, "text", None, None)

    assert keep.filter(record("visnav.node.mapper", logging.INFO))
    assert keep.filter(record("visnav.launch", logging.INFO))
    assert not keep.filter(record("OpenGL.acceleratesupport", logging.INFO))
    assert not keep.filter(record("matplotlib.font_manager", logging.INFO))
    assert keep.filter(record("matplotlib.font_manager", logging.WARNING))
    assert not keep.filter(record("py.warnings", logging.DEBUG))


def test_library_warnings_go_to_debug_and_visnav_warnings_stay(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        route_warnings()
        with caplog.at_level(logging.DEBUG):
            warnings.warn("'@' is faster on contiguous arrays", RuntimeWarning, stacklevel=1)
            warnings.warn("a dubious world", WorldWarning, stacklevel=1)
    by_logger = {(r.name, r.levelno): r.getMessage() for r in caplog.records}
    assert "contiguous" in by_logger[("py.warnings", logging.DEBUG)]
    assert by_logger[("visnav.warnings", logging.WARNING)] == "WorldWarning: a dubious world"


def test_the_compilation_notice_comes_once_and_only_when_numba_compiles(
    caplog: pytest.LogCaptureFixture,
) -> None:
    numba = pytest.importorskip("numba")

    @numba.njit(cache=False)
    def twice(x: float) -> float:  # pragma: no cover - compiled
        return 2.0 * x

    @numba.njit(cache=False)
    def thrice(x: float) -> float:  # pragma: no cover - compiled
        return 3.0 * x

    with caplog.at_level(logging.INFO), kernel_compilation_notice("compiling kernels"):
        assert twice(2.0) == 4.0
        assert thrice(2.0) == 6.0
        assert twice(3.0) == 6.0  # compiled already: nothing happens
    notices = [r for r in caplog.records if r.name == "visnav.kernels"]
    assert [r.getMessage() for r in notices] == ["compiling kernels"]
    caplog.clear()
    with caplog.at_level(logging.INFO), kernel_compilation_notice("compiling kernels"):
        assert twice(4.0) == 8.0
    assert not [r for r in caplog.records if r.name == "visnav.kernels"]


def _navigator_without_a_map() -> tuple[Navigator, StaticLayer, list[tuple[str, str]]]:
    fp = Footprint.from_params(robot_radius=0.2)
    gc = LayeredCostmap("map", resolution=0.05, track_unknown_space=True, footprint=fp)
    static = StaticLayer()
    gc.add_layer(static)
    lc = LayeredCostmap("odom", width=2.0, height=2.0, resolution=0.05, rolling_window=True)
    log: list[tuple[str, str]] = []
    nav = Navigator(gc, lc, GlobalPlanner(), DWAPlanner(), log=lambda lvl, t: log.append((lvl, t)))
    return nav, static, log


def test_no_map_at_start_up_is_debug_until_the_grace_period_ends() -> None:
    nav, _, log = _navigator_without_a_map()
    nav.go_to((1.0, 1.0, 0.0))
    s = 1_000_000_000
    for t in range(int(STARTUP_GRACE_S) - 1):
        nav.step(t * s, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0))
    stops = [(lvl, t) for lvl, t in log if "not current" in t]
    assert stops
    assert {lvl for lvl, _ in stops} == {"debug"}
    for t in range(int(STARTUP_GRACE_S) - 1, int(STARTUP_GRACE_S) + 3):
        nav.step(t * s, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0))
    warned = [t for lvl, t in log if lvl == "warning" and "not current" in t]
    assert len(warned) == 1  # it persisted: one warning, not one per cycle
    assert warned[0].endswith("since start-up")


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_node_in_its_own_process_is_quiet_too(tmp_path: Path, domain: int) -> None:
    source = Path(__file__).parents[2] / "src/visnav/scenarios/launch/car.launch.yaml"
    text = source.read_text()
    entry = "            exec: mapper\n            name: mapper\n"
    assert entry in text
    own = tmp_path / "car_own_mapper.launch.yaml"
    own.write_text(text.replace(entry, entry + "            process: own\n", 1))
    stderr = _visnav(["launch", str(own), "duration:=2"], tmp_path, domain)
    info = _check_quiet(stderr)
    assert any("started /mapper" in line for line in info)  # the child really ran
