"""``visnav sweep``: a scenario over seeds x settings, on this machine or a Ray cluster.

The sweep directory ``DIR`` holds ``sweep.json`` (the sweep's definition and every run's
status, reason and summary; rewritten atomically after each run, so it is consistent
whenever the sweep stops), ``sweep.csv`` (one row per run, every summary field
flattened), ``report.html`` and ``runs/<setting>/<seed>/`` with what ``visnav run``
writes for that run (``summary.json``, ``bag/``, the task files) plus ``run.json`` and
``run.log``. A run's status is ``ok``, ``failed`` (with the reason: exit code and last log
line, the signal that killed it, or the timeout), ``pending`` or ``interrupted`` (Ctrl-C;
its partial directory is removed). ``resume=True`` runs what is not ``ok``.
"""

from __future__ import annotations

import contextlib
import csv
import datetime as _dt
import json
import secrets
import shutil
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Protocol, TextIO

from visnav.scenarios.sweep_spec import RunSpec, SweepError, check_run_inputs, expand_runs
from visnav.scenarios.sweep_worker import RunResult

__all__ = [
    "STATE_NAME",
    "SweepBackend",
    "flatten",
    "load_state",
    "run_sweep",
    "write_csv",
]

STATE_NAME = "sweep.json"
CSV_NAME = "sweep.csv"
_VERSION = 1


class SweepBackend(Protocol):
    """Where runs run: :class:`~visnav.scenarios.sweep_local.LocalBackend` or the Ray one."""

    name: str

    def run(self, specs: Sequence[RunSpec], sweep_dir: Path) -> Iterator[RunResult]:
        """Run the specs; yield each result as it finishes."""


def _now() -> str:
    return _dt.datetime.now(tz=_dt.timezone.utc).isoformat(timespec="seconds")


def load_state(sweep_dir: Path) -> dict[str, Any]:
    """Read ``DIR/sweep.json``.

    Raises:
        SweepError: missing or unreadable file.
    """
    path = sweep_dir / STATE_NAME
    try:
        state: dict[str, Any] = json.loads(path.read_text())
    except FileNotFoundError:
        msg = f"{path} does not exist: {sweep_dir} holds no sweep (run visnav sweep --out there)"
        raise SweepError(msg) from None
    except (OSError, ValueError) as exc:
        msg = f"{path}: unreadable sweep state ({exc}); rerun the sweep into a new --out"
        raise SweepError(msg) from None
    if not _well_formed(state):
        msg = f"{path}: not a visnav sweep file of version {_VERSION}; rerun into a new --out"
        raise SweepError(msg)
    return state


_RUN_KEYS = {"key": str, "dir": str, "status": str, "setting": str, "seed": int, "options": dict}


def _well_formed(state: Any) -> bool:
    if not isinstance(state, dict) or state.get("version") != _VERSION:
        return False
    kinds = {"scenario": str, "seeds": list, "sets": dict, "runs": list, "sweep_id": int}
    if not all(isinstance(state.get(k), t) for k, t in kinds.items()):
        return False
    return all(
        isinstance(run, dict) and all(isinstance(run.get(k), t) for k, t in _RUN_KEYS.items())
        for run in state["runs"]
    )


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    tmp.replace(path)


def flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    """Flatten nested dicts to ``a.b.c`` keys; lists become JSON text."""
    out: dict[str, Any] = {}
    if isinstance(value, dict):
        for k, v in value.items():
            out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(value, list):
        out[prefix] = json.dumps(value)
    else:
        out[prefix] = value
    return out


def _column_group(name: str) -> int:
    """Where a summary column goes: the settings, then the results, the topics last."""
    if name.startswith("set."):
        return 0
    return 2 if name.startswith(("topics.", "bag", "launch_file")) else 1


