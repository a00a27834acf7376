"""``sweep.csv``: the run, its settings and its results first, the per-topic counts last."""

from __future__ import annotations

import csv
from pathlib import Path

from visnav.scenarios.sweep import write_csv

# Shaped as visnav run writes summary.json: the bag and the topic counts come before the
# observer's results.
SUMMARY = {
    "scenario": "car",
    "seed": 3,
    "sim_duration_s": 30.0,
    "wall_duration_s": 41.5,
    "real_time_factor": 0.72,
    "bag": "runs/x/3/bag",
    "topics": {
        "/scan": {"type": "sensor_msgs/msg/LaserScan", "count": 600, "rate_hz": 20.0},
        "/odom": {"type": "nav_msgs/msg/Odometry", "count": 1500, "rate_hz": 50.0},
    },
    "launch_file": "my_car.launch.yaml",
    "goals_total": 4,
    "goals_reached": 4,
    "path_ratio": 1.04,
    "goal_times_s": [10.5, 12.0],
    "slam": {"ate_rmse_m": 0.013, "frames": 300, "tracked": 298},
}


def test_result_columns_come_before_the_topic_columns(tmp_path: Path) -> None:
    run = {
        "key": "slam=true/3",
        "dir": "runs/slam=true/3",
        "status": "ok",
        "reason": None,
        "setting": "slam=true",
        "seed": 3,
        "wall_s": 42.0,
        "node": None,
        "options": {"slam": True},
        "summary": SUMMARY,
    }
    failed = {**run, "seed": 4, "status": "failed", "reason": "exit code 1", "summary": None}
    path = write_csv(tmp_path, {"runs": [run, failed]})
    with path.open(newline="") as f:
        header = next(csv.reader(f))
        f.seek(0)
        rows = list(csv.DictReader(f))
    assert header == [
        "setting", "seed", "status", "reason", "wall_s", "node", "dir",
        "set.slam",
        "scenario", "sim_duration_s", "wall_duration_s", "real_time_factor",
        "goals_total", "goals_reached", "path_ratio", "goal_times_s",
        "slam.ate_rmse_m", "slam.frames", "slam.tracked",
        "bag",
        "topics./scan.type", "topics./scan.count", "topics./scan.rate_hz",
        "topics./odom.type", "topics./odom.count", "topics./odom.rate_hz",
        "launch_file",
    ]  # fmt: skip
    assert rows[0]["path_ratio"] == "1.04"
    assert rows[0]["goal_times_s"] == "[10.5, 12.0]"
    assert rows[1]["status"] == "failed"
    assert rows[1]["path_ratio"] == ""
