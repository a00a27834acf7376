"""``trajectory.png``: the picture of a run (scenarios/trajectory_plot.py)."""

from __future__ import annotations

import logging
import struct
from pathlib import Path

import numpy as np
import pytest

from visnav.graph import Context
from visnav.launch.loader import load_launch
from visnav.scenarios.runner import launch_file, run_scenario
from visnav.scenarios.trajectory_plot import (
    TRAJECTORY_PNG,
    GoalMark,
    RunTracks,
    map_shade,
    trajectory_png,
    write_trajectory_png,
)


def _png_size(png: bytes) -> tuple[int, int]:
    """(width, height) from the PNG's IHDR chunk."""
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert png[12:16] == b"IHDR"
    width, height = struct.unpack(">II", png[16:24])
    return width, height


def _tracks(*, drift: float = 1.1) -> RunTracks:
    t = np.linspace(0.0, 2.0 * np.pi, 600)
    truth = np.c_[3.0 * np.cos(t), 2.0 * np.sin(t)]
    grid = np.full((100, 160), -1, dtype=np.int8)
    grid[20:80, 20:140] = 0
    grid[20, 20:140] = 100
    return RunTracks(
        title="car, seed 3: 1/3 goals reached, 0 collisions, 60.0 s simulated",
        truth=truth,
        estimates={
            "SLAM (slam/path)": truth + 0.03,
            "localisation (amcl)": truth[::5] - 0.05,
            "wheel odometry (/odom)": truth * drift,
        },
        goals=[GoalMark(3.0, 0.0, True), GoalMark(-3.0, 0.0, False), GoalMark(0, 2, False, False)],
        plans=[truth[:150] + 0.2, truth[150:300] + 0.2],
        shade=map_shade(grid),
        extent=(-4.0, 4.0, -2.5, 2.5),
        map_label="saved map (map.yaml)",
    )


def test_the_picture_is_a_png_of_the_map_and_legend_size() -> None:
    png = trajectory_png(_tracks())
    width, height = _png_size(png)
    # 8 in of axes for 8.8 m of x (map + margin) at 100 dpi, plus margins and the legend;
    # the height follows the map's aspect (5.8 m of y)
    assert 1000 <= width <= 1300
    assert 500 <= height <= 750
    assert len(png) > 20_000  # lines, markers, map and text: not an empty canvas


def test_the_same_tracks_draw_the_same_bytes_and_others_differ() -> None:
    first = trajectory_png(_tracks())
    assert trajectory_png(_tracks()) == first
    assert trajectory_png(_tracks(drift=1.2)) != first


def test_a_long_thin_map_and_no_map_still_draw() -> None:
    x = np.linspace(0.0, 40.0, 50)
    corridor = RunTracks(title="a corridor", truth=np.c_[x, 0.1 * np.sin(x)])
    width, height = _png_size(trajectory_png(corridor))
    assert height >= 300  # at least 3 in of axes, the limits widened to keep metres square
    assert width > height
    lone = RunTracks(title="no motion", truth=np.zeros((1, 2)))
    assert _png_size(trajectory_png(lone))[0] > 0


def test_map_shades_free_white_unknown_grey_occupied_black() -> None:
    shade = map_shade(np.array([[0, -1, 100, 50]], dtype=np.int8))
    assert shade.tolist() == [[1.0, 0.82, 0.0, 0.5]]


def test_a_run_without_a_bag_logs_a_warning_and_does_not_raise(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    description = load_launch(launch_file("car"), {"seed": "0", "out": str(tmp_path)})
    summary = {"scenario": "car", "seed": 0, "bag": str(tmp_path / "bag")}
    with caplog.at_level(logging.WARNING, logger="visnav.scenarios"):
        assert write_trajectory_png(tmp_path, description, summary) is None
    assert "trajectory.png" in caplog.text
    assert "no bag" in caplog.text
    assert not (tmp_path / TRAJECTORY_PNG).exists()


def test_a_bag_that_does_not_read_is_a_warning_too(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap").write_bytes(b"not an mcap file")
    description = load_launch(launch_file("car"), {"seed": "0", "out": str(tmp_path)})
    with caplog.at_level(logging.WARNING, logger="visnav.scenarios"):
        assert write_trajectory_png(tmp_path, description, {"bag": str(bag)}) is None
    assert "no trajectory.png" in caplog.text


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_15_s_car_run_writes_trajectory_png(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """``visnav run car --duration 15`` (its library call): the picture, without a warning."""
    with caplog.at_level(logging.WARNING), Context(transport="local") as ctx:
        run_scenario("car", duration_s=15.0, out=tmp_path / "run", context=ctx, progress=None)
    assert "trajectory.png" not in caplog.text  # no "no trajectory.png in ..." warning
    png = (tmp_path / "run" / TRAJECTORY_PNG).read_bytes()
    width, height = _png_size(png)
    assert width > 600
    assert height > 400
    assert len(png) > 30_000  # the saved map, the tracks and the legend
