"""Guards around a MuJoCo run: spawn poses, instability, MuJoCo's log file, one sim per domain.

* :func:`check_spawn_pose` refuses a spawn pose that is not finite or lies outside
  the world (``--spawn 1e300 0 0 0`` used to run with NaN physics every step).
* :class:`InstabilityMonitor` turns MuJoCo's instability warnings (``Nan, Inf or
  huge value in QPOS/QVEL/QACC``, after which MuJoCo silently resets the state)
  into a :class:`SimulationUnstableError` that stops the run with the sim time and
  a fix. Gazebo keeps running in that case; visnav stops, because every sensor
  and odometry message after a reset is wrong.
* :func:`route_mujoco_warnings` sends MuJoCo's warnings to the ``visnav.sim.mujoco``
  logger instead of stdout and ``MUJOCO_LOG.TXT`` in the current directory.
* :func:`refuse_second_simulation` refuses to start a simulation in a graph domain
  where another one already publishes ``/clock`` or is starting: a claim on
  :data:`CLAIM_TOPIC` closes the check-then-act race of two simulations started at
  the same moment (the one with the larger Zenoh session id refuses).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import mujoco

from visnav.graph.introspect import wait_for_discovery
from visnav.graph.node import Node
from visnav.msgs.types import String
from visnav.sim.errors import SecondSimulationError, SimulationUnstableError, SpawnPoseError
from visnav.sim.world_geometry import shape_aabb

if TYPE_CHECKING:
    from visnav.description.worldmodel import WorldDescription
    from visnav.graph.context import Context
    from visnav.graph.graph_cache import EndpointInfo

__all__ = [
    "CLAIM_TOPIC",
    "InstabilityMonitor",
    "SecondSimulationError",
    "SimulationUnstableError",
    "SpawnPoseError",
    "check_spawn_pose",
    "refuse_second_simulation",
    "route_mujoco_warnings",
    "world_bounds",
]

CLAIM_TOPIC = "/_visnav/simulation_claim"
"""A hidden topic (never published on): each simulation that passed the /clock check
keeps a publisher on it for as long as it runs, its claim on the graph domain."""

_MUJOCO_LOG = logging.getLogger("visnav.sim.mujoco")
_MARGIN_M = 10.0  # a spawn may lie this far outside the obstacles of a world without ground
_MAX_HEIGHT_M = 10_000.0
_UNSTABLE = (
    (mujoco.mjtWarning.mjWARN_BADQPOS, "position (QPOS)"),
    (mujoco.mjtWarning.mjWARN_BADQVEL, "velocity (QVEL)"),
    (mujoco.mjtWarning.mjWARN_BADQACC, "acceleration (QACC)"),
)


def world_bounds(world: WorldDescription) -> tuple[float, float, float, float]:
    """The x-y box a robot may be spawned in: the ground, else the obstacles plus a margin.

    Returns:
        ``(x_min, y_min, x_max, y_max)`` in metres.
    """
    if world.ground is not None:
        sx, sy = world.ground.size
        return (-0.5 * sx, -0.5 * sy, 0.5 * sx, 0.5 * sy)
    shapes = world.collision_shapes
    if not shapes:
        return (-1000.0, -1000.0, 1000.0, 1000.0)
    boxes = [shape_aabb(s) for s in shapes]
    lo = [min(float(b[0][i]) for b in boxes) - _MARGIN_M for i in range(2)]
    hi = [max(float(b[1][i]) for b in boxes) + _MARGIN_M for i in range(2)]
    return (lo[0], lo[1], hi[0], hi[1])


def check_spawn_pose(
    pose: Sequence[float], world: WorldDescription, *, robot: str = "robot"
) -> tuple[float, float, float, float]:
    """Refuse a spawn pose ``(x, y, z, yaw)`` that is not finite or lies outside the world.

    Args:
        pose: ``(x, y, z, yaw)`` in metres and radians.
        world: the world the robot is spawned in.
        robot: the robot's name, for the message.

    Returns:
        The pose as four floats.

    Raises:
        SpawnPoseError: not four numbers, a NaN or infinite value, x/y outside the
            world's ground (or obstacles), z below the ground or above 10 km.
    """
    if len(pose) != 4:
        msg = f"robot {robot!r}: spawn is {list(pose)}: expected x y z yaw (4 numbers)"
        raise SpawnPoseError(msg)
    x, y, z, yaw = (float(v) for v in pose)
    if not all(math.isfinite(v) for v in (x, y, z, yaw)):
        msg = (
            f"robot {robot!r}: spawn x y z yaw = {x:g} {y:g} {z:g} {yaw:g} is not finite; "
            "fix: give four finite numbers (m, m, m, rad)"
        )
        raise SpawnPoseError(msg)
    x0, y0, x1, y1 = world_bounds(world)
    ground = world.ground.z if world.ground is not None else -math.inf
    outside = not (x0 <= x <= x1 and y0 <= y <= y1)
    if outside or not (ground - 1.0 <= z <= max(ground, 0.0) + _MAX_HEIGHT_M):
        floor = f", z from {ground - 1.0:g} to {max(ground, 0.0) + _MAX_HEIGHT_M:g}"
        msg = (
            f"robot {robot!r}: spawn x y z = {x:g} {y:g} {z:g} lies outside world "
            f"{world.name!r} (x from {x0:g} to {x1:g}, y from {y0:g} to {y1:g}"
            f"{floor if world.ground is not None else ''}); fix: spawn inside the world"
        )
        raise SpawnPoseError(msg)
    return (x, y, z, yaw)


class InstabilityMonitor:
    """Watches MuJoCo's instability warnings of one ``MjData``.

    MuJoCo counts each warning kind in ``data.warning``; when the state holds NaN,
    Inf or huge values it resets the state and raises the count. :meth:`check`
    compares the counts with the last call (about 0.3 us per step).

    Args:
        data: the simulation's data.
    """

    def __init__(self, data: mujoco.MjData) -> None:
        self._data = data
        kinds = [int(kind) for kind, _ in _UNSTABLE]
        if kinds != list(range(kinds[0], kinds[0] + len(kinds))):  # pragma: no cover
            msg = "MuJoCo's warning kinds QPOS, QVEL, QACC are no longer adjacent"
            raise RuntimeError(msg)
        # a live view on MuJoCo's counters: reading it costs well under a microsecond
        self._counts = data.warning.number[kinds[0] : kinds[0] + len(kinds)]
        self._seen: list[int] = self._counts.tolist()

    def check(self, now_ns: int) -> None:
        """Raise if MuJoCo reported an unstable state since the last call.

        Args:
            now_ns: the sim time of the step just taken (for the message).

        Raises:
            SimulationUnstableError: naming the quantity, the degree of freedom and
                the sim time, with the usual causes as the fix.
        """
        counts: list[int] = self._counts.tolist()
        if counts == self._seen:
            return
        changed = next(k for k, (a, b) in enumerate(zip(counts, self._seen, strict=True)) if a != b)
        self._seen = counts
        kind, what = _UNSTABLE[changed]
        dof = int(self._data.warning[int(kind)].lastinfo)
        msg = (
            f"MuJoCo found NaN, Inf or a huge value in the {what} of degree of "
            f"freedom {dof} at sim time {now_ns * 1e-9:.3f} s: the simulation is "
            "unstable and was stopped; fix: check the spawn pose, the masses and "
            "inertias of the robot, and the world's timestep"
        )
        raise SimulationUnstableError(msg)


def _log_mujoco_warning(text: str) -> None:
    _MUJOCO_LOG.warning("MuJoCo: %s", text.strip())


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to the ``visnav.sim.mujoco`` logger (no MUJOCO_LOG.TXT).

    MuJoCo's default warning handler prints and appends to ``MUJOCO_LOG.TXT`` in the
    current directory. The handler is process-wide in MuJoCo, so it is installed
    only when none is set (a handler the embedding program set is kept); calling
    this again changes nothing.
    """
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_log_mujoco_warning)


