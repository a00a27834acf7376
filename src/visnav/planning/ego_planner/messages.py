"""Trajectories and position commands as standard ROS messages.

ego-planner sends its B-spline on a custom ``ego_planner/Bspline`` message and
the traj server sends ``quadrotor_msgs/PositionCommand``; visnav keeps to
standard types, both ``trajectory_msgs/MultiDOFJointTrajectory`` (the type
RotorS controllers take on ``command/trajectory``):

* **Trajectory** (planner -> traj server): ``header.stamp`` is the trajectory's
  start time, ``header.frame_id`` the map frame; one point per knot of the
  cubic B-spline with ``transforms[0].translation`` the position,
  ``velocities[0].linear`` the velocity, ``accelerations[0].linear`` the
  acceleration and ``time_from_start`` the knot time. Between knots the spline is
  one cubic, which the cubic Hermite interpolation of :class:`SampledTrajectory`
  reproduces exactly from the end positions and velocities.
* **Command** (traj server -> vehicle): one point with ``transforms[0]`` the
  position and the yaw (a rotation about z), ``velocities[0]`` the velocity and
  the yaw rate (``angular.z``), ``accelerations[0].linear`` the feed-forward
  acceleration, ``time_from_start`` 0. :func:`command_fields` turns it back into
  the fields of ``visnav.sim.vehicles.quadrotor.PositionCommand``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.typesys.stores.ros2_humble import (
    trajectory_msgs__msg__MultiDOFJointTrajectory as MultiDOFJointTrajectory,
)
from rosbags.typesys.stores.ros2_humble import (
    trajectory_msgs__msg__MultiDOFJointTrajectoryPoint as MultiDOFJointTrajectoryPoint,
)

from visnav.msgs.time import duration_to_ns, ns_to_duration, ns_to_time, time_to_ns
from visnav.msgs.types import Header, Transform, Twist, Vector3
from visnav.planning.errors import PlanningError
from visnav.tf.errors import InvalidArgumentException
from visnav.tf.transforms import quaternion_from_yaw, yaw_from_quaternion

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from visnav.planning.ego_planner.manager import LocalTrajectory

__all__ = [
    "MultiDOFJointTrajectory",
    "MultiDOFJointTrajectoryPoint",
    "PositionReference",
    "SampledTrajectory",
    "TrajectoryMessageError",
    "command_fields",
    "msg_to_reference",
    "msg_to_trajectory",
    "reference_to_msg",
    "trajectory_to_msg",
]

_NS = 1_000_000_000


class TrajectoryMessageError(PlanningError):
    """A trajectory or command message that cannot be read."""


def _vec(v: ArrayLike) -> Vector3:
    a = np.asarray(v, dtype=np.float64).reshape(3)
    return Vector3(x=float(a[0]), y=float(a[1]), z=float(a[2]))


def _arr(v: Vector3) -> NDArray[np.float64]:
    return np.array([v.x, v.y, v.z], dtype=np.float64)


def _point(
    pos: ArrayLike,
    vel: ArrayLike,
    acc: ArrayLike,
    t_ns: int,
    yaw: float = 0.0,
    yaw_dot: float = 0.0,
) -> MultiDOFJointTrajectoryPoint:
    return MultiDOFJointTrajectoryPoint(
        transforms=[
            Transform(
                translation=_vec(pos),
                rotation=quaternion_from_yaw(yaw),
            )
        ],
        velocities=[Twist(linear=_vec(vel), angular=Vector3(x=0.0, y=0.0, z=float(yaw_dot)))],
        accelerations=[Twist(linear=_vec(acc), angular=Vector3(x=0.0, y=0.0, z=0.0))],
        time_from_start=ns_to_duration(int(t_ns)),
    )


class SampledTrajectory:
    """Positions, velocities and accelerations at increasing times, cubic Hermite in between.

    Args:
        times: ``(M,)`` strictly increasing times from the start (s), ``M >= 1``.
        positions: ``(M, 3)``.
        velocities: ``(M, 3)``.
        accelerations: ``(M, 3)`` (used at the samples themselves).

    Raises:
        TrajectoryMessageError: Shapes that do not match or unordered times.
    """

    def __init__(
        self,
        times: ArrayLike,
        positions: ArrayLike,
        velocities: ArrayLike,
        accelerations: ArrayLike,
    ) -> None:
        self.times = np.asarray(times, dtype=np.float64).reshape(-1)
        self.positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        self.velocities = np.asarray(velocities, dtype=np.float64).reshape(-1, 3)
        self.accelerations = np.asarray(accelerations, dtype=np.float64).reshape(-1, 3)
        m = self.times.shape[0]
        if m == 0 or not (
            self.positions.shape[0] == self.velocities.shape[0] == self.accelerations.shape[0] == m
        ):
            msg = f"trajectory has {m} times but {self.positions.shape[0]} points: expected equal"
            raise TrajectoryMessageError(msg)
        if np.any(np.diff(self.times) <= 0):
            msg = "trajectory times must increase strictly"
            raise TrajectoryMessageError(msg)

    @property
    def duration(self) -> float:
        """Time of the last sample (s)."""
        return float(self.times[-1])

    def evaluate(
        self, t: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Position, velocity and acceleration at ``t`` (clamped to the samples)."""
        times = self.times
        if t <= times[0] or times.shape[0] == 1:
            return self.positions[0].copy(), self.velocities[0].copy(), self.accelerations[0].copy()
        if t >= times[-1]:
            return (
                self.positions[-1].copy(),
                self.velocities[-1].copy(),
                self.accelerations[-1].copy(),
            )
        k = int(np.searchsorted(times, t, side="right")) - 1
        h = times[k + 1] - times[k]
        s = (t - times[k]) / h
        p0, p1 = self.positions[k], self.positions[k + 1]
        m0, m1 = self.velocities[k] * h, self.velocities[k + 1] * h
        s2, s3 = s * s, s * s * s
        pos = (
            (2 * s3 - 3 * s2 + 1) * p0
            + (s3 - 2 * s2 + s) * m0
            + (-2 * s3 + 3 * s2) * p1
            + (s3 - s2) * m1
        )
        vel = (
            (6 * s2 - 6 * s) * p0
            + (3 * s2 - 4 * s + 1) * m0
            + (-6 * s2 + 6 * s) * p1
            + (3 * s2 - 2 * s) * m1
        ) / h
        acc = ((12 * s - 6) * p0 + (6 * s - 4) * m0 + (-12 * s + 6) * p1 + (6 * s - 2) * m1) / (
            h * h
        )
        return pos, vel, acc


