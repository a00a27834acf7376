"""The navigator: move_base's state machine, graph-free.

One :meth:`Navigator.step` per control cycle (``controller_frequency``) takes the robot
pose in the global and local frames and its velocity, and returns the velocity
command. Goals come from :meth:`Navigator.go_to` and end SUCCEEDED, ABORTED (with a
reason), PREEMPTED (a newer goal) or are REJECTED (a malformed goal); the handle's
``status``, ``text`` and ``error`` carry the outcome.

States, as move_base's ``executeCycle``:

* **PLANNING**: plan every cycle until a plan is found (-> CONTROLLING) or
  ``planner_patience`` (5 s) passes (-> CLEARING); a goal outside the global costmap is
  aborted at once (planning would always fail); a goal in an obstacle gets one costmap
  clearing, then is aborted;
* **CONTROLLING**: replan every ``1 / planner_frequency`` s (a failed replan keeps the
  old plan), ask the local planner for a command; with none, go back to PLANNING, and
  after ``controller_patience`` (15 s) without a valid command to CLEARING; the goal
  succeeds when the local planner says it is reached;
* **CLEARING**: run the next recovery behaviour, then plan again; when none is left,
  abort with the reason of the last failure;
* oscillation: when the robot has not moved ``oscillation_distance`` (0.5 m) for
  ``oscillation_timeout`` seconds while controlling, go to CLEARING;
* data: while a costmap is not current (a stale or empty scan, no map yet), the robot
  is stopped, the handle's text says why (logged once) and patience timers pause.

Differences: ``planner_frequency`` defaults to 1 Hz (nav2's replanning rate; move_base's
0 plans only on failure, which cannot follow a map being built) and
``oscillation_timeout`` to 10 s with 0.5 m (nav2's progress checker; move_base disables
it); a back-up behaviour runs before the last rotation; planning runs inside the
control cycle (move_base uses a planner thread), which keeps runs deterministic.
"""

from __future__ import annotations

import enum
import itertools
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from visnav.mapping.layered_costmap import LayeredCostmap
from visnav.planning.errors import PlanningError
from visnav.planning.global_planner import GlobalPlanner, PlanStatus
from visnav.planning.local_planner import (
    ControlResult,
    LocalPlanner,
    Pose2D,
    compose_2d,
    invert_2d,
)
from visnav.planning.recovery import (
    BackUpRecovery,
    ClearCostmapRecovery,
    Recovery,
    RecoveryContext,
    RotateRecovery,
)

__all__ = [
    "STARTUP_GRACE_S",
    "GoalHandle",
    "GoalStatus",
    "NavError",
    "NavState",
    "Navigator",
    "NavigatorParams",
    "default_recoveries",
]

_NS = 1_000_000_000
STARTUP_GRACE_S = 10.0
"""Seconds after the first control cycle during which a costmap that has never been current
(no map yet, sensors warming up) is expected: the stop is logged at debug level, and as a
warning only if it lasts past the grace period. Later stops are warnings at once."""


class GoalStatus(enum.IntEnum):
    """actionlib_msgs/GoalStatus codes."""

    PENDING = 0
    ACTIVE = 1
    PREEMPTED = 2
    SUCCEEDED = 3
    ABORTED = 4
    REJECTED = 5


class NavError(enum.Enum):
    """Why a goal did not succeed."""

    NONE = "none"
    INVALID_GOAL = "invalid_goal"
    NO_TRANSFORM = "no_transform"
    GOAL_OUTSIDE_MAP = "goal_outside_map"
    START_OUTSIDE_MAP = "start_outside_map"
    GOAL_IN_OBSTACLE = "goal_in_obstacle"
    NO_PATH = "no_path"
    CONTROL_FAILED = "control_failed"
    OSCILLATING = "oscillating"
    CANCELED = "canceled"
    PREEMPTED = "preempted"


class NavState(enum.Enum):
    """move_base's internal state."""

    IDLE = "idle"
    PLANNING = "planning"
    CONTROLLING = "controlling"
    CLEARING = "clearing"


class _Trigger(enum.Enum):
    NONE = "none"
    PLANNING = "planning"
    CONTROLLING = "controlling"
    OSCILLATION = "oscillation"


_TERMINAL = (GoalStatus.PREEMPTED, GoalStatus.SUCCEEDED, GoalStatus.ABORTED, GoalStatus.REJECTED)


