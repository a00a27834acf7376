"""The sweep report: Wilson intervals, the tables, and every plot rendered in headless Chromium."""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from visnav.bag import BagWriter
from visnav.msgs import make
from visnav.msgs.serde import serialize
from visnav.msgs.types import Odometry
from visnav.scenarios.report import setting_stats, wilson_interval
from visnav.scenarios.report_plots import read_trajectory

CHROMIUM = Path("/usr/bin/chromium")


def test_wilson_interval_reference_values() -> None:
    # reference values of Wilson's score interval (z = 1.96)
    lo, hi = wilson_interval(1, 3)
    assert (lo, hi) == pytest.approx((0.06149, 0.79234), abs=1e-4)
    assert wilson_interval(3, 3)[0] == pytest.approx(0.43850, abs=1e-4)
    assert wilson_interval(3, 3)[1] == 1.0
    assert wilson_interval(0, 10) == pytest.approx((0.0, 0.27753), abs=1e-4)
    assert wilson_interval(0, 0) == (0.0, 1.0)


def _summary(seed: int, **extra: Any) -> dict[str, Any]:
    base = {
        "scenario": "car",
        "seed": seed,
        "sim_duration_s": 100.0,
        "wall_duration_s": 120.0,
        "real_time_factor": 0.8 + 0.01 * seed,
        "bag": "bag",
        "topics": {"/scan": {"type": "sensor_msgs/msg/LaserScan", "count": 10, "rate_hz": 20.0}},
        "goals_total": 4,
        "goals_reached": 4,
        "collisions": 0,
        "path_ratio": 1.05 + 0.02 * seed,
        "planning_time_ms": {"median": 2.0 + seed, "p95": 4.0 + seed, "max": 9.0},
    }
    base.update(extra)
    return base


def _run(setting: str, seed: int, status: str, summary: Any, reason: Any = None) -> dict[str, Any]:
    return {
        "index": seed,
        "scenario": "car",
        "setting": setting,
        "options": {"slam": setting == "slam=true"},
        "seed": seed,
        "domain": 2**30 + seed,
        "key": f"{setting}/{seed}",
        "dir": f"runs/{setting}/{seed}",
        "status": status,
        "reason": reason,
        "wall_s": 1.0,
        "node": "here",
        "summary": summary,
    }


def _sweep_dir(root: Path) -> tuple[Path, dict[str, Any]]:
    slam = {"ate_rmse_m": 0.05, "ate_unaligned_rmse_m": 0.2}
    runs = [
        _run("slam=false", 0, "ok", _summary(0)),
        _run("slam=false", 1, "ok", _summary(1, collisions=1)),
        _run("slam=false", 2, "failed", None, "killed by signal SIGKILL (log x)"),
        *(_run("slam=true", s, "ok", _summary(s, slam=slam)) for s in range(3)),
    ]
    state = {
        "version": 1,
        "sweep_id": 1,
        "scenario": "car",
        "seeds": [0, 1, 2],
        "sets": {"slam": [False, True]},
        "backend": "local",
        "updated": "now",
        "runs": runs,
    }
    (root / "sweep.json").write_text(json.dumps(state))
    with BagWriter(root / "runs/slam=false/0/bag") as w:  # a straight drive, 50 Hz
        t = w.add_topic("/ground_truth/odom", "nav_msgs/msg/Odometry")
        for i in range(100):
            msg = make(Odometry)
            msg.pose.pose.position.x = -6.0 + 0.03 * i
            msg.pose.pose.position.y = -1.0
            w.write(t, i * 20_000_000, serialize(msg))
    return root, state


def test_stats_and_trajectory_from_the_bag(tmp_path: Path) -> None:
    root, state = _sweep_dir(tmp_path)
    stats = setting_stats(state["runs"][:3])
    assert stats["success"] == 1  # the collision run and the failed run do not count
    assert stats["failed"] == 1
    assert stats["interval"] == pytest.approx(wilson_interval(1, 3))
    assert stats["collisions"] == 1
    assert stats["path_ratio_text"] == "1.060 / 1.060 / 1.070"
    track = read_trajectory(root / "runs/slam=false/0/bag", "car")
    assert track is not None
    assert track.shape == (100, 2)
    assert track[-1, 0] == pytest.approx(-6.0 + 0.03 * 99)
    assert read_trajectory(root / "runs/slam=false/2/bag", "car") is None


