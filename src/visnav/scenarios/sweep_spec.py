"""What a sweep runs: seeds x settings, parsed and checked before anything runs.

``--seeds 0-99`` (a range, both ends included), ``--seeds 0,3,7`` or ``--seeds 4``;
``--set key=v1,v2`` (one option of :func:`~visnav.scenarios.runner.run_scenario`, the
values one setting each; several ``--set`` give their cartesian product). The scenario is
``car``, ``drone`` or a YAML scenario launch file. ``--set map=PATH`` (car) localises every
run in a saved map as ``visnav run car --map PATH`` does; ``{seed}`` in ``PATH`` is replaced
by each run's seed (``--set map=runs/first/{seed}/map.yaml``: every seed in the map its own
earlier run wrote), and every run's map is checked before anything runs
(:func:`check_run_inputs`). For a launch file the keys are the file's launch
arguments (but ``seed`` and ``out``, which the sweep sets) plus ``record_all`` and
``record_images``, each value checked by loading the file with it (``choices``). Every run
gets its own directory ``runs/<setting>/<seed>`` and its own graph domain, derived
from the sweep's random id and the run's index so that no two runs of a sweep share
one, on one machine or across a cluster.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import math
import os
import re
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.runner import SCENARIOS
from visnav.scenarios.saved_map import MAP_LOCALIZATIONS, saved_map_launch_args

__all__ = [
    "DOMAIN_BASE",
    "RUN_OPTIONS",
    "RunOption",
    "RunSpec",
    "SEED_FIELD",
    "SweepError",
    "check_run_inputs",
    "check_scenario",
    "domain_for",
    "expand_runs",
    "parse_seeds",
    "parse_sets",
    "resolve_map",
    "scenario_options",
    "setting_label",
]

DOMAIN_BASE = 1 << 30
"""Sweep run domains are ``DOMAIN_BASE + (sweep_id + index) mod 2**30`` (high, private)."""


class SweepError(ScenarioError):
    """Bad sweep input (seeds, settings, scenario, backend) or an unusable sweep directory."""


@dataclasses.dataclass(frozen=True)
class RunOption:
    """One ``--set`` key: the :func:`run_scenario` keyword it sets and its type."""

    keyword: str
    type_name: str
    parse: Callable[[str], Any]
    help: str


class _ReasonedValueError(ValueError):
    """A value that does not parse, with a reason worth showing in the one-line error."""


def _parse_bool(text: str) -> bool:
    low = text.strip().lower()
    if low in ("true", "1", "yes", "on"):
        return True
    if low in ("false", "0", "no", "off"):
        return False
    raise ValueError(text)


def _parse_map_localization(text: str) -> str:
    value = text.strip()
    if value not in MAP_LOCALIZATIONS:
        raise ValueError(text)
    return value


def _parse_seconds(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(text)
    return value


SEED_FIELD = "{seed}"
"""In a ``--set map=`` value: replaced by each run's seed."""


def _parse_map(text: str) -> str:
    """A map path template, made absolute (a Ray task may run in another directory)."""
    value = text.strip()
    if not value or "\0" in value:
        raise ValueError(text)
    rest = value.replace(SEED_FIELD, "")
    if "{" in rest or "}" in rest:
        msg = f"only {SEED_FIELD} is replaced in a map path; remove the other braces"
        raise _ReasonedValueError(msg)
    return str(Path(os.path.expanduser(value)).absolute())  # noqa: PTH111 - keeps ~nobody


def resolve_map(template: str, seed: int) -> str:
    """The map path of the run with ``seed``: ``template`` with ``{seed}`` replaced."""
    return template.replace(SEED_FIELD, str(int(seed)))


RUN_OPTIONS: dict[str, RunOption] = {
    "slam": RunOption("slam", "bool", _parse_bool, "car: run and score the visual SLAM"),
    "duration": RunOption(
        "duration_s", "float > 0", _parse_seconds, "simulated seconds (default: scenario's)"
    ),
    "record_all": RunOption("record_all", "bool", _parse_bool, "also record images and clouds"),
    "record_images": RunOption(
        "record_images", "bool", _parse_bool, "also record the camera images (not the clouds)"
    ),
    "realtime": RunOption("realtime", "bool", _parse_bool, "pace the run to the wall clock"),
    "ideal_sensors": RunOption(
        "ideal_sensors", "bool", _parse_bool, "car: ground-truth odometry, noise-free cameras"
    ),
    "map": RunOption(
        "launch_args",
        "path of a map.yaml, {seed}: the run's seed",
        _parse_map,
        "car: localise in this saved map (visnav run car --map)",
    ),
    "map_localization": RunOption(
        "launch_args",
        " or ".join(MAP_LOCALIZATIONS),
        _parse_map_localization,
        "car with map: what localises in it (visnav run car --map-localization)",
    ),
}
"""The options of ``visnav run`` a sweep may vary (``--set KEY=...``).

``map`` is ``visnav run car --map`` (with ``map_localization``, its
``--map-localization``): the launch args of
:func:`~visnav.scenarios.saved_map.saved_map_launch_args` for the run's path, its ``{seed}``
replaced; the others are :func:`run_scenario` keywords.
"""
_MAP_SCENARIOS = ("car", "tb3-nav")
"""The built-in scenarios that can localise in a saved map (launch arg ``use_map``)."""


