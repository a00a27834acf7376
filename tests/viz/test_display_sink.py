"""DisplaySink: the display rate per topic, TF never dropped, a bounded queue, a worker thread."""

from __future__ import annotations

import itertools
import json
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rerun")

from visnav.msgs import Header, LaserScan, make, ns_to_time, numpy_to_image
from visnav.viz.display_sink import DISPLAY_RATES_HZ, DisplaySink

MS = 1_000_000


class _Recorder:
    """A stand-in RerunSink that records what the worker logs (and on which thread)."""

    def __init__(self, delay_s: float = 0.0) -> None:
        self.logged: list[tuple[str, int]] = []
        self.threads: set[str] = set()
        self.worlds: list[Any] = []
        self.delay_s = delay_s
        self.fixed_frame = None
        self.closed = False

    def log(self, topic: str, msg: Any, stamp_ns: int | None = None) -> bool:
        time.sleep(self.delay_s)
        # a TFMessage: one entry per transform (the worker merges a batch's /tf messages)
        for item in getattr(msg, "transforms", None) or [msg]:
            header = getattr(item, "header", None)
            self.logged.append(
                (topic, header.stamp.sec * 10**9 + header.stamp.nanosec if header else -1)
            )
        self.threads.add(threading.current_thread().name)
        return True

    def log_world(self, world: Any) -> list[str]:
        self.worlds.append(world)
        return ["world/scene/boxes"]

    def poll(self) -> None:
        pass

    def close(self) -> None:
        self.closed = True

    def stats(self) -> dict[str, dict[str, Any]]:
        return {t: {"logged": 1} for t, _ in self.logged}


def _image(t_ns: int) -> Any:
    return numpy_to_image(
        np.zeros((2, 2, 3), np.uint8), "rgb8", header=Header(stamp=ns_to_time(t_ns), frame_id="c")
    )


def test_images_are_kept_at_the_display_rate_and_tf_always(vz: Any) -> None:
    rec = _Recorder()
    sink = DisplaySink(rec)  # type: ignore[arg-type]
    for i in range(30):  # 30 Hz for 1 s
        sink.log("/cam/image_raw", _image(i * 33 * MS))
        sink.log("/tf", vz.tf_msg(vz.tf("odom", "base", i * 33 * MS)))
    sink.close()
    images = [t for topic, t in rec.logged if topic == "/cam/image_raw"]
    assert len(images) == 5  # 5 Hz: one every 200 ms of stamp time
    assert all(b - a >= 200 * MS for a, b in itertools.pairwise(images))
    assert sum(topic == "/tf" for topic, _ in rec.logged) == 30
    assert sink.skipped == {"/cam/image_raw": 25}
    assert rec.threads == {"visnav-viewer"}  # logged on the worker, not the caller
    assert rec.closed
    assert DISPLAY_RATES_HZ["sensor_msgs/msg/Image"] == 5.0


def test_all_frames_with_empty_rates() -> None:
    rec = _Recorder()
    sink = DisplaySink(rec, rates_hz={})  # type: ignore[arg-type]
    for i in range(10):
        sink.log("/cam/image_raw", _image(i * MS))
    sink.close()
    assert len(rec.logged) == 10


def test_a_full_queue_skips_live_and_waits_for_a_bag() -> None:
    slow = _Recorder(delay_s=0.02)
    live = DisplaySink(slow, rates_hz={}, max_pending=3)  # type: ignore[arg-type]
    for i in range(20):
        live.log("/cam/image_raw", _image(i * MS))
    live.close()
    assert live.skipped["/cam/image_raw"] >= 10
    assert len(slow.logged) + live.skipped["/cam/image_raw"] == 20
    slow = _Recorder(delay_s=0.005)
    bag = DisplaySink(slow, rates_hz={}, max_pending=3, block=True)  # type: ignore[arg-type]
    for i in range(20):
        bag.log("/cam/image_raw", _image(i * MS))
    bag.close()
    assert len(slow.logged) == 20
    assert not bag.skipped


def test_the_world_is_loaded_off_the_callers_thread() -> None:
    rec = _Recorder()
    names: list[str] = []

    def loader() -> Any:
        names.append(threading.current_thread().name)
        return "a world"

    sink = DisplaySink(rec, world_loader=loader)  # type: ignore[arg-type]
    scan = make(LaserScan, header=Header(stamp=ns_to_time(MS), frame_id="laser"))
    sink.log("/scan", scan)
    assert sink.flush(5.0)
    sink.close()
    assert names == ["visnav-viewer-world"]
    assert rec.worlds == ["a world"]
    assert sink.stats()["/scan"]["skipped"] == 0


def test_world_for_bag_reads_the_run_summary(tmp_path: Path) -> None:
    from visnav.viz.scene import SCENARIO_WORLDS, load_sim_world, world_for_bag

    bag = tmp_path / "run" / "bag"
    bag.mkdir(parents=True)
    assert world_for_bag(bag) is None  # no summary.json
    (tmp_path / "run" / "summary.json").write_text(json.dumps({"scenario": "x", "seed": 0}))
    assert world_for_bag(bag) is None  # not a built-in scenario
    worlds = {**SCENARIO_WORLDS, "x": "office"}
    world = world_for_bag(bag, worlds=worlds)
    assert world is not None
    assert world.name == load_sim_world("office", seed=0).name
    assert SCENARIO_WORLDS["car"] == "office"
    assert SCENARIO_WORLDS["drone"] == "forest"


def test_world_archetypes_carry_the_materials_colours() -> None:
    from visnav.description.world_yaml import world_from_dict
    from visnav.viz.world_view import world_archetypes

    world = world_from_dict(
        {
            "name": "w",
            "materials": {"red": {"rgba": [1, 0, 0, 1]}},
            "objects": [
                {"type": "box", "name": "a", "size": [1, 2, 3], "material": "red"},
                {"type": "box", "name": "b", "size": [1, 1, 1], "rgba": [0, 0, 1, 1]},
                {"type": "cylinder", "name": "c", "radius": 0.5, "length": 2.0},
                {"type": "sphere", "name": "d", "radius": 0.5, "visual": False},
            ],
        }
    )
    out = dict(world_archetypes(world))
    assert set(out) == {"world/scene/boxes", "world/scene/cylinders", "world/scene/ground"}
    boxes = out["world/scene/boxes"]
    colors = boxes.colors.as_arrow_array().to_pylist()
    assert colors == [0xFF0000FF, 0x0000FFFF]  # RGBA packed: red, blue
    halves = np.asarray(boxes.half_sizes.as_arrow_array().to_pylist())
    assert np.allclose(halves[0], [0.5, 1.0, 1.5])
