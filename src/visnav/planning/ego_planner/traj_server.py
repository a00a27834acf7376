"""ego-planner's trajectory server (``plan_manage/traj_server.cpp``), graph-free.

At every tick (100 Hz upstream) the server evaluates the current trajectory at
``now - start``: position, velocity and acceleration, and a heading that looks
at the point ``time_forward`` seconds ahead (``calculate_yaw``): the wanted yaw
is the direction to that point (kept when it is nearer than 0.1 m); the step
towards it takes the wrapped shortest way, is limited to pi rad/s and then
halved (upstream's naive low-pass), and the yaw rate is averaged with the
previous one. After the end it holds the last
position with zero velocity and the last yaw; before the start it sends nothing.

Differences from upstream: the first tick has no elapsed time, so the yaw rate
is 0 (upstream divides by zero); the low-pass also applies across +-pi (upstream
skips it there by accident); the initial yaw can be set from odometry
(:meth:`TrajectoryServer.set_yaw`) instead of 0.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from visnav.planning.ego_planner.messages import PositionReference

if TYPE_CHECKING:
    from visnav.planning.ego_planner.messages import SampledTrajectory

__all__ = ["YAW_DOT_MAX", "TrajectoryServer"]

YAW_DOT_MAX = math.pi
_NS = 1_000_000_000


def _t3(v: object) -> tuple[float, float, float]:
    a = list(v)  # type: ignore[call-overload]
    return float(a[0]), float(a[1]), float(a[2])


class TrajectoryServer:
    """Samples the latest trajectory into position references.

    Args:
        time_forward: How far ahead the heading looks (s); upstream's launch uses 1.0.
        frame_id: Frame written into the references.
    """

    def __init__(self, *, time_forward: float = 1.0, frame_id: str = "world") -> None:
        self.time_forward = float(time_forward)
        self.frame_id = frame_id
        self.trajectory: SampledTrajectory | None = None
        self.start_ns = 0
        self.trajectory_count = 0
        self.last_yaw = 0.0
        self.last_yaw_dot = 0.0
        self._last_ns: int | None = None

    def set_trajectory(self, trajectory: SampledTrajectory, start_ns: int) -> None:
        """Follow ``trajectory`` whose time 0 is ``start_ns``."""
        self.trajectory = trajectory
        self.start_ns = int(start_ns)
        self.trajectory_count += 1

    def set_yaw(self, yaw: float) -> None:
        """Start from this heading (before the first trajectory)."""
        if self.trajectory is None:
            self.last_yaw = float(yaw)

    def calculate_yaw(
        self, t_cur: float, position: tuple[float, float, float], dt: float
    ) -> tuple[float, float]:
        """The heading and its rate at ``t_cur`` for a vehicle commanded at ``position``."""
        traj = self.trajectory
        if traj is None:
            return self.last_yaw, 0.0
        ahead, _v, _a = traj.evaluate(min(t_cur + self.time_forward, traj.duration))
        dx, dy = float(ahead[0]) - position[0], float(ahead[1]) - position[1]
        dz = float(ahead[2]) - position[2]
        last = self.last_yaw
        wanted = math.atan2(dy, dx) if math.sqrt(dx * dx + dy * dy + dz * dz) > 0.1 else last
        max_change = YAW_DOT_MAX * dt
        diff = wanted - last
        if diff > math.pi:
            diff -= 2 * math.pi
        elif diff < -math.pi:
            diff += 2 * math.pi
        if diff > max_change:
            step, yaw_dot = max_change, YAW_DOT_MAX
        elif diff < -max_change:
            step, yaw_dot = -max_change, -YAW_DOT_MAX
        else:
            step = diff
            yaw_dot = diff / dt if dt > 0 else 0.0
        # upstream's naive low-pass: the heading moves half the (limited) step
        yaw = math.atan2(math.sin(last + 0.5 * step), math.cos(last + 0.5 * step))
        yaw_dot = 0.5 * self.last_yaw_dot + 0.5 * yaw_dot
        self.last_yaw = yaw
        self.last_yaw_dot = yaw_dot
        return yaw, yaw_dot

    def command(self, now_ns: int) -> PositionReference | None:
        """The reference at ``now_ns``; None before the first trajectory or before its start."""
        traj = self.trajectory
        if traj is None:
            return None
        t_cur = (now_ns - self.start_ns) / _NS
        dt = 0.0 if self._last_ns is None else max(0.0, (now_ns - self._last_ns) / _NS)
        self._last_ns = now_ns
        if t_cur < 0.0:
            return None
        if t_cur < traj.duration:
            pos, vel, acc = traj.evaluate(t_cur)
            yaw, yaw_dot = self.calculate_yaw(t_cur, _t3(pos), dt)
            return PositionReference(
                now_ns, self.frame_id, _t3(pos), _t3(vel), _t3(acc), yaw, yaw_dot
            )
        pos, _v, _a = traj.evaluate(traj.duration)
        self.last_yaw_dot = 0.0
        return PositionReference(
            now_ns, self.frame_id, _t3(pos), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), self.last_yaw, 0.0
        )