_FILE_RUNNER_KEYS = ("record_all", "record_images")
"""``--set`` keys of a launch-file sweep that are options of the runner, not launch args."""
_LAUNCH = "launch:"


def _valid_keys(options: Mapping[str, RunOption] | None = None) -> str:
    chosen = RUN_OPTIONS if options is None else options
    return ", ".join(f"{k} ({o.type_name})" for k, o in chosen.items())


def is_scenario_file(scenario: str) -> bool:
    """Whether ``scenario`` names a launch file rather than a built-in scenario."""
    return scenario not in SCENARIOS


def _load_file(path: str, args: Mapping[str, str]) -> Any:
    from visnav.errors import VisnavError  # noqa: PLC0415
    from visnav.launch.loader import load_launch  # noqa: PLC0415

    try:
        with tempfile.TemporaryDirectory(prefix="visnav-sweep-check-") as tmp:
            return load_launch(path, {"seed": "0", "out": tmp, **args})
    except VisnavError as exc:
        first = exc
    try:  # does the file lack seed / out? then say so rather than "not declared"
        declared = load_launch(path, dict(args)).args
    except VisnavError:
        declared = None
    missing = [a for a in ("seed", "out") if declared is not None and a not in declared]
    if missing:
        msg = (
            f"scenario file {path}: it declares no arg {', '.join(missing)}; a scenario "
            "file needs `- arg: {name: seed}` and `- arg: {name: out}` (the observer's "
            "output_dir), like visnav/scenarios/launch/car.launch.yaml"
        )
        raise SweepError(msg)
    raise SweepError(str(first)) from None


def scenario_options(scenario: str) -> dict[str, RunOption]:
    """The ``--set`` keys of ``scenario``: :data:`RUN_OPTIONS`, or a launch file's args.

    Raises:
        SweepError: the launch file does not load or declares no ``seed`` / ``out`` arg.
    """
    if not is_scenario_file(scenario):
        return dict(RUN_OPTIONS)
    description = _load_file(scenario, {})
    out = {k: RUN_OPTIONS[k] for k in _FILE_RUNNER_KEYS}
    for name, info in description.args.items():
        if name in ("seed", "out") or name in out:
            continue

        def check(text: str, name: str = name) -> str:
            _load_file(scenario, {name: text})
            return text

        default = "required" if info.default is None else f"default {info.default!r}"
        out[name] = RunOption(
            _LAUNCH + name, f"launch arg, {default}", check, info.description or name
        )
    return out


def parse_seeds(text: str) -> list[int]:
    """Parse ``A-B`` (inclusive), ``A,B,C`` or ``A`` into a list of distinct seeds.

    Raises:
        SweepError: not that form, a negative seed, or a range whose end is before its start.
    """
    if not text.strip():
        msg = "--seeds is empty: the sweep would run nothing; give for example --seeds 0-9"
        raise SweepError(msg)
    seeds: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        m = re.fullmatch(r"(\d+)\s*-\s*(\d+)|(\d+)", part)
        if m is None:
            msg = (
                f"--seeds {text!r}: {part!r} is not a seed or a range; expected for example "
                "0-99, 0,3,7 or 4 (non-negative integers)"
            )
            raise SweepError(msg)
        if m.group(3) is not None:
            seeds.append(int(m.group(3)))
            continue
        lo, hi = int(m.group(1)), int(m.group(2))
        if hi < lo:
            msg = f"--seeds {text!r}: the range {part} ends before it starts; write {hi}-{lo}"
            raise SweepError(msg)
        seeds.extend(range(lo, hi + 1))
    return list(dict.fromkeys(seeds))