def refuse_second_simulation(
    ctx: Context, *, command: str = "visnav sim", owner: Node | None = None
) -> None:
    """Refuse to start when another simulation publishes ``/clock`` in ``ctx``'s domain.

    Two simulations in one domain mix their clocks, TF and commands. Looking for a
    ``/clock`` publisher alone is check-then-act: two simulations started at the same
    moment both find none (their clocks come seconds later, after the world is built)
    and both run. So a simulation that finds no ``/clock`` publisher and no claim of
    another process then claims the domain (a publisher on :data:`CLAIM_TOPIC`),
    waits for discovery again and looks once more: of the claims made at the same
    moment, the one of the smallest Zenoh session id stays and the others refuse.
    Both sides see the same claims, so exactly one runs. ROS has no such guard
    (two Gazebos in one ``ROS_DOMAIN_ID`` mix their clocks silently).

    Args:
        ctx: the graph context the new simulation would join.
        command: the command to show in the fix.
        owner: the node the claim belongs to (it goes when the node is destroyed);
            None puts it on a hidden node ``_visnav_simulation_claim`` of ``ctx``.

    Raises:
        SecondSimulationError: naming the domain, the other node and the fix.
    """
    own = ctx.zid
    if ctx.zenoh is not None:
        wait_for_discovery(ctx, timeout_s=1.0)
    clocks = [e for e in ctx.graph.endpoints("/clock") if e.kind == "publisher"]
    claims = [e for e in _claims(ctx) if e.zid != own]
    if clocks or claims:
        other = (clocks or claims)[0]
        what = "already publishes /clock" if clocks else "is starting"
        msg = (
            f"another simulation {what} in graph domain {ctx.domain!r} (node "
            f"{other.node_fqn}): two simulations in one domain mix their clocks, TF and "
            "commands; stop it, or run this one in a domain of its own "
            f"(VISNAV_DOMAIN=<number> {command} ...)"
        )
        raise SecondSimulationError(msg)
    if ctx.zenoh is None:  # an in-process graph: nothing else can start at the same moment
        return
    node = owner if owner is not None else Node("_visnav_simulation_claim", context=ctx)
    pub = node.create_publisher(String, CLAIM_TOPIC, 1)
    wait_for_discovery(ctx, timeout_s=2.0)
    rivals = sorted((e for e in _claims(ctx) if e.zid < own), key=lambda e: e.zid)
    if not rivals:
        return
    if owner is None:
        node.destroy_node()
    else:
        node.destroy_publisher(pub)
    msg = (
        f"another simulation started at the same moment in graph domain {ctx.domain!r} "
        f"(node {rivals[0].node_fqn}) and keeps the domain: two simulations in one domain "
        "mix their clocks, TF and commands; run this one in a domain of its own "
        f"(VISNAV_DOMAIN=<number> {command} ...)"
    )
    raise SecondSimulationError(msg)


def _claims(ctx: Context) -> list[EndpointInfo]:
    return [e for e in ctx.graph.endpoints(CLAIM_TOPIC) if e.kind == "publisher"]
