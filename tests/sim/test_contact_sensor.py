"""The bumper (``bumper_states``): robot-vs-world contacts, checked against a plain loop."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import mujoco
import pytest

from visnav.graph import Context, Node
from visnav.sim.contact_sensor import ContactSensor, geom_label
from visnav.sim.simulator import Simulator

from .test_simulator import car, small_world


@pytest.fixture
def ctx(mujoco_gl: str) -> Iterator[Context]:
    del mujoco_gl
    with Context(transport="local") as context:
        yield context


def reference(model: mujoco.MjModel, data: mujoco.MjData, root: int) -> list[dict[str, Any]]:
    """The contacts as the module docstring defines them, one contact at a time."""
    robot = {b for b in range(model.nbody) if int(model.body_rootid[b]) == root}
    out = []
    for c in data.contact[: data.ncon]:
        g1, g2 = int(c.geom1), int(c.geom2)
        in1, in2 = int(model.geom_bodyid[g1]) in robot, int(model.geom_bodyid[g2]) in robot
        if in1 == in2:
            continue
        own, other = (g1, g2) if in1 else (g2, g1)
        shape = mujoco.mjtGeom(int(model.geom_type[other])).name.removeprefix("mjGEOM_").lower()
        out.append(
            {
                "name": geom_label(model, own),
                "hardware_id": geom_label(model, other),
                "message": shape,
                "values": {
                    "x": f"{float(c.pos[0]):.6g}",
                    "y": f"{float(c.pos[1]):.6g}",
                    "z": f"{float(c.pos[2]):.6g}",
                    "depth": f"{-float(c.dist):.6g}",
                },
            }
        )
    return out


def test_contacts_match_the_reference(ctx: Context) -> None:
    with Simulator(small_world(), [car()], context=ctx, contact_rate=100.0) as sim:
        sensor = next(p for p in sim.robot().plugins if isinstance(p, ContactSensor))
        got: list[Any] = []
        node = Node("listener", context=ctx)
        node.create_subscription(sensor._array, "/bumper_states", got.append, 100)
        root = sim.model.body(sim.robot().handles.root_body).id
        expected: list[list[dict[str, Any]]] = []
        real_sense = sensor.sense

        def sense(data: mujoco.MjData, now_ns: int) -> None:
            if sensor._clock.next_ns <= now_ns:
                expected.append(reference(sim.model, data, root))
            real_sense(data, now_ns)

        sensor.sense = sense  # type: ignore[method-assign]
        sim._sense = [sense if f == real_sense else f for f in sim._sense]
        sim.run(0.3)
        assert len(got) == len(expected) >= 25
        wheels_on_floor = 0
        for msg, want in zip(got, expected, strict=True):
            have = [
                {
                    "name": s.name,
                    "hardware_id": s.hardware_id,
                    "message": s.message,
                    "values": {kv.key: kv.value for kv in s.values},
                }
                for s in msg.status
            ]
            assert have == want
            assert msg.header.frame_id == "world"
            wheels_on_floor += sum(s.message == "plane" for s in msg.status)
        assert wheels_on_floor > 0  # the car stands on the floor: the test sees contacts