def write_csv(sweep_dir: Path, state: dict[str, Any]) -> Path:
    """Write ``DIR/sweep.csv``: one row per run, every summary field flattened.

    Columns: the run's (``setting``, ``seed``, ``status``, ``reason``, ``wall_s``,
    ``node``, ``dir``), its settings (``set.*``), the results in summary order (goals,
    collisions, path, localization, SLAM, ...) and last the bag path and the per-topic
    counts (``topics.<name>.type|count|rate_hz``, some 60 columns for the car).
    """
    base = ["setting", "seed", "status", "reason", "wall_s", "node", "dir"]
    rows: list[dict[str, Any]] = []
    extra: dict[str, None] = {}
    for run in state["runs"]:
        row = {k: run.get(k) for k in base}
        row.update({f"set.{k}": v for k, v in run["options"].items()})
        # a summary value that differs from the run's own column of that name (the
        # summary's `status` beside the sweep's) goes to summary.<key>
        for key, value in flatten(run.get("summary") or {}).items():
            if key not in base:
                row[key] = value
            elif row[key] != value:
                row[f"summary.{key}"] = value
        extra.update(dict.fromkeys(k for k in row if k not in base))
        rows.append(row)
    path = sweep_dir / CSV_NAME
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="") as f:
        columns = base + sorted(extra, key=_column_group)  # stable: summary order within
        writer = csv.DictWriter(f, fieldnames=columns, restval="")
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(path)
    return path


def _new_state(
    scenario: str, seeds: list[int], sets: dict[str, list[Any]], backend: str
) -> dict[str, Any]:
    sweep_id = secrets.randbits(30)  # only names graph domains; results do not depend on it
    runs = expand_runs(scenario, seeds, sets, sweep_id=sweep_id)
    return {
        "version": _VERSION,
        "sweep_id": sweep_id,
        "scenario": scenario,
        "seeds": seeds,
        "sets": sets,
        "backend": backend,
        "created": _now(),
        "updated": _now(),
        "runs": [
            {
                **spec.to_json(),
                "key": spec.key,
                "dir": spec.rel_dir,
                "status": "pending",
                "reason": None,
                "wall_s": None,
                "node": None,
                "summary": None,
            }
            for spec in runs
        ],
    }


def _open_state(
    sweep_dir: Path,
    scenario: str,
    seeds: list[int] | None,
    sets: dict[str, list[Any]] | None,
    *,
    resume: bool,
    backend: str,
) -> dict[str, Any]:
    exists = (sweep_dir / STATE_NAME).exists()
    if not resume:
        if exists:
            msg = (
                f"{sweep_dir / STATE_NAME} exists: {sweep_dir} already holds a sweep; pass "
                "--resume to finish it, or choose another --out"
            )
            raise SweepError(msg)
        if seeds is None:
            msg = "--seeds is missing: give the seeds to run, for example --seeds 0-9"
            raise SweepError(msg)
        return _new_state(scenario, seeds, sets or {}, backend)
    if not exists:
        if seeds is None:
            msg = f"--resume: {sweep_dir} holds no sweep yet; give --seeds to start one"
            raise SweepError(msg)
        return _new_state(scenario, seeds, sets or {}, backend)
    state = load_state(sweep_dir)
    for name, given, stored in (
        ("scenario", scenario, state["scenario"]),
        ("--seeds", seeds, state["seeds"]),
        ("--set", sets, state["sets"]),
    ):
        if given is not None and given != stored:
            msg = (
                f"--resume: {sweep_dir} holds a sweep with {name} {stored!r}, not {given!r}; "
                "resume with the same arguments (or none), or choose another --out"
            )
            raise SweepError(msg)
    return state


def _todo(sweep_dir: Path, state: dict[str, Any]) -> list[dict[str, Any]]:
    out = []
    for run in state["runs"]:
        done = run["status"] == "ok" and (sweep_dir / run["dir"] / "summary.json").is_file()
        if not done:
            out.append(run)
    return out


