"""``DIR/report.html`` of a sweep: per-setting tables and plots, one self-contained static file.

A run *succeeds* when it ended ``ok``, reached every goal and had no collision; the
success rate's 95 % interval is Wilson's score interval (sound at 0 % and 100 % and for
few runs, where the normal approximation is not). Tables per setting: runs, failures,
success rate with its interval, goals reached, collisions, path ratio (travelled /
shortest), planning time (median over runs of each run's median, p95 over runs of each
run's p95, largest max), SLAM ATE (aligned) and localization error (the summary's
``localization``: the map-frame error the navigation sees, SLAM's or amcl's; RMSE mean
over runs and the largest max), real-time factor. Plots (matplotlib PNG embedded
as base64): success per setting, the distributions of path ratio and planning time, and
every run's trajectory over its world's map. A table lists the failed runs with reason.
"""

from __future__ import annotations

import base64
import html
import math
import statistics
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from visnav.scenarios.report_plots import (
    distribution_png,
    read_trajectory,
    success_png,
    trajectories_png,
)
from visnav.scenarios.runner import SCENARIOS

__all__ = ["REPORT_NAME", "setting_stats", "task_ok", "wilson_interval", "write_report"]

REPORT_NAME = "report.html"
_Z95 = 1.959963984540054


def wilson_interval(successes: int, n: int, z: float = _Z95) -> tuple[float, float]:
    """Wilson's score interval of a binomial proportion (``(0, 1)`` for ``n == 0``)."""
    if n <= 0:
        return (0.0, 1.0)
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


def task_ok(run: dict[str, Any]) -> bool:
    """True when the run ended ``ok``, reached all its goals and never collided."""
    s = run.get("summary")
    if run.get("status") != "ok" or not s:
        return False
    goals = s.get("goals_total")
    return bool(goals and s.get("goals_reached") == goals and s.get("collisions", 0) == 0)


def _values(runs: Sequence[dict[str, Any]], *path: str) -> list[float]:
    out = []
    for run in runs:
        value: Any = run.get("summary") or {}
        for key in path:
            value = value.get(key) if isinstance(value, dict) else None
        if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
            out.append(float(value))
    return out


def _fmt(values: list[float], how: str, digits: int = 3) -> str:
    if not values:
        return "-"
    if how == "mean":
        v = statistics.fmean(values)
    elif how == "median":
        v = statistics.median(values)
    elif how == "max":
        v = max(values)
    elif how == "min":
        v = min(values)
    else:
        v = float(np.percentile(values, float(how.lstrip("p"))))
    return f"{v:.{digits}f}"


