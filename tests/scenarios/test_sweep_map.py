"""``--set map=PATH`` in a sweep: ``visnav run car --map`` per run, ``{seed}`` per seed."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.mapping.map_io import save_map
from visnav.scenarios.sweep import load_state, run_sweep
from visnav.scenarios.sweep_local import LocalBackend
from visnav.scenarios.sweep_spec import (
    RUN_OPTIONS,
    RunSpec,
    SweepError,
    check_run_inputs,
    expand_runs,
    parse_sets,
    setting_label,
)
from visnav.scenarios.sweep_worker import RunResult


def _write_map(path: Path, *, slam_map: bool = True) -> Path:
    """A small valid map_server map (map.yaml + map.pgm) in ``path``'s directory.

    With ``slam_map`` a ``slam_map.npz`` beside it too (the sweep checks only that it is
    there; the SLAM node reads it).
    """
    import numpy as np

    from visnav.mapping.map_io import MapMetadata, OccupancyMap

    grid = np.zeros((4, 5), dtype=np.int8)
    grid[0, :] = 100
    meta = MapMetadata(
        image=path.with_suffix(".pgm"),
        resolution=0.05,
        origin=(0.0, 0.0, 0.0),
        negate=False,
        occupied_thresh=0.65,
        free_thresh=0.196,
        mode="trinary",
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    save_map(OccupancyMap(grid, meta).to_msg(), path.with_suffix(""))
    assert path.is_file()
    if slam_map:
        (path.parent / "slam_map.npz").write_bytes(b"")
    return path


def test_map_parses_to_an_absolute_template(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    sets = parse_sets(["map=runs/first/{seed}/map.yaml"])
    assert sets == {"map": [str(tmp_path / "runs/first/{seed}/map.yaml")]}
    two = parse_sets(["map=/a/{seed}/map.yaml,/b/map.yaml"])
    assert two == {"map": ["/a/{seed}/map.yaml", "/b/map.yaml"]}
    with pytest.raises(SweepError) as info:
        parse_sets(["planner=x"])
    assert "map (path of a map.yaml, {seed}: the run's seed)" in str(info.value)


@pytest.mark.parametrize(
    ("item", "pattern"),
    [
        ("map=", r"--set 'map=': map='' is not a path of a map.yaml"),
        ("map= ", r"map=' ' is not a path of a map.yaml"),
        (
            "map=/m/{Seed}/map.yaml",
            r"map='/m/\{Seed\}/map.yaml' is not a path of a map.yaml, \{seed\}: the run's seed "
            r"\(only \{seed\} is replaced in a map path; remove the other braces\); valid keys",
        ),
    ],
)
def test_bad_map_values_one_line(item: str, pattern: str) -> None:
    with pytest.raises(SweepError, match=pattern) as info:
        parse_sets([item])
    assert "\n" not in str(info.value)


def test_seed_replaced_per_run_and_passed_as_visnav_run_car_map() -> None:
    runs = expand_runs("car", [3, 12], {"map": ["/m/{seed}/map.yaml"], "slam": [False]}, sweep_id=5)
    assert [r.options["map"] for r in runs] == ["/m/3/map.yaml", "/m/12/map.yaml"]
    assert runs[0].setting == runs[1].setting == "map=%2Fm%2F{seed}%2Fmap.yaml,slam=false"
    assert runs[1].rel_dir == "runs/map=%2Fm%2F{seed}%2Fmap.yaml,slam=false/12"
    assert runs[1].run_kwargs() == {
        "seed": 12,
        "slam": False,
        # without SLAM the saved map is AMCL's: no slam_map
        "launch_args": {"map": "/m/12/map.yaml", "use_map": "true", "map_localization": "slam"},
    }
    assert RunSpec.from_json(json.loads(json.dumps(runs[1].to_json()))) == runs[1]
    fixed = expand_runs("car", [0, 1], {"map": ["/m/map.yaml"]}, sweep_id=0)
    assert {r.options["map"] for r in fixed} == {"/m/map.yaml"}  # no {seed}: one map for all


def test_labels_of_paths_stay_distinct_and_short() -> None:
    assert setting_label({"map": "/a/b"}) != setting_label({"map": "/a%2Fb"})
    assert "/" not in setting_label({"map": "/a/b"})
    long = setting_label({"map": "/x" * 300})
    assert len(long.encode()) <= 200
    assert long != setting_label({"map": "/x" * 301})


def test_map_only_for_the_car() -> None:
    with pytest.raises(SweepError, match=r"--set map: the drone scenario cannot localise"):
        expand_runs("drone", [0], {"map": ["/m/map.yaml"]}, sweep_id=0)


def test_missing_map_names_the_seed_and_path(tmp_path: Path) -> None:
    _write_map(tmp_path / "1" / "map.yaml")
    template = str(tmp_path / "{seed}" / "map.yaml")
    runs = expand_runs("car", [1, 2, 4], {"map": [template]}, sweep_id=0)
    with pytest.raises(SweepError) as info:
        check_run_inputs(runs)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(
        f"--set map: seed 2: no map file {tmp_path / '2' / 'map.yaml'}; expected the map.yaml "
        "of an earlier car run (visnav run car --seed 2 --out DIR writes DIR/map.yaml)"
    )
    assert message.endswith("(and 1 more runs' maps, seeds 4)")
    check_run_inputs(runs[:1])  # seed 1's map is there


def test_a_missing_slam_map_is_refused_unless_amcl_localises(tmp_path: Path) -> None:
    _write_map(tmp_path / "3" / "map.yaml", slam_map=False)
    template = str(tmp_path / "{seed}" / "map.yaml")
    runs = expand_runs("car", [3], {"map": [template]}, sweep_id=0)
    with pytest.raises(SweepError) as info:
        check_run_inputs(runs)
    message = str(info.value)
    assert message.startswith(f"--set map: seed 3: {tmp_path / '3' / 'map.yaml'}: no SLAM map ")
    assert message.endswith("(--map-localization amcl)")
    amcl = {"map": [template], "map_localization": ["amcl"]}
    (run,) = expand_runs("car", [3], amcl, sweep_id=0)
    check_run_inputs([run])
    assert run.run_kwargs()["launch_args"]["map_localization"] == "amcl"
    check_run_inputs(expand_runs("car", [3], {"map": [template], "slam": [False]}, sweep_id=0))
    with pytest.raises(SweepError, match=r"--set map_localization: only with --set map"):
        expand_runs("car", [3], {"map_localization": ["amcl"]}, sweep_id=0)
    with pytest.raises(SweepError, match=r"map_localization"):
        parse_sets(["map_localization=gps"])


def test_broken_map_is_refused_with_map_servers_reason(tmp_path: Path) -> None:
    path = _write_map(tmp_path / "0" / "map.yaml")
    path.with_suffix(".pgm").unlink()
    runs = expand_runs("car", [0], {"map": [str(tmp_path / "{seed}/map.yaml")]}, sweep_id=0)
    with pytest.raises(SweepError, match=r"--set map: seed 0: bad map: .*map.pgm"):
        check_run_inputs(runs)


def test_a_missing_map_stops_the_sweep_before_anything_runs(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    sets = parse_sets([f"map={tmp_path}/{{seed}}/map.yaml"])
    with pytest.raises(SweepError, match=r"seed 0: no map file"):
        run_sweep("car", out=out, backend=LocalBackend(jobs=1), seeds=[0], sets=sets)
    assert not out.exists()


class _FailingBackend:
    """Records what it was asked to run; every run fails (no process is started)."""

    name = "fake"

    def __init__(self) -> None:
        self.keys: list[str] = []

    def run(self, specs: Sequence[RunSpec], sweep_dir: Path) -> Iterator[RunResult]:
        for spec in specs:
            self.keys.append(spec.key)
            yield RunResult(spec.key, "failed", "fake")


def test_resume_checks_the_maps_of_the_runs_left(tmp_path: Path) -> None:
    for seed in (0, 1):
        _write_map(tmp_path / str(seed) / "map.yaml")
    out = tmp_path / "sweep"
    sets = parse_sets([f"map={tmp_path}/{{seed}}/map.yaml"])
    backend = _FailingBackend()
    state = run_sweep(
        "car", out=out, backend=backend, seeds=[0, 1], sets=sets, progress=None, report=False
    )
    assert [r["options"]["map"] for r in state["runs"]] == [
        str(tmp_path / "0" / "map.yaml"),
        str(tmp_path / "1" / "map.yaml"),
    ]
    assert load_state(out)["sets"] == {"map": [str(tmp_path / "{seed}" / "map.yaml")]}
    (tmp_path / "1" / "map.yaml").unlink()
    with pytest.raises(SweepError, match=r"^--set map: seed 1: no map file "):
        run_sweep("car", out=out, backend=backend, resume=True, progress=None, report=False)
    assert len(backend.keys) == 2  # nothing ran on the refused resume
    assert {r["status"] for r in load_state(out)["runs"]} == {"failed"}


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=40))
def test_fuzz_map_values_only_visnav_errors(text: str) -> None:
    try:
        sets = parse_sets([f"map={text}"])
    except VisnavError:
        return
    for template in sets["map"]:
        assert Path(template).is_absolute()
        runs = expand_runs("car", [7], {"map": [template]}, sweep_id=0)
        assert "{seed}" not in runs[0].options["map"]
        assert "/" not in runs[0].setting


def test_option_is_registered() -> None:
    assert RUN_OPTIONS["map"].keyword == "launch_args"


@pytest.mark.slow
def test_a_sweep_localises_each_seed_in_its_own_map(tmp_path: Path) -> None:
    first = tmp_path / "first" / "1"
    subprocess.run(
        [
            sys.executable, "-m", "visnav.cli.main", "run", "car", "--quiet", "--no-slam",
            "--duration", "3", "--seed", "1", "--out", str(first),
        ],
        capture_output=True, timeout=300, check=True,
        env={**os.environ, "VISNAV_DOMAIN": str(1_700_000_000 + os.getpid() % 100_000)},
    )  # fmt: skip
    shutil.rmtree(first / "bag")  # only the map is needed
    out = tmp_path / "sweep"
    done = subprocess.run(
        [
            sys.executable, "-m", "visnav.cli.main", "sweep", "car", "--quiet", "--seeds", "1",
            "--set", "slam=false", "--set", "duration=3", "--set",
            f"map={tmp_path}/first/{{seed}}/map.yaml", "--out", str(out), "--no-report",
        ],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    (run,) = load_state(out)["runs"]
    assert run["status"] == "ok", run["reason"]
    assert run["options"]["map"] == str(first / "map.yaml")
    assert run["summary"]["localization"]["source"] == "amcl"
    assert (out / run["dir"] / "summary.json").is_file()


def test_cli_missing_map_one_line_before_anything_runs(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    done = subprocess.run(
        [
            sys.executable, "-m", "visnav.cli.main", "sweep", "car", "--seeds", "3",
            "--set", f"map={tmp_path}/{{seed}}/map.yaml", "--out", str(out),
        ],
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(f"error: --set map: seed 3: no map file {tmp_path}/3/map.yaml;")
    assert not out.exists()
