"""Is a sweep run the same run as ``visnav run``? Summaries and trajectories, compared.

Two runs of a scenario with the same seed and options are the same run when their
summaries agree on every key but the wall-clock ones (``wall_duration_s``,
``real_time_factor``, and the bag's size, whose chunks are flushed on a wall-clock period)
and the output path (``bag``), and the ground-truth odometry in
their bags is byte-identical (the serialized messages, so the trajectories are
bit-identical).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from visnav.scenarios.report_plots import TRAJECTORY_TOPICS

__all__ = ["WALL_KEYS", "run_differences", "summary_differences", "trajectory_digest"]

WALL_KEYS = ("wall_duration_s", "real_time_factor", "bag", "bag_bytes", "bag_mb_per_sim_s")
"""Summary keys that depend on the machine or the output path, not on the run."""


def _without_cpu(value: Any) -> Any:
    """A summary value without its CPU-time entries (``slam.cpu_s``: the machine's, too)."""
    if isinstance(value, dict):
        return {k: v for k, v in value.items() if not str(k).startswith("cpu_s")}
    return value


def summary_differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """The summary keys (but :data:`WALL_KEYS`) whose values differ, as ``key: a != b``."""
    out = []
    for key in sorted(set(a) | set(b)):
        if key in WALL_KEYS:
            continue
        if _without_cpu(a.get(key)) != _without_cpu(b.get(key)):
            out.append(f"{key}: {str(a.get(key))[:60]} != {str(b.get(key))[:60]}")
    return out


def trajectory_digest(bag: Path, scenario: str) -> tuple[int, str]:
    """``(messages, sha256)`` of the serialized ground-truth odometry in ``bag``."""
    from visnav.bag import BagReader  # noqa: PLC0415

    digest = hashlib.sha256()
    count = 0
    with BagReader(bag) as reader:
        for raw in reader.raw_messages([TRAJECTORY_TOPICS[scenario]]):
            digest.update(raw.t_ns.to_bytes(8, "little", signed=True))
            digest.update(bytes(raw.data))
            count += 1
    return count, digest.hexdigest()


def run_differences(run_a: Path, run_b: Path) -> list[str]:
    """Everything that differs between two run directories (empty: the same run)."""
    a = json.loads((run_a / "summary.json").read_text())
    b = json.loads((run_b / "summary.json").read_text())
    out = summary_differences(a, b)
    ta = trajectory_digest(run_a / "bag", a["scenario"])
    tb = trajectory_digest(run_b / "bag", b["scenario"])
    if ta != tb:
        out.append(f"trajectory: {ta[0]} msgs {ta[1][:12]} != {tb[0]} msgs {tb[1][:12]}")
    return out