def _cdp() -> ModuleType:
    path = Path(__file__).parents[1] / "viz" / "_cdp.py"
    spec = importlib.util.spec_from_file_location("viz_cdp", path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_PAGE_FACTS = """
(() => {
  const imgs = Array.from(document.images).map(img => {
    const c = document.createElement('canvas');
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    const g = c.getContext('2d'); g.drawImage(img, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    let ink = 0;
    for (let i = 0; i < d.length; i += 4) { if (d[i] + d[i+1] + d[i+2] < 600) ink++; }
    return {alt: img.alt, w: img.naturalWidth, h: img.naturalHeight,
            shown: img.getBoundingClientRect().width, ink: ink};
  });
  const rows = Array.from(document.querySelectorAll('#settings tr')).map(r => r.innerText);
  const failures = Array.from(document.querySelectorAll('#failures tr')).map(r => r.innerText);
  return JSON.stringify({imgs, rows, failures, ready: document.readyState});
})()
"""


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(300)
@pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian chromium is not installed")
def test_report_renders_tables_and_every_plot_in_chromium(tmp_path: Path) -> None:
    (tmp_path / "sweep").mkdir()
    root, _ = _sweep_dir(tmp_path / "sweep")
    done = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "sweep", "report", str(root)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    report = root / "report.html"
    assert done.stdout.strip() == str(report)
    cdp = _cdp()
    with cdp.headless_chromium(tmp_path / "chromium", log=tmp_path / "chromium.log") as page:
        page.call("Page.navigate", url=report.as_uri())
        facts: dict[str, Any] = {}
        for _ in range(50):
            facts = json.loads(page.evaluate(_PAGE_FACTS))
            if facts["ready"] == "complete" and all(i["w"] > 0 for i in facts["imgs"]):
                break
            time.sleep(0.2)
        page.screenshot(tmp_path / "report.png")
    # width x height of each figure at 100 dpi: 2 settings -> 4.4 x 3.2 in; 3 panels a row
    expected = {
        "success per setting": (440, 320),
        "path ratio (travelled / shortest)": (440, 320),
        "planning time (each run's median)": (440, 320),
        "trajectories slam=false": (900, 320),
        "trajectories slam=true": (900, 320),
    }
    got = {i["alt"]: (i["w"], i["h"]) for i in facts["imgs"]}
    assert got == expected
    for img in facts["imgs"]:
        assert img["shown"] > 0, img
        assert img["ink"] > 0.01 * img["w"] * img["h"], img  # not blank: axes, bars, maps
    rows = facts["rows"]
    assert len(rows) == 3  # header + one row per setting
    lo, hi = wilson_interval(1, 3)
    assert f"33.3 % ({100 * lo:.1f} to {100 * hi:.1f} %)" in rows[1]
    assert "100.0 % (43.9 to 100.0 %)" in rows[2]
    assert "0.0500 / 0.0500" in rows[2]  # SLAM ATE
    assert "killed by signal SIGKILL" in facts["failures"][1]
    assert not math.isnan(np.mean([i["ink"] for i in facts["imgs"]]))


def test_localization_column_uses_the_summarys_localization() -> None:
    """SLAM in the loop and amcl runs report ``localization``; older runs SLAM's ATE."""
    runs = [
        {"status": "ok", "summary": {"localization": {"rmse_m": 0.02, "max_m": 0.09}}},
        {"status": "ok", "summary": {"localization": {"rmse_m": 0.04, "max_m": 0.12}}},
    ]
    assert setting_stats(runs)["loc_text"] == "0.0300 / 0.1200"
    old = [{"status": "ok", "summary": {"slam": {"ate_unaligned_rmse_m": 0.05}}}]
    assert setting_stats(old)["loc_text"] == "0.0500 / 0.0500"
    assert setting_stats([{"status": "failed"}])["loc_text"] == "- / -"
