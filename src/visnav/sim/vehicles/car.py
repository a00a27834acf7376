"""The built-in car: ``scenarios/robots/car.urdf.xacro``.

A differential-drive base (two driven wheels of 0.16 m diameter, 0.36 m apart,
and a frictionless rear caster), an RGB camera and a depth camera, described the
way Gazebo users write robots, so :mod:`visnav.sim.robot` loads it like any user
URDF:

* frames ``base_footprint`` (on the ground) -> ``base_link`` (axle height) ->
  ``left_wheel`` / ``right_wheel`` (continuous joints about y), ``caster_link``,
  ``camera_link`` -> ``camera_optical_frame`` and ``depth_camera_link`` ->
  ``depth_camera_optical_frame`` (REP 103 optical rotation, rpy -pi/2 0 -pi/2);
* ``libgazebo_ros_camera.so`` RGB camera 640 x 480 at 30 Hz (hfov 80 deg):
  ``/camera/image_raw``, ``/camera/camera_info``;
* depth camera (``sensor type="depth"``) 640 x 480 at 20 Hz (hfov 87 deg,
  0.1 - 10 m): ``/depth_camera/depth/image_raw``, ``/depth_camera/depth/camera_info``,
  ``/depth_camera/points``;
* ``libgazebo_ros_p3d.so`` ground truth at 50 Hz on ``/ground_truth/odom``
  (``world -> base_footprint``);
* ``libgazebo_ros_diff_drive.so`` at 50 Hz (``cmd_vel`` in, ``odom`` and the
  ``odom -> base_footprint`` TF out; 1 m/s^2 wheel acceleration, 20 N m torque),
  driven in the simulator by :class:`~visnav.sim.vehicles.diff_drive.DiffDriveController`;
* ``libgazebo_ros_joint_state_publisher.so`` for the wheel joints.

Xacro arguments: ``odometry_source`` (1 world, 0 encoder), ``camera_rate``,
``depth_rate``.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

__all__ = ["CAR_BASE_FRAME", "car_description_path"]

CAR_BASE_FRAME = "base_footprint"
"""The car's root link (its free-floating body in MuJoCo and its odometry child frame)."""


def car_description_path() -> Path:
    """Path of the built-in car's Xacro file."""
    return Path(str(files("visnav.scenarios") / "robots" / "car.urdf.xacro"))
