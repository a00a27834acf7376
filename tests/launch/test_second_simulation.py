"""A launch's ``sim`` node refuses a graph domain that already has a ``/clock`` publisher.

Issue 13: two bare ``visnav launch`` runs with a ``sim`` node in one ``VISNAV_DOMAIN``
cross-talked (clock jumps, a foreign ``/map``); ``visnav sim`` and ``visnav run`` already
refused a second simulation, now the node itself does, wherever it runs.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from visnav.graph import Context, Node
from visnav.msgs import Clock
from visnav.sim.errors import SecondSimulationError
from visnav.sim.sim_node import SimulatorNode

_SIM = "launch:\n  - node: {{exec: sim, {process}params: {{world: office, robot: car{extra}}}}}\n"


def test_a_sim_node_refuses_a_domain_that_has_a_clock(domain: int) -> None:
    with Context(domain) as ctx:
        other = Node("player", context=ctx)
        other.create_publisher(Clock, "/clock", 1)
        with pytest.raises(SecondSimulationError) as info:
            SimulatorNode("sim", context=ctx)
        # the refused node left nothing behind: only the first /clock publisher remains
        assert other.count_publishers("/clock") == 1
        assert [n.get_name() for n in ctx.nodes] == ["player"]
    text = str(info.value)
    assert f"graph domain {domain}" in text
    assert "node /player" in text
    assert "VISNAV_DOMAIN=<number> visnav launch" in text


def _launch(path: Path, domain: int, **kwargs: object) -> subprocess.Popen[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    cmd = [sys.executable, "-m", "visnav.cli.main", "launch", str(path)]
    return subprocess.Popen(cmd, env=env, text=True, **kwargs)  # type: ignore[call-overload,no-any-return]


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.parametrize("process", ["shared", "own"])
def test_a_second_bare_launch_with_a_sim_is_refused(
    domain: int, tmp_path: Path, process: str
) -> None:
    first_file = tmp_path / "first.yaml"
    first_file.write_text(_SIM.format(process="", extra=", duration: 600.0"))
    second_file = tmp_path / "second.yaml"
    own = "process: own, " if process == "own" else ""
    second_file.write_text(_SIM.format(process=own, extra=", duration: 5.0"))
    first = _launch(first_file, domain, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with Context(domain) as ctx:
            probe = Node("probe", context=ctx)
            stamps: list[int] = []
            probe.create_subscription(
                Clock, "/clock", lambda m: stamps.append(m.clock.sec * 10**9 + m.clock.nanosec), 100
            )
            assert ctx.spin_until(lambda: len(stamps) > 10, 120.0), "the first launch never ticked"
            second = _launch(second_file, domain, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
            out, err = second.communicate(timeout=120)
            assert second.returncode == 1, (out, err)
            errors = [line for line in err.splitlines() if line.startswith("error: ")]
            assert len(errors) == 1, err
            line = errors[0]
            assert "second.yaml:2" in line
            assert f"graph domain {domain}" in line
            assert "VISNAV_DOMAIN=<number> visnav launch" in line
            assert "Traceback" not in err
            # the first simulation is untouched: its clock still runs forwards only
            stamps.clear()
            assert ctx.spin_until(lambda: len(stamps) > 10, 30.0)
            assert stamps == sorted(stamps)
            assert probe.count_publishers("/clock") == 1
            assert first.poll() is None
    finally:
        first.send_signal(signal.SIGINT)
        try:
            first.wait(30)
        except subprocess.TimeoutExpired:
            first.kill()
            first.wait(10)
