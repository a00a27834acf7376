"""Sweep input: seeds, --set settings, the run product and domains; bad input in one line."""

from __future__ import annotations

import contextlib
import functools
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.scenarios.runner import launch_file
from visnav.scenarios.sweep import load_state
from visnav.scenarios.sweep_spec import (
    RunSpec,
    SweepError,
    check_scenario,
    domain_for,
    expand_runs,
    parse_seeds,
    parse_sets,
    scenario_options,
    setting_label,
)


def test_seeds_ranges_lists_and_single() -> None:
    assert parse_seeds("0-3") == [0, 1, 2, 3]
    assert parse_seeds("5, 1,5,2-3") == [5, 1, 2, 3]
    assert parse_seeds("7") == [7]


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("5-2", r"--seeds '5-2': the range 5-2 ends before it starts; write 2-5"),
        ("", r"--seeds is empty"),
        ("a", r"'a' is not a seed or a range; expected for example 0-99"),
        ("-3", r"is not a seed or a range"),
    ],
)
def test_bad_seeds_one_line(text: str, pattern: str) -> None:
    with pytest.raises(SweepError, match=pattern) as info:
        parse_seeds(text)
    assert "\n" not in str(info.value)


def test_sets_parse_typed_values_in_order() -> None:
    sets = parse_sets(["slam=false,true", "duration=2.5", "record-all=no"])
    assert sets == {"slam": [False, True], "duration": [2.5], "record_all": [False]}
    assert setting_label({"slam": False, "duration": 5.0}) == "slam=false,duration=5"
    assert setting_label({}) == "default"


@pytest.mark.parametrize(
    ("item", "pattern"),
    [
        ("planner=dwa", r"unknown key 'planner'; expected KEY=V1,V2 with KEY one of slam \(bool\)"),
        ("slam=maybe", r"slam='maybe' is not a bool; valid keys: slam \(bool\), duration"),
        ("duration=-1", r"duration='-1' is not a float > 0"),
        ("slam", r"no '=' in it"),
    ],
)
def test_bad_set_lists_valid_keys_with_types(item: str, pattern: str) -> None:
    with pytest.raises(SweepError, match=pattern) as info:
        parse_sets([item])
    message = str(info.value)
    assert "\n" not in message
    assert "record_all (bool)" in message


def test_product_settings_outermost_and_distinct_domains() -> None:
    runs = expand_runs("car", [0, 1], {"slam": [False, True]}, sweep_id=2**30 - 1)
    assert [(r.setting, r.seed) for r in runs] == [
        ("slam=false", 0),
        ("slam=false", 1),
        ("slam=true", 0),
        ("slam=true", 1),
    ]
    assert runs[3].rel_dir == "runs/slam=true/1"
    assert runs[3].run_kwargs() == {"seed": 1, "slam": True}
    assert len({r.domain for r in runs}) == 4  # wraps around 2**30 without colliding
    assert all(2**30 <= r.domain < 2**31 for r in runs)
    assert RunSpec.from_json(json.loads(json.dumps(runs[2].to_json()))) == runs[2]
    assert domain_for(7, 3) == domain_for(8, 2)  # only the sum matters; ids are random


def test_empty_product_and_unknown_scenarios_refused() -> None:
    with pytest.raises(SweepError, match="the sweep is empty"):
        expand_runs("car", [], {}, sweep_id=0)
    with pytest.raises(SweepError, match="no such YAML launch file"):
        expand_runs("my_scenario.yaml", [0], {}, sweep_id=0)
    with pytest.raises(SweepError, match="scenario 'boat': not a built-in scenario"):
        expand_runs("boat", [0], {}, sweep_id=0)


