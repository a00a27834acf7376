"""``visnav sweep FILE``: a scenario launch file swept over seeds and its own args."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from visnav.scenarios.runner import launch_file


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_sweep_of_a_launch_file_runs_it_with_its_args(tmp_path: Path) -> None:
    scenario = tmp_path / "my_car.launch.yaml"
    scenario.write_text(launch_file("car").read_text())
    out = tmp_path / "sweep"
    args = ["--seeds", "2", "--set", "goals=1,2", "--set", "duration=0.3", "--set", "slam=false"]
    args += ["--out", str(out), "--no-report", "--quiet"]
    done = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "sweep", str(scenario), *args],
        capture_output=True,
        text=True,
        timeout=550,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    state = json.loads((out / "sweep.json").read_text())
    assert state["scenario"] == str(scenario.absolute())
    assert [r["setting"] for r in state["runs"]] == [
        "goals=1,duration=0.3,slam=false",
        "goals=2,duration=0.3,slam=false",
    ]
    for run, goals in zip(state["runs"], (1, 2), strict=True):
        assert run["status"] == "ok", run["reason"]
        summary = json.loads((out / run["dir"] / "summary.json").read_text())
        assert summary["launch_file"] == str(scenario.absolute())
        assert summary["scenario"] == "car"  # the observer's kind
        assert summary["seed"] == 2
        assert summary["goals_total"] == goals
        assert summary["sim_duration_s"] == pytest.approx(0.3, abs=0.01)
        assert "slam" not in summary