def parse_sets(
    items: Sequence[str], options: Mapping[str, RunOption] | None = None
) -> dict[str, list[Any]]:
    """Parse ``--set key=v1,v2`` items into ``{key: [values]}`` (keys in given order).

    Args:
        items: the ``--set`` values.
        options: the valid keys (default :data:`RUN_OPTIONS`; a launch file's:
            :func:`scenario_options`).

    Raises:
        SweepError: no ``=``, an unknown key, a repeated key, an empty value list or a
            value of the wrong type; the message lists the valid keys with their types.
    """
    valid = RUN_OPTIONS if options is None else options
    out: dict[str, list[Any]] = {}
    for item in items:
        key, sep, values = item.partition("=")
        key = key.strip()
        if key not in valid:
            key = key.replace("-", "_")
        if not sep or key not in valid:
            what = f"unknown key {key!r}" if sep else "no '=' in it"
            msg = f"--set {item!r}: {what}; expected KEY=V1,V2 with KEY one of {_valid_keys(valid)}"
            raise SweepError(msg)
        if key in out:
            msg = f"--set {item!r}: {key} is set twice; give all its values in one --set"
            raise SweepError(msg)
        option = valid[key]
        parsed: list[Any] = []
        for raw in values.split(","):
            try:
                parsed.append(option.parse(raw))
            except ValueError as exc:
                why = f" ({exc})" if isinstance(exc, _ReasonedValueError) else ""
                msg = (
                    f"--set {item!r}: {key}={raw!r} is not a {option.type_name}{why}; valid "
                    f"keys: {_valid_keys(valid)}"
                )
                raise SweepError(msg) from None
        out[key] = list(dict.fromkeys(parsed))
    return out


def _format_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


_MAX_LABEL = 200
"""Longer setting labels are cut and end in a digest (a file name has at most 255 bytes)."""


def _label_value(value: Any) -> str:
    """A value in a directory name: ``%`` and ``/`` escaped (``%25``, ``%2F``), so distinct."""
    return _format_value(value).replace("%", "%25").replace("/", "%2F")


def setting_label(setting: dict[str, Any]) -> str:
    """The directory name of a setting: ``slam=false,duration=5``, or ``default``.

    A path value has its ``/`` written ``%2F`` (``map=%2Fruns%2F{seed}%2Fmap.yaml``); a
    label longer than 200 bytes is cut and ends in ``~`` and 12 hex digits of its SHA-256.
    """
    if not setting:
        return "default"
    label = ",".join(f"{k}={_label_value(v)}" for k, v in setting.items())
    if len(label.encode()) > _MAX_LABEL:
        digest = hashlib.sha256(label.encode()).hexdigest()[:12]
        head = label.encode()[: _MAX_LABEL - 13].decode(errors="ignore")
        label = f"{head}~{digest}"
    return label


