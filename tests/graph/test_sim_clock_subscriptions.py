"""A ``use_sim_time`` node keeps following ``/clock`` when ``/clock`` has more subscriptions.

Seen in session 4 (unverified): "a node with a second /clock subscription stopped its sim
clock". The node's own ``/clock`` subscription (``use_sim_time``) must be independent of any
other subscription to ``/clock`` on the same node or on another node of the process, whatever
its QoS or kind (plain, best effort, raw, paced), whether it is made before or after sim time
is switched on, and after it is destroyed again. The ``/clock`` publisher is another node of the
same context (in-process delivery) or a real second process (Zenoh).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from visnav.graph import Context, Node, QoSProfile, ReliabilityPolicy
from visnav.graph.parameters import Parameter
from visnav.msgs import Clock, ns_to_time

SCRIPTS = Path(__file__).parent / "scripts"
SIM0_NS = 1_000_000_000_000  # clock_pub.py and the local publisher start at 1000 s
STEP_NS = 10_000_000
_KINDS: dict[str, dict[str, Any]] = {
    "reliable": {"qos": 10},
    "best_effort": {"qos": QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)},
    "raw": {"qos": 10, "raw": True},
    "paced": {"qos": 1, "paced": True},
}


def _local_clock(ctx: Context) -> None:
    """A /clock publisher node in ``ctx`` (wall-clock timer, 10 ms of sim time per tick)."""
    node = Node("clock_pub", context=ctx)
    pub = node.create_publisher(Clock, "/clock", QoSProfile(depth=1))
    tick = [0]

    def step() -> None:
        tick[0] += 1
        pub.publish(Clock(clock=ns_to_time(SIM0_NS + tick[0] * STEP_NS)))

    node.create_timer(0.005, step)


def _assert_follows(ctx: Context, node: Node, what: str) -> None:
    """The node's clock is sim time and advances by at least 20 /clock ticks."""
    clock = node.get_clock()
    assert ctx.spin_until(lambda: clock.now_ns() > SIM0_NS, 30.0), f"{what}: no sim time"
    start = clock.now_ns()
    advanced = ctx.spin_until(lambda: clock.now_ns() >= start + 20 * STEP_NS, 30.0)
    assert advanced, f"{what}: the sim clock stopped at {start} ns"
    assert clock.ros_time_is_active


def _check(ctx: Context, kind: str, where: str, order: str) -> None:
    what = f"{kind} /clock subscription on {where} node, made {order} use_sim_time"
    node = Node("user", context=ctx, use_sim_time=order == "after")
    owner = node if where == "the same" else Node("other", context=ctx)
    got: list[Any] = []
    if order == "before":
        spec = dict(_KINDS[kind])
        qos = spec.pop("qos")
        sub = owner.create_subscription(Clock, "/clock", got.append, qos, **spec)
        node.set_parameters([Parameter("use_sim_time", value=True)])
    else:
        _assert_follows(ctx, node, "use_sim_time alone")
        spec = dict(_KINDS[kind])
        qos = spec.pop("qos")
        sub = owner.create_subscription(Clock, "/clock", got.append, qos, **spec)
    _assert_follows(ctx, node, what)
    assert ctx.spin_until(lambda: len(got) > 3, 30.0), f"{what}: it got nothing itself"
    owner.destroy_subscription(sub)
    _assert_follows(ctx, node, f"{what}, then destroyed")
    node.set_parameters([Parameter("use_sim_time", value=False)])
    assert not node.get_clock().ros_time_is_active
    node.set_parameters([Parameter("use_sim_time", value=True)])
    _assert_follows(ctx, node, f"{what}, sim time off and on again")
    if owner is not node:
        owner.destroy_node()
        _assert_follows(ctx, node, f"{what}, that node destroyed")
    node.destroy_node()


@pytest.mark.parametrize("order", ["after", "before"])
@pytest.mark.parametrize("where", ["the same", "another"])
@pytest.mark.parametrize("kind", list(_KINDS))
def test_in_process_clock(kind: str, where: str, order: str) -> None:
    with Context(transport="local") as ctx:
        _local_clock(ctx)
        _check(ctx, kind, where, order)


def test_clock_from_another_process(start_script: Any) -> None:
    """The commonest cases against a real /clock process (Zenoh)."""
    start_script(SCRIPTS / "clock_pub.py", "60")
    with Context() as ctx:
        _check(ctx, "reliable", "the same", "after")
        _check(ctx, "paced", "another", "before")


@pytest.mark.slow
@pytest.mark.ci
def test_clock_from_another_process_every_case(start_script: Any) -> None:
    """Every combination against one real /clock process (Zenoh), one context."""
    start_script(SCRIPTS / "clock_pub.py", "120")
    with Context() as ctx:
        for kind in _KINDS:
            for where in ("the same", "another"):
                for order in ("after", "before"):
                    _check(ctx, kind, where, order)