@dataclass
class GoalHandle:
    """A navigation goal and its outcome.

    Attributes:
        goal_id: increasing id.
        goal: ``(x, y, yaw)`` in the global frame.
        frame_id: the global frame.
        status: current status.
        text: the latest status text (the reason when it failed or is stopped).
        error: the failure category.
        accepted_ns: when the goal was accepted.
        finished_ns: when it ended (0 while running).
        plans: number of plans computed.
        recoveries: recovery behaviours run.
    """

    goal_id: int
    goal: Pose2D
    frame_id: str
    status: GoalStatus = GoalStatus.PENDING
    text: str = ""
    error: NavError = NavError.NONE
    accepted_ns: int = 0
    finished_ns: int = 0
    plans: int = 0
    recoveries: list[str] = field(default_factory=list)

    @property
    def done(self) -> bool:
        """True once the goal reached a terminal status."""
        return self.status in _TERMINAL

    @property
    def succeeded(self) -> bool:
        """True when the goal was reached."""
        return self.status is GoalStatus.SUCCEEDED


@dataclass(frozen=True)
class NavigatorParams:
    """move_base parameters (see the module docs for the two changed defaults)."""

    planner_frequency: float = 1.0
    controller_frequency: float = 20.0
    planner_patience: float = 5.0
    controller_patience: float = 15.0
    max_planning_retries: int = -1
    oscillation_timeout: float = 10.0
    oscillation_distance: float = 0.5
    recovery_behavior_enabled: bool = True
    clearing_rotation_allowed: bool = True
    conservative_reset_dist: float = 3.0

    def __post_init__(self) -> None:
        if not (self.controller_frequency > 0 and math.isfinite(self.controller_frequency)):
            msg = f"controller_frequency is {self.controller_frequency}; expected Hz > 0"
            raise PlanningError(msg)
        if self.planner_frequency < 0:
            msg = f"planner_frequency is {self.planner_frequency}; expected Hz >= 0 (0 = on demand)"
            raise PlanningError(msg)


def default_recoveries(params: NavigatorParams, circumscribed_radius: float) -> list[Recovery]:
    """move_base's default behaviours, plus a back-up before the last rotation."""
    out: list[Recovery] = [
        ClearCostmapRecovery("conservative_reset", reset_distance=params.conservative_reset_dist)
    ]
    if params.clearing_rotation_allowed:
        out.append(RotateRecovery("rotate_recovery"))
    out.append(ClearCostmapRecovery("aggressive_reset", reset_distance=4.0 * circumscribed_radius))
    out.append(BackUpRecovery("back_up"))
    if params.clearing_rotation_allowed:
        out.append(RotateRecovery("rotate_recovery_2"))
    return out