class _Bar:
    """The live progress bar (rich) on ``stream``; plain lines when it is not a terminal."""

    def __init__(self, total: int, done: int, stream: TextIO | None) -> None:
        self._progress: Any = None
        self._task: Any = None
        self._stream = stream
        self.ok = self.failed = 0
        if stream is None:
            return
        from rich.console import Console  # noqa: PLC0415 - only for the CLI
        from rich.progress import (  # noqa: PLC0415
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self._progress = Progress(
            TextColumn("sweep"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[counts]}"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            console=Console(file=stream),
        )
        self._task = self._progress.add_task("sweep", total=total, completed=done, counts="")
        self._progress.start()

    def advance(self, line: str, *, ok: bool) -> None:
        if ok:
            self.ok += 1
        else:
            self.failed += 1
        if self._progress is None:
            return
        counts = f"ok {self.ok} failed {self.failed}"
        self._progress.console.print(line, markup=False, highlight=False)
        self._progress.update(self._task, advance=1, counts=counts)

    def stop(self) -> None:
        if self._progress is not None:
            self._progress.stop()


def _line(run: dict[str, Any], result: RunResult) -> str:
    head = f"{run['setting']} seed {run['seed']}:"
    if result.status != "ok" or result.summary is None:
        return f"{head} FAILED {result.reason}"
    s = result.summary
    goals = f"{s.get('goals_reached')}/{s.get('goals_total')} goals" if "goals_total" in s else ""
    return (
        f"{head} ok {goals}, {s.get('collisions', 0)} collisions, sim "
        f"{s.get('sim_duration_s', 0):.0f} s in {result.wall_s:.0f} s"
    )


def run_sweep(
    scenario: str,
    *,
    out: str | Path,
    backend: SweepBackend,
    seeds: list[int] | None = None,
    sets: dict[str, list[Any]] | None = None,
    resume: bool = False,
    progress: TextIO | None = sys.stderr,
    report: bool = True,
) -> dict[str, Any]:
    """Run a sweep (or the rest of one) and write its outputs; return the sweep state.

    Args:
        scenario: a built-in scenario (``car``, ``drone``) or a scenario launch file.
        out: the sweep directory.
        backend: where the runs run.
        seeds: the seeds (None with ``resume``: the stored ones).
        sets: ``{option: [values]}`` from :func:`~visnav.scenarios.sweep_spec.parse_sets`.
        resume: finish the sweep in ``out``: rerun what is not ``ok``.
        progress: where the progress bar goes (None: quiet).
        report: write ``report.html`` at the end.

    Returns:
        The state written to ``sweep.json``.

    Raises:
        SweepError: bad arguments, sweep directory or input file (a ``map`` of a run
            that is to run), before anything runs.
        KeyboardInterrupt: after Ctrl-C, once the directory is consistent.
    """
    sweep_dir = Path(out).absolute()
    state = _open_state(sweep_dir, scenario, seeds, sets, resume=resume, backend=backend.name)
    todo = _todo(sweep_dir, state)
    specs = [RunSpec.from_json(run) for run in todo]
    check_run_inputs(specs)  # a missing map: one line, before anything runs or is written
    sweep_dir.mkdir(parents=True, exist_ok=True)
    by_key = {run["key"]: run for run in state["runs"]}
    for run in todo:
        run.update(status="pending", reason=None, summary=None, wall_s=None, node=None)
    _save(sweep_dir, state)
    bar = _Bar(len(state["runs"]), len(state["runs"]) - len(todo), progress)
    finished: set[str] = set()
    results = backend.run(specs, sweep_dir)
    try:
        for result in results:
            run = by_key[result.key]
            run.update(
                status=result.status,
                reason=result.reason,
                summary=result.summary,
                wall_s=round(result.wall_s, 3),
                node=result.node,
            )
            finished.add(result.key)
            _save(sweep_dir, state)
            bar.advance(_line(run, result), ok=result.status == "ok")
    except KeyboardInterrupt:
        close = getattr(results, "close", None)
        if callable(close):  # a generator: stop (kill) the runs still going first
            close()
        for spec in specs:
            if spec.key not in finished:
                by_key[spec.key]["status"] = "interrupted"
                with contextlib.suppress(OSError):
                    shutil.rmtree(sweep_dir / spec.rel_dir)
        _save(sweep_dir, state)
        raise
    finally:
        bar.stop()
    if report:
        from visnav.scenarios.report import write_report  # noqa: PLC0415 - matplotlib

        write_report(sweep_dir, state)
    return state


def _save(sweep_dir: Path, state: dict[str, Any]) -> None:
    state["updated"] = _now()
    _write_atomic(sweep_dir / STATE_NAME, json.dumps(state, indent=1) + "\n")
    write_csv(sweep_dir, state)
