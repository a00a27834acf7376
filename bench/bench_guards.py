"""Benchmark: what the input guards of issue 13 cost.

Rows, each a median of ``ROUNDS`` rounds, with its reference timed alternately in the same
rounds (so both see the same machine load):

* **YAML load** of a realistic launch file (the docs example, repeated to ~200 entries)
  and of a world file: :func:`visnav.safe_yaml.load_yaml` (SafeLoader plus the alias
  check) against plain ``yaml.load(..., SafeLoader)`` on the same text. Both use the
  pure-Python loader (as visnav does, for line numbers).
* **Alias bomb** (469 bytes, 9 levels of 9 aliases): visnav's refusal against PyYAML
  merely constructing it (shared references; walking it is what took 40 s before).
* **Instability check** per physics step: :meth:`InstabilityMonitor.check` against
  ``mujoco.mj_step`` of a one-body model (the cheapest step a robot can have).

Run: python bench/bench_guards.py
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import mujoco
import yaml

from visnav.safe_yaml import YamlError, load_yaml
from visnav.sim.guards import InstabilityMonitor

ROUNDS = 9

LAUNCH_ENTRY = """\
  - arg: {name: robot%(i)d, default: car, description: "car or quad"}
  - group:
      namespace: $(arg robot%(i)d)
      use_sim_time: true
      children:
        - node:
            exec: depthimage_to_laserscan
            name: depth_to_scan
            params: {range_max: 8.0, output_frame: camera_link, ranges: [0.1, 0.2, 0.3]}
            remap: {depth: /front/depth/image_raw, depth_camera_info: /front/depth/camera_info}
"""
LAUNCH = "launch:\n" + "".join(LAUNCH_ENTRY % {"i": i} for i in range(100))

WORLD_OBJECT = (
    "  - {type: box, name: wall%(i)d, pos: [%(i)d, 3, 1], size: [6, 0.2, 2], material: wall}\n"
)
WORLD = (
    "name: bench\nground: {size: [100, 100]}\nmaterials:\n  wall: &wall {rgba: [1, 0, 0, 1]}\n"
    "objects:\n" + "".join(WORLD_OBJECT % {"i": i} for i in range(500))
)


def bomb() -> str:
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for prev, name in zip("abcdefgh", "bcdefghi", strict=True):
        lines.append(f"{name}: &{name} [" + ",".join([f"*{prev}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def paired(
    ours: Callable[[], object], ref: Callable[[], object], *, repeat: int
) -> tuple[float, float]:
    """Median seconds per call of ``ours`` and ``ref``, timed alternately in each round."""
    times: tuple[list[float], list[float]] = ([], [])
    for _ in range(ROUNDS):
        for func, out in ((ours, times[0]), (ref, times[1])):
            start = time.perf_counter()
            for _ in range(repeat):
                func()
            out.append((time.perf_counter() - start) / repeat)
    return statistics.median(times[0]), statistics.median(times[1])


def refuse(text: str) -> None:
    try:
        load_yaml(text, source="bomb.yaml")
    except YamlError:
        return
    msg = "the bomb was not refused"
    raise AssertionError(msg)


def row(name: str, ours: float, ref: float, unit: str = "ms") -> None:
    scale = 1e3 if unit == "ms" else 1e6
    print(f"{name:<34} {ours * scale:10.3f} {ref * scale:10.3f} {unit}   ratio {ours / ref:5.2f}")


def main() -> None:
    print(f"{'row':<34} {'visnav':>10} {'reference':>10}")
    for name, text in (("launch YAML, 400 entries", LAUNCH), ("world YAML, 500 objects", WORLD)):
        ours, ref = paired(
            lambda t=text: load_yaml(t, source="x.yaml"),
            lambda t=text: yaml.load(t, Loader=yaml.SafeLoader),
            repeat=3,
        )
        row(f"{name} ({len(text) // 1024} KB)", ours, ref)
    text = bomb()
    ours, ref = paired(
        lambda: refuse(text), lambda: yaml.load(text, Loader=yaml.SafeLoader), repeat=20
    )
    row(f"alias bomb ({len(text)} B): refuse/load", ours, ref)
    xml = '<mujoco><worldbody><body><freejoint/><geom size=".1"/></body></worldbody></mujoco>'
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    monitor = InstabilityMonitor(data)
    ours, ref = paired(lambda: monitor.check(0), lambda: mujoco.mj_step(model, data), repeat=20_000)
    row("instability check / mj_step", ours, ref, unit="us")


if __name__ == "__main__":
    main()