class Navigator:
    """move_base without the graph.

    Args:
        global_costmap: the costmap plans are made on (global frame).
        local_costmap: the costmap the local planner uses (local frame).
        planner: the global planner.
        controller: the local planner.
        params: navigator parameters.
        recoveries: recovery behaviours in order (default :func:`default_recoveries`).
        log: ``log(level, text)`` with level ``"info"``, ``"warning"`` or ``"error"``.
    """

    def __init__(
        self,
        global_costmap: LayeredCostmap,
        local_costmap: LayeredCostmap,
        planner: GlobalPlanner,
        controller: LocalPlanner,
        params: NavigatorParams | None = None,
        *,
        recoveries: Sequence[Recovery] | None = None,
        log: Callable[[str, str], None] | None = None,
    ) -> None:
        self.global_costmap = global_costmap
        self.local_costmap = local_costmap
        self.planner = planner
        self.controller = controller
        self.params = params or NavigatorParams()
        self.recoveries = (
            list(recoveries)
            if recoveries is not None
            else default_recoveries(self.params, local_costmap.footprint.circumscribed_radius)
        )
        self._log = log or (lambda _level, _text: None)
        self._ids = itertools.count(1)
        self.handle: GoalHandle | None = None
        self.state = NavState.IDLE
        self.plan: NDArray[np.float64] = np.empty((0, 3))
        self.plan_listeners: list[Callable[[NDArray[np.float64]], None]] = []
        self.last_control: ControlResult | None = None
        self._reset_timers(0)
        self._stopped_text = ""
        self._stop_warned = False
        self._first_step_ns: int | None = None
        self._was_current = False

    # ------------------------------------------------------------------ goals
    def _reset_timers(self, now_ns: int) -> None:
        self.recovery_index = 0
        self.recovery_trigger = _Trigger.NONE
        self._active_recovery: Recovery | None = None
        self._last_valid_control = now_ns
        self._last_valid_plan = now_ns
        self._last_osc_reset = now_ns
        self._osc_pose: Pose2D | None = None
        self._next_plan_ns = now_ns
        self._planning_retries = 0
        self._last_plan_failure = ""
        self._last_plan_status = PlanStatus.OK
        self._last_control_failure = ""
        self._goal_clear_tried = False

    def go_to(self, goal: Pose2D, *, now_ns: int = 0) -> GoalHandle:
        """Accept a goal ``(x, y, yaw)`` in the global frame (a running goal is preempted)."""
        frame = self.global_costmap.global_frame
        handle = GoalHandle(
            next(self._ids), (float(goal[0]), float(goal[1]), float(goal[2])), frame
        )
        handle.accepted_ns = now_ns
        if not all(math.isfinite(v) for v in handle.goal):
            return self._finish(
                handle,
                GoalStatus.REJECTED,
                NavError.INVALID_GOAL,
                f"goal {handle.goal} has a non-finite coordinate: expected finite x, y, yaw",
                now_ns,
            )
        if self.handle is not None and not self.handle.done:
            self._finish(
                self.handle,
                GoalStatus.PREEMPTED,
                NavError.PREEMPTED,
                "preempted by a new goal",
                now_ns,
            )
        self.handle = handle
        handle.status = GoalStatus.ACTIVE
        handle.text = "planning"
        self.state = NavState.PLANNING
        self.controller.reset()
        self.plan = np.empty((0, 3))
        self._reset_timers(now_ns)
        self._log(
            "info",
            f"new goal {handle.goal_id}: ({goal[0]:.2f}, {goal[1]:.2f}, {goal[2]:.2f}) "
            f"in '{frame}'",
        )
        return handle

    def reject(self, goal: Pose2D, error: NavError, reason: str, *, now_ns: int = 0) -> GoalHandle:
        """Return a handle that is already REJECTED (the node uses it when TF fails)."""
        handle = GoalHandle(
            next(self._ids), goal, self.global_costmap.global_frame, accepted_ns=now_ns
        )
        return self._finish(handle, GoalStatus.REJECTED, error, reason, now_ns)

    def cancel(self, *, now_ns: int = 0) -> None:
        """Cancel the running goal (PREEMPTED with error CANCELED)."""
        if self.handle is not None and not self.handle.done:
            self._finish(self.handle, GoalStatus.PREEMPTED, NavError.CANCELED, "canceled", now_ns)

    def _finish(
        self, handle: GoalHandle, status: GoalStatus, error: NavError, text: str, now_ns: int
    ) -> GoalHandle:
        handle.status = status
        handle.error = error
        handle.text = text
        handle.finished_ns = now_ns
        if handle is self.handle:
            self.state = NavState.IDLE
            self.controller.reset()
            self._active_recovery = None
        level = "info" if status in (GoalStatus.SUCCEEDED, GoalStatus.PREEMPTED) else "error"
        self._log(level, f"goal {handle.goal_id} {status.name.lower()}: {text}")
        return handle

    # ------------------------------------------------------------------ cycle
    def step(
        self,
        now_ns: int,
        pose_global: Pose2D,
        pose_local: Pose2D,
        velocity: tuple[float, float],
    ) -> tuple[float, float]:
        """One control cycle; returns ``(v, w)`` (zero when idle, stopped or failing)."""
        if self._first_step_ns is None:
            self._first_step_ns = now_ns
        h = self.handle
        if h is None or h.done:
            return 0.0, 0.0
        stale = [
            cm for cm in (self.local_costmap, self.global_costmap) if not cm.is_current(now_ns)
        ]
        if stale:
            text = f"stopped: costmap data are not current ({stale[0].reason})"
            key = re.sub(r"[0-9.]+", "#", text)  # one log line per kind of stop, not per age
            early = not self._was_current and now_ns - self._first_step_ns < STARTUP_GRACE_S * _NS
            if key != self._stopped_text:
                self._log("debug" if early else "warning", text)
                self._stopped_text = key
                self._stop_warned = not early
            elif not early and not self._stop_warned:  # a start-up stop that persists
                self._log("warning", f"{text}, since start-up")
                self._stop_warned = True
            h.text = text
            self._last_osc_reset = now_ns
            self._last_valid_control = now_ns
            self._last_valid_plan = now_ns
            return 0.0, 0.0
        self._was_current = True
        if self._stopped_text:
            level = "info" if self._stop_warned else "debug"
            self._log(level, "sensor data are current again; resuming")
            self._stopped_text = ""
            self._stop_warned = False
        if self.state is NavState.CONTROLLING and self.controller.is_goal_reached(
            pose_global, velocity
        ):
            self._finish(h, GoalStatus.SUCCEEDED, NavError.NONE, "goal reached", now_ns)
            return 0.0, 0.0
        self._check_oscillation(now_ns, pose_global)
        if self.state in (NavState.PLANNING, NavState.CONTROLLING):
            self._maybe_plan(now_ns, pose_global)
            if h.done:
                return 0.0, 0.0
        if self.state is NavState.CONTROLLING:
            return self._control(now_ns, pose_global, pose_local, velocity)
        if self.state is NavState.CLEARING:
            return self._clear(now_ns, pose_global, pose_local, velocity)
        return 0.0, 0.0

    def _check_oscillation(self, now_ns: int, pose: Pose2D) -> None:
        p = self.params
        if (
            self._osc_pose is None
            or math.hypot(pose[0] - self._osc_pose[0], pose[1] - self._osc_pose[1])
            >= p.oscillation_distance
        ):
            self._osc_pose = pose
            self._last_osc_reset = now_ns
            if self.recovery_trigger is _Trigger.OSCILLATION:
                self.recovery_index = 0
        if (
            p.oscillation_timeout > 0
            and self.state is not NavState.CLEARING
            and now_ns - self._last_osc_reset > p.oscillation_timeout * _NS
        ):
            self._log(
                "warning",
                f"the robot moved less than {p.oscillation_distance:.2f} m in "
                f"{p.oscillation_timeout:.1f} s: running recovery behaviours",
            )
            self.state = NavState.CLEARING
            self.recovery_trigger = _Trigger.OSCILLATION
            self._last_osc_reset = now_ns

    def _maybe_plan(self, now_ns: int, pose: Pose2D) -> None:
        p = self.params
        h = self.handle
        assert h is not None
        due = self.state is NavState.PLANNING or (
            p.planner_frequency > 0 and now_ns >= self._next_plan_ns
        )
        if not due:
            return
        result = self.planner.make_plan(self.global_costmap.costmap, pose, h.goal)
        if p.planner_frequency > 0:
            self._next_plan_ns = now_ns + round(_NS / p.planner_frequency)
        if result.ok:
            h.plans += 1
            self.plan = result.poses
            self.controller.set_plan(result.poses)
            for listener in self.plan_listeners:
                listener(result.poses)
            self._last_valid_plan = now_ns
            self._planning_retries = 0
            self._goal_clear_tried = False
            if self.state is NavState.PLANNING:
                self.state = NavState.CONTROLLING
                h.text = "following the plan"
                if self.recovery_trigger is _Trigger.PLANNING:
                    self.recovery_index = 0
            return
        self._last_plan_failure = result.reason
        self._last_plan_status = result.status
        if result.status is PlanStatus.GOAL_OUTSIDE_MAP:
            self._finish(h, GoalStatus.ABORTED, NavError.GOAL_OUTSIDE_MAP, result.reason, now_ns)
            return
        if result.status is PlanStatus.GOAL_IN_OBSTACLE:
            if self._goal_clear_tried:
                self._finish(
                    h, GoalStatus.ABORTED, NavError.GOAL_IN_OBSTACLE, result.reason, now_ns
                )
                return
            self._goal_clear_tried = True
            self._log("warning", f"{result.reason}; clearing the obstacle layers once")
            self._run_instant(ClearCostmapRecovery("goal_clear", reset_distance=0.0), now_ns, pose)
            return
        if self.state is NavState.CONTROLLING:
            h.text = f"replanning failed, following the previous plan: {result.reason}"
            return
        self._planning_retries += 1
        h.text = f"planning failed: {result.reason}"
        expired = now_ns > self._last_valid_plan + p.planner_patience * _NS
        if expired or (0 <= p.max_planning_retries < self._planning_retries):
            self.state = NavState.CLEARING
            self.recovery_trigger = _Trigger.PLANNING

    def _run_instant(self, rec: Recovery, now_ns: int, pose: Pose2D) -> None:
        ctx = RecoveryContext(
            now_ns, pose, pose, (0.0, 0.0), self.local_costmap, self.global_costmap
        )
        rec.start(ctx)
        rec.step(ctx)

    def _control(
        self, now_ns: int, pose_global: Pose2D, pose_local: Pose2D, velocity: tuple[float, float]
    ) -> tuple[float, float]:
        p = self.params
        h = self.handle
        assert h is not None
        T_local_global = compose_2d(pose_local, invert_2d(pose_global))  # noqa: N806
        lc = self.local_costmap
        r = self.controller.compute_velocity(
            pose_local, velocity, lc.costmap, lc.footprint, T_local_global
        )
        self.last_control = r
        if r.ok:
            self._last_valid_control = now_ns
            if self.recovery_trigger is _Trigger.CONTROLLING:
                self.recovery_index = 0
            return r.v, r.w
        self._last_control_failure = r.reason
        if now_ns > self._last_valid_control + p.controller_patience * _NS:
            self._log("warning", f"no valid control for {p.controller_patience:.1f} s: {r.reason}")
            self.state = NavState.CLEARING
            self.recovery_trigger = _Trigger.CONTROLLING
        else:
            h.text = f"no valid control, replanning: {r.reason}"
            self._last_valid_plan = now_ns
            self._planning_retries = 0
            self.state = NavState.PLANNING
        return 0.0, 0.0

    def _clear(
        self, now_ns: int, pose_global: Pose2D, pose_local: Pose2D, velocity: tuple[float, float]
    ) -> tuple[float, float]:
        h = self.handle
        assert h is not None
        ctx = RecoveryContext(
            now_ns, pose_local, pose_global, velocity, self.local_costmap, self.global_costmap
        )
        if self._active_recovery is None:
            if not self.params.recovery_behavior_enabled or self.recovery_index >= len(
                self.recoveries
            ):
                self._abort_after_recoveries(now_ns)
                return 0.0, 0.0
            rec = self.recoveries[self.recovery_index]
            self._active_recovery = rec
            h.recoveries.append(rec.name)
            h.text = f"running recovery behaviour {rec.name}"
            self._log(
                "warning",
                f"running recovery behaviour {rec.name} "
                f"({self.recovery_index + 1}/{len(self.recoveries)})",
            )
            rec.start(ctx)
        rec = self._active_recovery
        out = rec.step(ctx)
        if not out.done:
            return out.v, out.w
        if out.failed:
            self._log("warning", f"recovery behaviour {rec.name} ended early: {out.failed}")
        self._active_recovery = None
        self.recovery_index += 1
        self.state = NavState.PLANNING
        self._last_valid_plan = now_ns
        self._last_valid_control = now_ns
        self._last_osc_reset = now_ns
        self._planning_retries = 0
        return 0.0, 0.0

    def _abort_after_recoveries(self, now_ns: int) -> None:
        h = self.handle
        assert h is not None
        n = len(self.recoveries) if self.params.recovery_behavior_enabled else 0
        if self.recovery_trigger is _Trigger.PLANNING:
            error = {
                PlanStatus.GOAL_IN_OBSTACLE: NavError.GOAL_IN_OBSTACLE,
                PlanStatus.START_OUTSIDE_MAP: NavError.START_OUTSIDE_MAP,
            }.get(self._last_plan_status, NavError.NO_PATH)
            text = (
                f"failed to find a valid plan even after {n} recovery behaviours: "
                f"{self._last_plan_failure}"
            )
        elif self.recovery_trigger is _Trigger.CONTROLLING:
            error = NavError.CONTROL_FAILED
            text = (
                f"failed to find a valid control even after {n} recovery behaviours: "
                f"{self._last_control_failure}"
            )
        else:
            error = NavError.OSCILLATING
            text = (
                f"the robot is oscillating (moved less than "
                f"{self.params.oscillation_distance:.2f} m in "
                f"{self.params.oscillation_timeout:.1f} s) even after {n} recovery behaviours"
            )
        self._finish(h, GoalStatus.ABORTED, error, text, now_ns)