def setting_stats(runs: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The figures of one setting's runs (the report's table row)."""
    n = len(runs)
    ok = [r for r in runs if r.get("status") == "ok"]
    wins = sum(task_ok(r) for r in runs)
    lo, hi = wilson_interval(wins, n)
    ratio = _values(runs, "path_ratio")
    plan_med = _values(runs, "planning_time_ms", "median")
    plan_p95 = _values(runs, "planning_time_ms", "p95")
    plan_max = _values(runs, "planning_time_ms", "max")
    ate = _values(runs, "slam", "ate_rmse_m")
    # the localization the navigation saw (SLAM in the loop or amcl); older summaries
    # without it: SLAM's unaligned ATE
    loc = [
        v
        for run in runs
        for v in (
            _values([run], "localization", "rmse_m")
            or _values([run], "slam", "ate_unaligned_rmse_m")
        )
    ]
    loc_max = _values(runs, "localization", "max_m") or loc
    rtf = _values(runs, "real_time_factor")
    return {
        "runs": n,
        "failed": n - len(ok),
        "success": wins,
        "success_rate": wins / n if n else 0.0,
        "interval": (lo, hi),
        "goals": f"{sum(_values(ok, 'goals_reached')):.0f}/{sum(_values(ok, 'goals_total')):.0f}",
        "collisions": int(sum(_values(ok, "collisions"))),
        "runs_with_collisions": sum(1 for v in _values(ok, "collisions") if v > 0),
        "path_ratio": ratio,
        "path_ratio_text": " / ".join(_fmt(ratio, how) for how in ("mean", "median", "max")),
        "planning_ms": plan_med,
        "planning_text": " / ".join(
            _fmt(v, how, 2)
            for v, how in ((plan_med, "median"), (plan_p95, "p95"), (plan_max, "max"))
        ),
        "ate_text": f"{_fmt(ate, 'mean', 4)} / {_fmt(ate, 'max', 4)}",
        "loc_text": f"{_fmt(loc, 'mean', 4)} / {_fmt(loc_max, 'max', 4)}",
        "rtf_text": f"{_fmt(rtf, 'mean', 2)} / {_fmt(rtf, 'min', 2)}",
    }


def _img(png: bytes, alt: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return f'<img class="plot" alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


_CSS = """
body{font-family:sans-serif;margin:2em;color:#222} table{border-collapse:collapse;margin:1em 0}
th,td{border:1px solid #bbb;padding:4px 8px;text-align:right} th{background:#eee}
td.l,th.l{text-align:left} .fail{color:#b00}
img.plot{display:block;margin:1em 0;border:1px solid #ddd}
"""

_COLUMNS = (
    ("setting", "setting"),
    ("runs", "runs"),
    ("failed", "failed runs"),
    ("rate", "success rate (95 % CI)"),
    ("goals", "goals reached"),
    ("collisions", "collisions (runs)"),
    ("ratio", "path ratio mean / median / max"),
    ("plan", "planning ms median / p95 / max"),
    ("ate", "SLAM ATE m mean / max"),
    ("loc", "localization m: RMSE mean / largest max"),
    ("rtf", "real-time factor mean / min"),
)


def _table(settings: dict[str, list[dict[str, Any]]], stats: dict[str, dict[str, Any]]) -> str:
    head = "".join(f"<th>{html.escape(t)}</th>" for _, t in _COLUMNS)
    rows = []
    for label in settings:
        s = stats[label]
        lo, hi = s["interval"]
        cells = [
            f'<td class="l">{html.escape(label)}</td>',
            f"<td>{s['runs']}</td>",
            f'<td class="{"fail" if s["failed"] else ""}">{s["failed"]}</td>',
            f"<td>{100 * s['success_rate']:.1f} % ({100 * lo:.1f} to {100 * hi:.1f} %)</td>",
            f"<td>{s['goals']}</td>",
            f"<td>{s['collisions']} ({s['runs_with_collisions']})</td>",
            f"<td>{s['path_ratio_text']}</td>",
            f"<td>{s['planning_text']}</td>",
            f"<td>{s['ate_text']}</td>",
            f"<td>{s['loc_text']}</td>",
            f"<td>{s['rtf_text']}</td>",
        ]
        rows.append("<tr>" + "".join(cells) + "</tr>")
    return f'<table id="settings"><tr>{head}</tr>{"".join(rows)}</table>'


def _failures(runs: Sequence[dict[str, Any]]) -> str:
    bad = [r for r in runs if r.get("status") != "ok"]
    if not bad:
        return "<p>No run failed.</p>"
    rows = "".join(
        f'<tr><td class="l">{html.escape(r["setting"])}</td><td>{r["seed"]}</td>'
        f'<td class="l fail">{html.escape(r["status"])}</td>'
        f'<td class="l">{html.escape(str(r.get("reason") or ""))}</td></tr>'
        for r in bad
    )
    head = '<tr><th class="l">setting</th><th>seed</th><th class="l">status</th>'
    return f'<table id="failures">{head}<th class="l">reason</th></tr>{rows}</table>'


def _kind(scenario: str, runs: list[dict[str, Any]]) -> str | None:
    """``car`` / ``drone``: the scenario, or for a launch file its runs' summary ``scenario``."""
    if scenario in SCENARIOS:
        return scenario
    for run in runs:
        kind = (run.get("summary") or {}).get("scenario")
        if kind in SCENARIOS:
            return str(kind)
    return None


def write_report(sweep_dir: Path, state: dict[str, Any]) -> Path:
    """Write ``DIR/report.html`` for the sweep ``state`` (as in ``sweep.json``); return its path."""
    scenario = state["scenario"]
    settings: dict[str, list[dict[str, Any]]] = {}
    for run in state["runs"]:
        settings.setdefault(run["setting"], []).append(run)
    stats = {label: setting_stats(runs) for label, runs in settings.items()}
    labels = list(settings)
    parts = [
        f"<h1>visnav sweep: {html.escape(scenario)}</h1>",
        f"<p>{len(state['runs'])} runs ({len(labels)} settings x {len(state['seeds'])} seeds), "
        f"backend {html.escape(str(state.get('backend')))}, updated "
        f"{html.escape(str(state.get('updated')))}. A run succeeds when it ended ok, reached "
        "every goal and had no collision.</p>",
        _table(settings, stats),
        "<h2>Success per setting</h2>",
        _img(
            success_png(
                labels,
                [stats[lb]["success_rate"] for lb in labels],
                [stats[lb]["interval"] for lb in labels],
            ),
            "success per setting",
        ),
    ]
    for key, title, unit, note in (
        ("path_ratio", "path ratio (travelled / shortest)", "ratio", "no run reports path_ratio"),
        ("planning_ms", "planning time (each run's median)", "ms", "no run reports planning times"),
    ):
        parts.append(f"<h2>{html.escape(title)}</h2>")
        values = [stats[lb][key] for lb in labels]
        if any(values):
            parts.append(_img(distribution_png(title, unit, labels, values), title))
        else:
            parts.append(f"<p>Not plotted: {note} (scenario {html.escape(scenario)}).</p>")
    parts.append("<h2>Failed runs</h2>")
    parts.append(_failures(state["runs"]))
    kind = _kind(scenario, state["runs"])
    if kind is None:
        parts.append(
            "<p>Trajectories not plotted: the scenario file's observer is not a car or "
            "drone one.</p>"
        )
        settings = {}
    for label, runs in settings.items():
        panels = [
            {
                "seed": r["seed"],
                "status": r["status"],
                "reason": r.get("reason"),
                "ok_task": task_ok(r),
                "track": read_trajectory(sweep_dir / r["dir"] / "bag", str(kind)),
            }
            for r in runs
        ]
        parts.append(f"<h2>Trajectories: {html.escape(label)}</h2>")
        parts.append(
            "<p>Ground truth over the world's map; green: success, orange: goal missed or "
            "collision, red frame: failed run.</p>"
        )
        parts.append(_img(trajectories_png(str(kind), panels), f"trajectories {label}"))
    page = (
        "<!DOCTYPE html><html><head><meta charset='utf-8'>"
        f"<title>visnav sweep {html.escape(scenario)}</title><style>{_CSS}</style></head>"
        f"<body>{''.join(parts)}</body></html>\n"
    )
    path = sweep_dir / REPORT_NAME
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(page)
    tmp.replace(path)
    return path
