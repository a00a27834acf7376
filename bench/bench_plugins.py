"""Benchmark: what the parameter idiom and the plugin registries cost (issue 17).

Rows (medians of repeated runs, ratio to the reference measured in the same run):

* ``compressed`` publish through :class:`ImageTransportPublisher` (registry codec) vs the
  codec function :func:`compress` called directly, one 640x480 rgb8 frame (JPEG 80);
* declaring move_base's parameter dataclasses (navigator, global planner, DWA, RPP,
  costmap) with :func:`declare_params` (type hints, descriptors, range checks, the
  on-set callback) vs the same names and defaults by hand (``declare_parameter``).

Run: python bench/bench_plugins.py
"""

from __future__ import annotations

import dataclasses
import statistics
import time
from collections.abc import Callable

import numpy as np

from visnav.graph import Context, Node
from visnav.graph.param_dataclass import declare_params
from visnav.mapping.costmap_layers import CostmapParams
from visnav.msgs.image import numpy_to_image
from visnav.msgs.types import CompressedImage
from visnav.perception.image_transport import ImageTransportPublisher, compress
from visnav.planning.dwa import DWAParams
from visnav.planning.global_planner import GlobalPlannerParams
from visnav.planning.navigator import NavigatorParams
from visnav.planning.pure_pursuit import RPPParams

REPEATS = 21


def _paired(
    fn: Callable[[], object], ref: Callable[[], object], *, repeats: int = REPEATS, inner: int = 5
) -> tuple[float, float, float]:
    """Medians (ms) of ``fn`` and ``ref`` timed in alternation, and the median per-pair ratio.

    Alternating the two keeps the load of other processes on the machine in both.
    """
    fn()
    ref()
    a, b, ratios = [], [], []
    for _ in range(repeats):
        pair = []
        for f in (fn, ref):
            t0 = time.perf_counter()
            for _ in range(inner):
                f()
            pair.append((time.perf_counter() - t0) / inner * 1e3)
        a.append(pair[0])
        b.append(pair[1])
        ratios.append(pair[0] / pair[1])
    return statistics.median(a), statistics.median(b), statistics.median(ratios)


def bench_transport() -> tuple[float, float, float]:
    rng = np.random.default_rng(0)
    image = numpy_to_image(rng.integers(0, 255, (480, 640, 3), dtype=np.uint8), "rgb8")
    with Context(transport="local") as ctx:
        node = Node("pub", context=ctx)
        pub = ImageTransportPublisher(node, "cam/image_raw", transports=("compressed",))
        sink = Node("sink", context=ctx)
        sink.create_subscription(CompressedImage, "cam/image_raw/compressed", lambda m: None, 1)
        return _paired(
            lambda: pub.publish(image),
            lambda: compress(image, format="jpeg", jpeg_quality=80),
        )


_CLASSES = (NavigatorParams, GlobalPlannerParams, DWAParams, RPPParams, CostmapParams)


def bench_declaration() -> tuple[float, float, float, int]:
    fields = [(c, f.name, f.default) for c in _CLASSES for f in dataclasses.fields(c)]
    counter = iter(range(10**9))

    def with_dataclasses() -> None:
        with Context(transport="local") as c:
            node = Node(f"n{next(counter)}", context=c)
            for cls in _CLASSES:
                declare_params(node, cls, prefix=f"{cls.__name__}.")

    def by_hand() -> None:
        with Context(transport="local") as c:
            node = Node(f"n{next(counter)}", context=c)
            for cls, name, default in fields:
                value = default if default is not dataclasses.MISSING else []
                node.declare_parameter(f"{cls.__name__}.{name}", value)

    return (*_paired(with_dataclasses, by_hand, repeats=31, inner=3), len(fields))


def main() -> None:
    reg, direct, ratio = bench_transport()
    print(
        f"compressed publish via registry: {reg:.2f} ms, compress() direct: {direct:.2f} ms, "
        f"ratio {ratio:.3f}"
    )
    idiom, hand, ratio, count = bench_declaration()
    print(
        f"declaring {count} parameters (move_base's dataclasses): declare_params {idiom:.2f} ms, "
        f"declare_parameter by hand {hand:.2f} ms, ratio {ratio:.2f}"
    )


if __name__ == "__main__":
    main()
