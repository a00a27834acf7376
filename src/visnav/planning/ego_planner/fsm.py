"""ego-planner's replan state machine (``plan_manage/ego_replan_fsm.cpp``), graph-free.

States: ``INIT`` (waiting for odometry) -> ``WAIT_TARGET`` -> ``GEN_NEW_TRAJ`` (plan
from the odometry state) -> ``EXEC_TRAJ``; while executing, the plan is redone
(``REPLAN_TRAJ``, from the current trajectory's state) once the vehicle is
``thresh_replan`` from the trajectory's start, unless within ``thresh_no_replan``
of the goal; ``WAIT_TARGET`` again when the trajectory ends. :meth:`ReplanFSM.check_collision`
(20 Hz upstream) samples the rest of the trajectory (its first two thirds while
there) every 10 ms against the inflated map; on a hit it replans at once, and if
that fails it goes to ``EMERGENCY_STOP`` (hit within ``emergency_time``) or
``REPLAN_TRAJ``. ``EMERGENCY_STOP`` holds the odometry position until the
vehicle is slower than 0.1 m/s, then plans anew.

Local targets are taken on the global trajectory ``planning_horizon`` ahead of the
start; near the goal (within ``max_vel^2 / (2 max_acc)``) the target velocity is 0.

The machine is driven by explicit calls with the graph time, so tests can run it
without a graph: :meth:`ReplanFSM.set_odometry`, :meth:`ReplanFSM.set_goal`,
:meth:`ReplanFSM.set_waypoints`, :meth:`ReplanFSM.step` (100 Hz upstream) and
:meth:`ReplanFSM.check_collision`.
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from visnav.planning.errors import PlanningError

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from visnav.planning.ego_planner.manager import LocalTrajectory, PlannerManager

__all__ = ["FSMError", "FSMParams", "FSMState", "ReplanFSM", "TargetType"]

_LOG = logging.getLogger("visnav.planning.ego_planner")


class FSMError(PlanningError):
    """Invalid FSM parameters or goals."""


class FSMState(enum.IntEnum):
    """The execution states (ego-planner's ``FSM_EXEC_STATE``)."""

    INIT = 0
    WAIT_TARGET = 1
    GEN_NEW_TRAJ = 2
    REPLAN_TRAJ = 3
    EXEC_TRAJ = 4
    EMERGENCY_STOP = 5


class TargetType(enum.IntEnum):
    """Where goals come from (``fsm/flight_type``)."""

    MANUAL_TARGET = 1
    PRESET_TARGET = 2


@dataclass(frozen=True, kw_only=True)
class FSMParams:
    """ego-planner's ``fsm/...`` parameters.

    Upstream's ``fsm/planning_horizen_time`` is read there and never used, so it is not a
    parameter here (a launch file setting it gets the unknown-parameter warning).

    Attributes:
        flight_type: 1 goals arrive one by one, 2 the preset ``waypoints``.
        thresh_replan: Replan once this far from the trajectory's start (m).
        thresh_no_replan: Do not replan this near the goal (m).
        planning_horizon: Distance of the local target (m).
        emergency_time: A collision sooner than this stops the vehicle (s).
        waypoints: Preset waypoints ``((x, y, z), ...)`` for flight type 2.
        flight_height: Height given to goals that come without one (m); upstream 1.0.
    """

    flight_type: int = 1
    thresh_replan: float = 1.5
    thresh_no_replan: float = 2.0
    planning_horizon: float = 7.5
    emergency_time: float = 1.0
    waypoints: tuple[tuple[float, float, float], ...] = ()
    flight_height: float = 1.0

    def __post_init__(self) -> None:
        if self.flight_type not in (1, 2):
            msg = (
                f"fsm: flight_type is {self.flight_type!r}; "
                "expected 1 (goal topic) or 2 (waypoints)"
            )
            raise FSMError(msg)
        if self.flight_type == 2 and not self.waypoints:
            msg = "fsm: flight_type 2 needs waypoints; set fsm.waypoints to [x0, y0, z0, x1, ...]"
            raise FSMError(msg)
        if not self.planning_horizon > 0:
            msg = f"fsm: planning_horizon is {self.planning_horizon}; expected > 0 m"
            raise FSMError(msg)


class ReplanFSM:
    """The state machine around a :class:`~visnav.planning.ego_planner.manager.PlannerManager`.

    Args:
        manager: The planner.
        params: FSM parameters.
        on_trajectory: Called with each new local trajectory (to publish it).
        logger: Where state changes go (default the ``visnav.planning.ego_planner`` logger).
    """

    def __init__(
        self,
        manager: PlannerManager,
        params: FSMParams | None = None,
        *,
        on_trajectory: Callable[[LocalTrajectory], object] | None = None,
        logger: logging.Logger | None = None,
    ) -> None:
        self.manager = manager
        self.params = params or FSMParams()
        self.on_trajectory = on_trajectory
        self.log = logger or _LOG
        self.state = FSMState.INIT
        self.transitions: list[tuple[FSMState, FSMState, str]] = []
        self._repeat = 0
        self.have_odom = False
        self.have_target = False
        self.have_new_target = False
        self.odom_pos = np.zeros(3)
        self.odom_vel = np.zeros(3)
        self.start_pt = np.zeros(3)
        self.start_vel = np.zeros(3)
        self.start_acc = np.zeros(3)
        self.end_pt = np.zeros(3)
        self.local_target_pt = np.zeros(3)
        self.local_target_vel = np.zeros(3)
        self._escape_emergency = True
        self._preset_pending = self.params.flight_type == TargetType.PRESET_TARGET
        self.goals_reached = 0

    # ------------------------------------------------------------------ inputs
    def set_odometry(self, position: ArrayLike, velocity: ArrayLike, *, now_ns: int = 0) -> None:
        """Latest odometry (map frame). Preset waypoints are planned on the first one."""
        self.odom_pos = np.asarray(position, dtype=np.float64).reshape(3).copy()
        self.odom_vel = np.asarray(velocity, dtype=np.float64).reshape(3).copy()
        self.have_odom = True
        if self._preset_pending:
            self._preset_pending = False
            self.set_waypoints(self.params.waypoints, now_ns=now_ns)

    def set_goal(self, goal: ArrayLike, *, now_ns: int) -> bool:
        """A new goal (``waypointCallback``): x, y and optionally z (else ``flight_height``).

        Returns:
            Whether a global trajectory to it was planned.
        """
        g = np.asarray(goal, dtype=np.float64).reshape(-1)
        if g.shape[0] not in (2, 3) or not np.all(np.isfinite(g)):
            msg = f"goal is {g.tolist()}: expected finite x, y[, z]"
            raise FSMError(msg)
        end = np.array([g[0], g[1], g[2] if g.shape[0] == 3 else self.params.flight_height])
        return self._plan_global(end[None], now_ns)

    def set_waypoints(self, waypoints: ArrayLike, *, now_ns: int) -> bool:
        """Plan the global trajectory through ``(K, 3)`` waypoints (``planGlobalTrajbyGivenWps``).

        Returns:
            Whether a global trajectory was planned.
        """
        wps = np.asarray(waypoints, dtype=np.float64).reshape(-1, 3)
        return self._plan_global(wps, now_ns)

    def _plan_global(self, waypoints: NDArray[np.float64], now_ns: int) -> bool:
        if not self.have_odom:
            self.log.warning("ego_planner: a goal arrived before any odometry; ignored")
            return False
        self.end_pt = waypoints[-1].copy()
        zero = np.zeros(3)
        ok = self.manager.plan_global_trajectory(
            self.odom_pos, self.odom_vel, zero, waypoints, zero, zero, now_ns=now_ns
        )
        if not ok:
            self.log.error("ego_planner: unable to generate the global trajectory")
            return False
        self.have_target = True
        self.have_new_target = True
        if self.state in (FSMState.INIT, FSMState.WAIT_TARGET):
            self._change(FSMState.GEN_NEW_TRAJ, "TRIG")
        elif self.state == FSMState.EXEC_TRAJ:
            self._change(FSMState.REPLAN_TRAJ, "TRIG")
        return True

    # ------------------------------------------------------------------ machine
    def _change(self, new: FSMState, caller: str) -> None:
        self._repeat = self._repeat + 1 if new == self.state else 1
        if new != self.state:
            self.log.debug("ego_planner [%s]: from %s to %s", caller, self.state.name, new.name)
        self.transitions.append((self.state, new, caller))
        self.state = new

    def step(self, now_ns: int) -> None:
        """One run of the execution timer (``execFSMCallback``)."""
        m = self.manager
        if self.state == FSMState.INIT:
            if self.have_odom:
                self._change(FSMState.WAIT_TARGET, "FSM")
        elif self.state == FSMState.WAIT_TARGET:
            if self.have_target:
                self._change(FSMState.GEN_NEW_TRAJ, "FSM")
        elif self.state == FSMState.GEN_NEW_TRAJ:
            self.start_pt = self.odom_pos.copy()
            self.start_vel = self.odom_vel.copy()
            self.start_acc = np.zeros(3)
            random_poly = self._repeat > 1
            if self._call_replan(now_ns, poly_init=True, random_poly=random_poly):
                self._change(FSMState.EXEC_TRAJ, "FSM")
                self._escape_emergency = True
            else:
                self._change(FSMState.GEN_NEW_TRAJ, "FSM")
        elif self.state == FSMState.REPLAN_TRAJ:
            ok = self._plan_from_current(now_ns)
            self._change(FSMState.EXEC_TRAJ if ok else FSMState.REPLAN_TRAJ, "FSM")
        elif self.state == FSMState.EXEC_TRAJ:
            local = m.local
            if local is None:
                self._change(FSMState.GEN_NEW_TRAJ, "FSM")
                return
            t_cur = min(local.duration, local.elapsed(now_ns))
            pos = local.position.evaluate(t_cur)
            if t_cur > local.duration - 1e-2:
                self.have_target = False
                self.goals_reached += 1
                self._change(FSMState.WAIT_TARGET, "FSM")
            else:
                p = self.params
                near_end = float(np.linalg.norm(self.end_pt - pos)) < p.thresh_no_replan
                near_start = float(np.linalg.norm(local.start_pos - pos)) < p.thresh_replan
                if not (near_end or near_start):
                    self._change(FSMState.REPLAN_TRAJ, "FSM")
        elif self.state == FSMState.EMERGENCY_STOP:
            if self._escape_emergency:
                m.emergency_stop(self.odom_pos, now_ns=now_ns)
                self._publish()
            elif float(np.linalg.norm(self.odom_vel)) < 0.1:
                self._change(FSMState.GEN_NEW_TRAJ, "FSM")
            self._escape_emergency = False

    def check_collision(self, now_ns: int) -> None:
        """One run of the safety timer (``checkCollisionCallback``)."""
        local = self.manager.local
        if self.state == FSMState.WAIT_TARGET or local is None:
            return
        t_cur = local.elapsed(now_ns)
        t_end = local.duration
        if t_cur < local.duration * 2 / 3:
            t_end = local.duration * 2 / 3  # only the first two thirds are trusted
        times = np.arange(t_cur, t_end, 0.01)
        if times.size == 0:
            return
        hits = self.manager.grid_map.inflate_occupancy(local.position.evaluate(times))
        if not hits.any():
            return
        t_hit = float(times[int(np.argmax(hits))])
        if self._plan_from_current(now_ns):
            self._change(FSMState.EXEC_TRAJ, "SAFETY")
        elif t_hit - t_cur < self.params.emergency_time:
            self.log.warning(
                "ego_planner: obstacle %.2f s ahead and no new plan; emergency stop", t_hit - t_cur
            )
            self._change(FSMState.EMERGENCY_STOP, "SAFETY")
        else:
            self._change(FSMState.REPLAN_TRAJ, "SAFETY")

    def _plan_from_current(self, now_ns: int) -> bool:
        local = self.manager.local
        if local is None:
            return False
        t_cur = local.elapsed(now_ns)
        self.start_pt = local.position.evaluate(t_cur)
        self.start_vel = local.velocity.evaluate(t_cur)
        self.start_acc = local.acceleration.evaluate(t_cur)
        return (
            self._call_replan(now_ns, poly_init=False, random_poly=False)
            or self._call_replan(now_ns, poly_init=True, random_poly=False)
            or self._call_replan(now_ns, poly_init=True, random_poly=True)
        )

    def _call_replan(self, now_ns: int, *, poly_init: bool, random_poly: bool) -> bool:
        self._local_target()
        ok = self.manager.rebound_replan(
            self.start_pt,
            self.start_vel,
            self.start_acc,
            self.local_target_pt,
            self.local_target_vel,
            now_ns=now_ns,
            poly_init=self.have_new_target or poly_init,
            random_poly=random_poly,
        )
        self.have_new_target = False
        if ok:
            self._publish()
        return ok

    def _publish(self) -> None:
        if self.on_trajectory is not None and self.manager.local is not None:
            self.on_trajectory(self.manager.local)

    def _local_target(self) -> None:
        """Pick the local target on the global trajectory (``getLocalTarget``)."""
        g = self.manager.global_traj
        p = self.manager.params
        if g is None:
            self.local_target_pt = self.end_pt.copy()
            self.local_target_vel = np.zeros(3)
            return
        horizon = self.params.planning_horizon
        t_step = horizon / 20 / p.max_vel
        times = np.arange(g.last_progress_time, g.duration, t_step)
        reached_end = True
        t_target = g.duration
        if times.size:
            dist = np.linalg.norm(g.traj.evaluate(times) - self.start_pt, axis=1)
            far = np.nonzero(dist >= horizon)[0]
            if far.size and far[0] == 0:
                self.log.error("ego_planner: the global trajectory's progress point is too far")
                return
            if far.size:
                k = int(far[0])
                reached_end = False
                t_target = float(times[k])
                self.local_target_pt = g.traj.evaluate(t_target)
                g.last_progress_time = float(times[int(np.argmin(dist[: k + 1]))])
        if reached_end:
            self.local_target_pt = self.end_pt.copy()
        braking = p.max_vel * p.max_vel / (2 * p.max_acc)
        if float(np.linalg.norm(self.end_pt - self.local_target_pt)) < braking:
            self.local_target_vel = np.zeros(3)
        else:
            self.local_target_vel = g.traj.evaluate_vel(t_target)
