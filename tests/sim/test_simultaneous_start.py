"""Two simulations started at the same moment in one graph domain: exactly one runs.

``refuse_second_simulation`` used to look for a ``/clock`` publisher only; two
simulations started together both found none (their clocks come after the world is
built) and both ran. Now each claims the domain and looks again; the claim of the
smaller Zenoh session id stays.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import pytest

from visnav.graph import Context, Node
from visnav.msgs.types import Clock
from visnav.sim.guards import CLAIM_TOPIC, SecondSimulationError, refuse_second_simulation

# a "simulation": the guard, then a /clock publisher held until the test has seen both
_SIM = """
import sys, time
from visnav.graph import Context, Node
from visnav.msgs.types import Clock
from visnav.sim.guards import SecondSimulationError, refuse_second_simulation
start = float(sys.argv[1])
time.sleep(max(0.0, start - time.time()))  # both processes leave their imports together
with Context() as ctx:
    try:
        refuse_second_simulation(ctx, command="visnav sim")
    except SecondSimulationError as exc:
        print("refused", exc, flush=True)
        sys.exit(3)
    Node("sim", context=ctx).create_publisher(Clock, "/clock", 1)
    print("running", flush=True)
    time.sleep(float(sys.argv[2]))
"""


def _pair(domain: int, hold_s: float) -> list[tuple[int, str]]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    start = time.time() + 3.0  # after both interpreters imported visnav
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", _SIM, str(start), str(hold_s)],
            env=env,
            stdout=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    out = []
    for p in procs:
        text, _ = p.communicate(timeout=60)
        out.append((p.returncode, text.strip()))
    return out


@pytest.mark.slow
def test_two_processes_started_together_leave_exactly_one_running(domain: int) -> None:
    for attempt in range(2):
        results = _pair(domain + attempt, hold_s=2.5)
        codes = sorted(code for code, _ in results)
        assert codes == [0, 3], results
        refused = next(text for code, text in results if code == 3)
        assert f"graph domain {domain + attempt}" in refused
        assert "VISNAV_DOMAIN=<number> visnav sim" in refused


def test_two_contexts_claiming_at_the_same_moment_leave_exactly_one(domain: int) -> None:
    """The same race between two sessions of one process (threads): one refusal."""
    results: dict[str, BaseException | None] = {}
    with Context(domain) as a, Context(domain) as b:
        start = threading.Barrier(2)

        def run(ctx: Context) -> None:
            start.wait()
            try:
                refuse_second_simulation(ctx)
                results[ctx.zid] = None
            except SecondSimulationError as exc:
                results[ctx.zid] = exc

        threads = [threading.Thread(target=run, args=(c,)) for c in (a, b)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        winners = [zid for zid, exc in results.items() if exc is None]
        assert len(winners) == 1, results
        (winner,) = winners
        (loser,) = (exc for exc in results.values() if exc is not None)
        assert isinstance(loser, SecondSimulationError)
        assert "started at the same moment" in str(loser) or "is starting" in str(loser)
        # the loser took its claim back: only the winner's claim stays in the graph
        deadline = time.monotonic() + 5.0
        while True:
            claims = [e for e in a.graph.endpoints(CLAIM_TOPIC) if e.kind == "publisher"]
            if [e.zid for e in claims] == [winner] or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        assert [e.zid for e in claims] == [winner]


@pytest.mark.slow
def test_a_claim_refuses_a_later_simulation_before_its_clock_exists(domain: int) -> None:
    """A simulation still building its world (claimed, no /clock yet) keeps the domain."""
    with Context(domain) as a, Context(domain) as b:
        refuse_second_simulation(a)
        with pytest.raises(SecondSimulationError, match="is starting"):
            refuse_second_simulation(b)
        # the /clock check still comes first, and own-process claims do not count
        Node("sim", context=a).create_publisher(Clock, "/clock", 1)
        with pytest.raises(SecondSimulationError, match="already publishes /clock"):
            refuse_second_simulation(a)