def trajectory_to_msg(
    traj: LocalTrajectory, *, frame_id: str, joint_name: str = "base_link"
) -> MultiDOFJointTrajectory:
    """The local trajectory sampled at its knots (see the module docstring)."""
    spline = traj.position
    p = spline.order
    knots = spline.knots[p : spline.knots.shape[0] - p] - spline.t_start
    times = np.unique(np.clip(knots, 0.0, traj.duration))
    pos = spline.evaluate(times)
    vel = traj.velocity.evaluate(times)
    acc = traj.acceleration.evaluate(times)
    points = [_point(pos[i], vel[i], acc[i], round(times[i] * _NS)) for i in range(times.shape[0])]
    return MultiDOFJointTrajectory(
        header=Header(stamp=ns_to_time(traj.start_time_ns), frame_id=frame_id),
        joint_names=[joint_name],
        points=points,
    )


def msg_to_trajectory(msg: MultiDOFJointTrajectory) -> tuple[int, SampledTrajectory]:
    """Read a trajectory message: ``(start time ns, trajectory)``.

    Raises:
        TrajectoryMessageError: No points, points without a transform, or unordered times.
    """
    if not msg.points:
        msg_text = "trajectory message has no points"
        raise TrajectoryMessageError(msg_text)
    times, pos, vel, acc = [], [], [], []
    for i, pt in enumerate(msg.points):
        if not pt.transforms:
            text = f"trajectory point {i} has no transform: expected transforms[0] = position"
            raise TrajectoryMessageError(text)
        times.append(duration_to_ns(pt.time_from_start) / _NS)
        pos.append(_arr(pt.transforms[0].translation))
        vel.append(_arr(pt.velocities[0].linear) if pt.velocities else np.zeros(3))
        acc.append(_arr(pt.accelerations[0].linear) if pt.accelerations else np.zeros(3))
    return time_to_ns(msg.header.stamp), SampledTrajectory(times, pos, vel, acc)


