"""``libgazebo_ros_imu.so``: the ROS 1 IMU *model* plugin (TurtleBot3's ``/imu``).

Not the ``<sensor type="imu">`` plugin (:class:`~visnav.sim.plugins.ImuPlugin`, MuJoCo's
gyro and accelerometer): gazebo_ros_imu reads a link's world pose and velocities at every
world update and derives the rest, so its readings differ from a real IMU's in ways a
user of the ROS 1 plugin relies on:

* ``orientation``: the link frame in the world, rotated by ``rpyOffset`` (no noise);
* ``angular_velocity``: the link's angular velocity, plus ``gaussianNoise``;
* ``linear_acceleration``: the change of the link origin's velocity since the previous
  message divided by the time between them, plus ``gaussianNoise``: gravity is **not**
  in it (a robot at rest reads 0, where a real IMU and ``libgazebo_ros_imu_sensor.so``
  read +9.81 m/s^2 up); the first message after a (re)subscription reads 0;
* both vectors are expressed in the reported (offset) frame; every covariance diagonal
  is ``gaussianNoise``^2.

Messages go out only while ``topicName`` has a subscriber (the plugin computes nothing
otherwise), at ``updateRate`` (0 = every physics step), stamped with the sim time of the
state they describe (after ``mj_step1``).

Where visnav differs: gazebo_ros_imu rotates both vectors by the orientation instead of
its inverse (``RotateVector``; its own ``@todo`` says so), which is only right while the
link is aligned with the world; visnav expresses them in the link frame. ``serviceName``
(a ``std_srvs/Empty`` "calibrate" service that always succeeds) is not offered.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from visnav.description.rigid import matrix_to_quat_xyzw, rpy_to_matrix
from visnav.msgs.types import Imu, Quaternion, Vector3
from visnav.sim.plugin_factories import RobotBuild
from visnav.sim.plugins import SENSOR_QOS, SimPlugin, _header
from visnav.sim.sensor_timing import SensorClock
from visnav.sim.vehicles._state import BodyReader

if TYPE_CHECKING:
    import mujoco
    from numpy.typing import NDArray

    from visnav.description.gazebo_specs import ImuModelSpec
    from visnav.graph.node import Node
    from visnav.sim.rebind import IdMap

__all__ = ["ImuModelPlugin", "make_imu_model"]


class ImuModelPlugin(SimPlugin):
    """``libgazebo_ros_imu.so``: ``sensor_msgs/Imu`` of a link, from its motion.

    Args:
        node: the plugin's node.
        spec: the plugin with its final topic and frame.
        model: the compiled model.
        body: MuJoCo body id of ``bodyName``.
        rng: the noise generator.
        start_ns: sim time of the first possible message.
    """

    def __init__(
        self,
        node: Node,
        spec: ImuModelSpec,
        model: mujoco.MjModel,
        *,
        body: int,
        rng: np.random.Generator,
        start_ns: int = 0,
    ) -> None:
        super().__init__(node, spec.plugin_name)
        self.spec = spec
        self.clock = SensorClock(spec.update_rate, start_ns=start_ns)
        self._body = BodyReader(model, body)
        self._rng = rng
        self._offset = rpy_to_matrix(spec.rpy_offset)
        var = spec.gaussian_noise**2
        self._cov = np.diag([var] * 3).reshape(-1)
        self._last: tuple[int, NDArray[np.float64]] | None = None
        self._wanted = (-1, False)
        self.samples = 0
        self._pub = node.create_publisher(Imu, spec.topic or "/default_imu", SENSOR_QOS)

    def _subscribed(self) -> bool:
        version = self.node.context.graph.version
        if version != self._wanted[0]:
            self._wanted = (version, self._pub.get_subscription_count() > 0)
        return self._wanted[1]

    def rewind(self, now_ns: int) -> None:
        """Sim time went back to ``now_ns``: the schedule restarts, no acceleration history."""
        super().rewind(now_ns)
        self._last = None

    def rebind(self, ids: IdMap) -> None:
        """Read the same body of a recompiled model."""
        self._body.rebind(ids)

    def sense(self, data: mujoco.MjData, now_ns: int) -> None:
        """Publish the state at ``now_ns`` when due and subscribed."""
        if not self.clock.due(now_ns):
            return
        if not self._subscribed():
            self._last = None
            return
        state = self._body.read(data)  # fresh arrays: kept without copies below
        rot = self._offset @ state.rotation
        linear = state.linear
        last = self._last
        if last is not None and now_ns > last[0]:
            accel = (linear - last[1]) / ((now_ns - last[0]) * 1e-9)
        else:
            accel = np.zeros(3)
        self._last = (now_ns, linear)
        angular = state.angular
        sigma = self.spec.gaussian_noise
        if sigma > 0.0:
            angular = angular + self._rng.normal(0.0, sigma, 3)
            accel = accel + self._rng.normal(0.0, sigma, 3)
        self.samples += 1
        cov = self._cov
        qx, qy, qz, qw = matrix_to_quat_xyzw(rot)
        gx, gy, gz = (rot.T @ angular).tolist()
        ax, ay, az = (rot.T @ accel).tolist()
        self._pub.publish(
            Imu(
                header=_header(now_ns, self.spec.frame_id),
                orientation=Quaternion(x=qx, y=qy, z=qz, w=qw),
                orientation_covariance=cov.copy(),
                angular_velocity=Vector3(x=gx, y=gy, z=gz),
                angular_velocity_covariance=cov.copy(),
                linear_acceleration=Vector3(x=ax, y=ay, z=az),
                linear_acceleration_covariance=cov.copy(),
            )
        )


def make_imu_model(build: RobotBuild, imu: ImuModelSpec) -> SimPlugin | None:
    """``libgazebo_ros_imu.so``: the IMU model plugin (None when its topic is empty)."""
    if imu.topic is None:
        return None
    spec = replace(imu, topic=build.push(imu.topic), frame_id=build.frame(imu.frame_id))
    model = build.model
    return ImuModelPlugin(
        build.node(imu.plugin_name),
        spec,
        model,
        body=model.body(build.handles.bodies[imu.body_name]).id,
        rng=np.random.default_rng(build.seed_of(imu.plugin_name)),
    )
