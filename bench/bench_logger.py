"""Benchmark: the node logger's rclpy filters vs the hand-written warn-once sets they replace.

Rows (per call, the path taken on every message after the first):

* ``once=True`` suppressed vs the replaced idiom ``if text not in reported: reported.add(...)``
  with a message formatted per call (the idiom keyed on the text, so it had to build it);
* ``throttle_duration_sec=5`` suppressed vs the same idiom;
* a plain call at a disabled level vs :mod:`logging`'s own disabled ``Logger.debug``;
* a plain enabled call (to a ``NullHandler``) vs :mod:`logging`'s own enabled call.

Times are thread CPU time per batch of calls (medians of ``ROUNDS`` x ``BATCHES``), each row
measured right after its reference so both see the same machine load.

Run: python bench/bench_logger.py
"""

from __future__ import annotations

import logging
import statistics
import time
from collections.abc import Callable

from visnav.graph.logger import NodeLogger

BATCH = 1000
BATCHES = 50
ROUNDS = 5


def _per_call_ns(fn: Callable[[], None]) -> float:
    samples = []
    for _ in range(BATCHES):
        t0 = time.thread_time_ns()
        for _ in range(BATCH):
            fn()
        samples.append((time.thread_time_ns() - t0) / BATCH)
    return statistics.median(samples)


def _row(name: str, visnav: Callable[[], None], reference: Callable[[], None]) -> None:
    ours, ref = [], []
    for _ in range(ROUNDS):
        ours.append(_per_call_ns(visnav))
        ref.append(_per_call_ns(reference))
    a, b = statistics.median(ours), statistics.median(ref)
    print(f"| {name} | {a / 1000:.2f} | {b / 1000:.2f} | {a / b:.2f} |")


def main() -> None:
    """Print the table."""
    base = logging.getLogger("visnav.node")
    base.handlers[:] = [logging.NullHandler()]
    base.propagate = False
    base.setLevel(logging.INFO)
    log = NodeLogger("/bench/node")
    stdlib = logging.getLogger("visnav.node.bench.node")
    reported: set[str] = set()
    frame = "camera_optical"

    def hand_written() -> None:
        text = f"dropped a scan: no transform from '{frame}' to 'map'"
        if text not in reported:
            reported.add(text)
            stdlib.warning(text)

    def once() -> None:
        log.warning(f"dropped a scan: no transform from '{frame}' to 'map'", once=True)

    def throttled() -> None:
        log.warning(
            f"dropped a scan: no transform from '{frame}' to 'map'", throttle_duration_sec=5.0
        )

    print("| call | visnav µs | reference µs | ratio |")
    print("|---|---|---|---|")
    _row("`warning(..., once=True)`, suppressed vs warn-once set", once, hand_written)
    _row("`warning(..., throttle_duration_sec=5)`, suppressed vs set", throttled, hand_written)
    _row(
        "`debug(...)` at level INFO vs `logging` debug",
        lambda: log.debug("x"),
        lambda: stdlib.debug("x"),
    )
    _row(
        "`info(...)` to a NullHandler vs `logging` info",
        lambda: log.info("x"),
        lambda: stdlib.info("x"),
    )


if __name__ == "__main__":
    main()