@dataclass(frozen=True)
class PositionReference:
    """One command of the traj server (the content of ``quadrotor_msgs/PositionCommand``).

    Attributes:
        stamp_ns: Command time (ns).
        frame_id: Frame of the references.
        position: Desired position (m).
        velocity: Desired velocity (m/s).
        acceleration: Feed-forward acceleration (m/s^2).
        yaw: Desired heading (rad).
        yaw_dot: Desired yaw rate (rad/s).
    """

    stamp_ns: int
    frame_id: str
    position: tuple[float, float, float]
    velocity: tuple[float, float, float]
    acceleration: tuple[float, float, float]
    yaw: float
    yaw_dot: float


def reference_to_msg(
    ref: PositionReference, *, joint_name: str = "base_link"
) -> MultiDOFJointTrajectory:
    """A one-point command message (see the module docstring)."""
    return MultiDOFJointTrajectory(
        header=Header(stamp=ns_to_time(ref.stamp_ns), frame_id=ref.frame_id),
        joint_names=[joint_name],
        points=[_point(ref.position, ref.velocity, ref.acceleration, 0, ref.yaw, ref.yaw_dot)],
    )


def msg_to_reference(msg: MultiDOFJointTrajectory) -> PositionReference:
    """Read a command message (its first point).

    Raises:
        TrajectoryMessageError: No point, no transform, or a zero or non-finite rotation.
    """
    if not msg.points or not msg.points[0].transforms:
        text = "command message needs one point with transforms[0] (position and yaw)"
        raise TrajectoryMessageError(text)
    pt = msg.points[0]
    tf = pt.transforms[0]
    try:
        yaw = yaw_from_quaternion(tf.rotation)
    except InvalidArgumentException as exc:
        text = f"command message points[0].transforms[0].rotation: {exc}; send a unit quaternion"
        raise TrajectoryMessageError(text) from exc
    vel = _arr(pt.velocities[0].linear) if pt.velocities else np.zeros(3)
    yaw_dot = float(pt.velocities[0].angular.z) if pt.velocities else 0.0
    acc = _arr(pt.accelerations[0].linear) if pt.accelerations else np.zeros(3)
    pos = _arr(tf.translation)
    return PositionReference(
        stamp_ns=time_to_ns(msg.header.stamp),
        frame_id=msg.header.frame_id,
        position=(float(pos[0]), float(pos[1]), float(pos[2])),
        velocity=(float(vel[0]), float(vel[1]), float(vel[2])),
        acceleration=(float(acc[0]), float(acc[1]), float(acc[2])),
        yaw=yaw,
        yaw_dot=yaw_dot,
    )


def command_fields(msg: MultiDOFJointTrajectory) -> dict[str, Any]:
    """Keyword arguments of ``visnav.sim.vehicles.quadrotor.PositionCommand`` for a command.

    ``PositionCommand(**command_fields(msg))`` gives the simulator's controller input.
    """
    ref = msg_to_reference(msg)
    return {
        "stamp_ns": ref.stamp_ns,
        "frame_id": ref.frame_id,
        "position": ref.position,
        "velocity": ref.velocity,
        "acceleration": ref.acceleration,
        "yaw": ref.yaw,
        "yaw_dot": ref.yaw_dot,
    }