def test_a_launch_file_scenario_sets_its_args(tmp_path: Path) -> None:
    path = tmp_path / "my_car.launch.yaml"
    path.write_text(launch_file("car").read_text())
    scenario = check_scenario(str(path))
    assert scenario == str(path.absolute())
    options = scenario_options(scenario)
    assert {"slam", "ideal_sensors", "goals", "duration", "record_all"} <= set(options)
    assert "seed" not in options
    assert "out" not in options
    sets = parse_sets(["goals=1,2", "slam=false", "record-all=yes"], options)
    assert sets == {"goals": ["1", "2"], "slam": ["false"], "record_all": [True]}
    runs = expand_runs(scenario, [3], sets, sweep_id=0)
    assert [r.setting for r in runs] == [
        "goals=1,slam=false,record_all=true",
        "goals=2,slam=false,record_all=true",
    ]
    assert runs[1].run_kwargs() == {
        "seed": 3,
        "record_all": True,
        "launch_args": {"goals": "2", "slam": "false"},
    }
    # values are checked by loading the file with them (choices), keys against its args
    with pytest.raises(SweepError, match="slam='maybe' is not a launch arg"):
        parse_sets(["slam=maybe"], options)
    with pytest.raises(SweepError, match="unknown key 'gaols'; expected KEY=V1,V2 with KEY one of"):
        parse_sets(["gaols=3"], options)


def test_a_launch_file_without_seed_or_out_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "bare.launch.yaml"
    path.write_text("launch:\n  - arg: {name: seed, default: '0'}\n")
    with pytest.raises(SweepError, match="declares no arg out"):
        scenario_options(check_scenario(str(path)))


@functools.cache
def _drone_options() -> dict[str, Any]:
    return scenario_options(str(launch_file("drone")))


@settings(max_examples=40, deadline=None)
@given(st.lists(st.text(max_size=25), max_size=3))
def test_fuzz_file_sets_only_visnav_errors(items: list[str]) -> None:
    options = _drone_options()
    try:
        sets = parse_sets(items, options)
    except VisnavError:
        return
    assert all(values for values in sets.values())


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "sweep", *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


@pytest.mark.parametrize(
    ("args", "start"),
    [
        (["--seeds", "0-1", "--set", "planner=dwa"], "error: --set 'planner=dwa': unknown key"),
        (["--seeds", "5-2"], "error: --seeds '5-2': the range 5-2 ends before it starts"),
        (["--seeds", "0", "--address", "auto"], "error: --address is for --backend ray"),
        (["--seeds", "0", "--jobs", "0"], "error: --jobs is 0"),
    ],
)
def test_cli_bad_input_one_line_before_anything_runs(
    tmp_path: Path, args: list[str], start: str
) -> None:
    out = tmp_path / "sweep"
    done = _cli("car", *args, "--out", str(out))
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(start), lines[0]
    assert not out.exists()


def test_existing_sweep_needs_resume_and_same_arguments(tmp_path: Path) -> None:
    (tmp_path / "sweep.json").write_text(
        json.dumps(
            {"version": 1, "runs": [], "scenario": "car", "seeds": [0], "sets": {}, "sweep_id": 3}
        )
    )
    done = _cli("car", "--seeds", "0", "--out", str(tmp_path))
    assert done.stderr.strip().endswith("pass --resume to finish it, or choose another --out")
    done = _cli("car", "--seeds", "0-1", "--resume", "--out", str(tmp_path))
    assert "holds a sweep with --seeds [0], not [0, 1]" in done.stderr


def test_report_of_a_directory_without_sweep(tmp_path: Path) -> None:
    done = _cli("report", str(tmp_path))
    assert done.returncode == 1
    assert f"{tmp_path / 'sweep.json'} does not exist" in done.stderr


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=30))
def test_fuzz_seeds_only_visnav_errors(text: str) -> None:
    try:
        seeds = parse_seeds(text)
    except VisnavError:
        return
    assert seeds
    assert all(s >= 0 for s in seeds)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.text(max_size=25), max_size=3))
def test_fuzz_sets_only_visnav_errors(items: list[str]) -> None:
    try:
        sets = parse_sets(items)
    except VisnavError:
        return
    assert all(values for values in sets.values())


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=200) | st.text(max_size=200).map(str.encode))
def test_fuzz_sweep_state_only_visnav_errors(
    tmp_path_factory: pytest.TempPathFactory, data: bytes
) -> None:
    root = tmp_path_factory.mktemp("state")
    (root / "sweep.json").write_bytes(data)
    with contextlib.suppress(VisnavError):
        load_state(root)