def domain_for(sweep_id: int, index: int) -> int:
    """The graph domain of run ``index`` of sweep ``sweep_id`` (distinct within a sweep)."""
    return DOMAIN_BASE + (sweep_id + index) % DOMAIN_BASE


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: the scenario, a setting, a seed and where it goes."""

    index: int
    scenario: str
    setting: str
    options: dict[str, Any]
    seed: int
    domain: int

    @property
    def rel_dir(self) -> str:
        """The run's directory relative to the sweep directory."""
        return f"runs/{self.setting}/{self.seed}"

    @property
    def key(self) -> str:
        """``<setting>/<seed>``: unique within a sweep."""
        return f"{self.setting}/{self.seed}"

    def run_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of :func:`run_scenario` for this run (not ``out``)."""
        kwargs: dict[str, Any] = {}
        launch: dict[str, str] = {}
        file = is_scenario_file(self.scenario)
        for key, value in self.options.items():
            if file and key not in _FILE_RUNNER_KEYS:
                launch[key] = _format_value(value)
            elif key == "map" and self.scenario.startswith("tb3-"):  # their map_file
                launch["map"] = str(value)
            elif key == "map":  # as visnav run car --map
                loc = str(self.options.get("map_localization", "slam"))
                slam = bool(self.options.get("slam", True))
                launch.update(saved_map_launch_args(str(value), loc, slam=slam))
            elif key == "map_localization":
                continue  # read with map
            else:
                kwargs[RUN_OPTIONS[key].keyword] = value
        if launch:
            kwargs["launch_args"] = launch
        return {"seed": self.seed, **kwargs}

    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict (:meth:`from_json` reverses it)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> RunSpec:
        """Rebuild a spec written by :meth:`to_json`."""
        return cls(
            index=int(data["index"]),
            scenario=str(data["scenario"]),
            setting=str(data["setting"]),
            options=dict(data["options"]),
            seed=int(data["seed"]),
            domain=int(data["domain"]),
        )


def check_scenario(name: str) -> str:
    """Return a built-in scenario's name, or a scenario launch file's absolute path.

    Raises:
        SweepError: neither a built-in scenario nor an existing YAML launch file.
    """
    if name in SCENARIOS:
        return name
    path = Path(name)
    if path.suffix in (".yaml", ".yml") and path.is_file():
        return str(path.absolute())
    looks_like_file = "/" in name or "." in name
    what = "no such YAML launch file (.yaml)" if looks_like_file else "not a built-in scenario"
    msg = (
        f"scenario {name!r}: {what}; expected {', '.join(SCENARIOS)} or the path of a "
        "scenario launch file (see visnav/scenarios/launch/car.launch.yaml)"
    )
    raise SweepError(msg)


def expand_runs(
    scenario: str, seeds: Sequence[int], sets: dict[str, list[Any]], *, sweep_id: int
) -> list[RunSpec]:
    """The cartesian product of settings and seeds, settings outermost.

    A run's ``options`` are its setting's with ``{seed}`` in ``map`` replaced by its seed
    (so ``sweep.json`` and ``sweep.csv`` name the map each run used); its setting label
    keeps the template.

    Raises:
        SweepError: the product is empty, or ``map`` is set for a scenario without one.
    """
    scenario = check_scenario(scenario)
    if "map" in sets and not is_scenario_file(scenario) and scenario not in _MAP_SCENARIOS:
        msg = (
            f"--set map: the {scenario} scenario cannot localise in a saved map; map is "
            f"for {', '.join(_MAP_SCENARIOS)} (visnav run car --map)"
        )
        raise SweepError(msg)
    if "map_localization" in sets and "map" not in sets and not is_scenario_file(scenario):
        msg = "--set map_localization: only with --set map (what localises in the saved map)"
        raise SweepError(msg)
    keys = list(sets)
    settings = [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*sets.values())]
    if not seeds or not settings:
        msg = "the sweep is empty (no seeds or a --set without values); give --seeds 0-9, say"
        raise SweepError(msg)
    runs: list[RunSpec] = []
    for setting in settings:
        label = setting_label(setting)
        for seed in seeds:
            index = len(runs)
            options = dict(setting)
            if "map" in options and not is_scenario_file(scenario):
                options["map"] = resolve_map(str(options["map"]), seed)
            runs.append(RunSpec(index, scenario, label, options, seed, domain_for(sweep_id, index)))
    return runs


def check_run_inputs(runs: Sequence[RunSpec]) -> None:
    """Check the input files of ``runs`` before any runs: each run's ``map`` loads.

    With SLAM localising (``map_localization`` slam, the default) the ``slam_map.npz``
    beside it must exist too (it is read, and its errors reported, by the SLAM node).

    Each map is read as map_server reads it (YAML and image), so a missing or broken map
    stops the sweep before anything runs, as other bad input does.

    Raises:
        SweepError: a run's map is missing or invalid; the line names the seed, the path,
            and how many other runs' maps are missing too.
    """
    from visnav.errors import VisnavError  # noqa: PLC0415
    from visnav.mapping.map_io import load_map  # noqa: PLC0415 - numpy, only with a map

    problems: list[tuple[RunSpec, str]] = []
    for spec in runs:
        path = spec.options.get("map") if not is_scenario_file(spec.scenario) else None
        if path is None:
            continue
        if not Path(path).is_file():
            why = (
                f"no map file {path}; expected the map.yaml of an earlier car run (visnav run "
                f"car --seed {spec.seed} --out DIR writes DIR/map.yaml), or fix --set map"
            )
            problems.append((spec, why))
            continue
        try:
            load_map(path)
            loc = str(spec.options.get("map_localization", "slam"))
            if not spec.scenario.startswith("tb3-"):  # the TurtleBot3 runs: AMCL only
                slam = bool(spec.options.get("slam", True))
                saved_map_launch_args(path, loc, slam=slam, check=True)
        except ScenarioError as exc:  # no SLAM map beside the map
            problems.append((spec, str(exc)))
        except VisnavError as exc:
            problems.append((spec, f"bad map: {exc}"))
    if problems:
        spec, why = problems[0]
        others = ""
        if len(problems) > 1:
            seeds = sorted({s.seed for s, _ in problems[1:]})
            shown = ", ".join(map(str, seeds[:10])) + (", ..." if len(seeds) > 10 else "")
            others = f" (and {len(problems) - 1} more runs' maps, seeds {shown})"
        msg = f"--set map: seed {spec.seed}: {why}{others}"
        raise SweepError(msg)
