"""Cost of ``Publisher.publish`` with no subscriber anywhere (session 8, helper pubwait).

Run: ``python bench/bench_publish_unmatched.py [--rounds N]``.

Since session 8 :meth:`visnav.graph.transport.ZenohPublisher.wants_sample` asks Zenoh's
current matching status when its matching listener says "no subscriber" (the listener can
lag the graph's liveliness token by tens of ms, and a sample published on seeing the
subscription was lost). This measures what that costs a publisher nobody listens to: the
``publish()`` of a ``std_msgs/String`` with the current ``wants_sample`` against the one
before session 8 (cached flag only, the reference), alternated in one process, ``--rounds``
rounds of best-of-5 timeit runs of 20,000 publishes; medians over the rounds.
"""

from __future__ import annotations

import argparse
import os
import statistics
import timeit
from collections.abc import Callable
from typing import Any

from visnav.graph import Context, Node
from visnav.graph.transport import ZenohPublisher
from visnav.msgs import String

N = 20_000


def _cached_flag_only(self: Any) -> bool:
    """``wants_sample`` as it was before session 8 (the reference)."""
    if self._cache is not None:
        return True
    if not self._matching:
        return False
    pace = self._pace
    return pace is None or not pace.all_paused()


def bench(rounds: int) -> dict[str, list[float]]:
    """Per-publish ns of each variant, one best-of-5 figure per round."""
    current: Callable[[Any], bool] = ZenohPublisher.wants_sample
    variants: dict[str, Callable[[Any], bool]] = {
        "before (cached flag)": _cached_flag_only,
        "now (asks Zenoh)": current,
    }
    out: dict[str, list[float]] = {name: [] for name in variants}
    domain = 3_000_000 + os.getpid() % 100_000
    try:
        with Context(domain) as ctx:
            pub = Node("bench_unmatched", context=ctx).create_publisher(String, "/nobody", 10)
            msg = String(data="x")
            for _ in range(rounds):
                for name, fn in variants.items():
                    ZenohPublisher.wants_sample = fn  # type: ignore[method-assign,assignment]
                    best = min(timeit.repeat(lambda: pub.publish(msg), number=N, repeat=5))
                    out[name].append(best / N * 1e9)
    finally:
        ZenohPublisher.wants_sample = current  # type: ignore[method-assign,assignment]
    return out


def main() -> None:
    """Print the medians and the ratio to the reference."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    results = bench(args.rounds)
    medians = {name: statistics.median(v) for name, v in results.items()}
    for name, values in results.items():
        runs = ", ".join(f"{v:.0f}" for v in values)
        print(f"publish() with no subscriber, {name}: median {medians[name]:.0f} ns ({runs})")
    before, now = medians.values()
    print(f"ratio now / before: {now / before:.2f} (+{now - before:.0f} ns per publish)")


if __name__ == "__main__":
    main()
