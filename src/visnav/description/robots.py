"""The built-in robots (``car``, ``quadrotor``) and robot lookup by name, file or XML.

The descriptions are Xacro files shipped in ``visnav/description/robots/``:

* ``car.urdf.xacro``: a differential-drive base (two driven wheels of 0.16 m diameter,
  0.36 m apart, a frictionless rear caster) with an RGB camera (640 x 480 at 30 Hz) and
  a depth camera (640 x 480 at 20 Hz, 0.1 - 10 m), ``libgazebo_ros_p3d.so`` ground truth
  on ``/ground_truth/odom``, ``libgazebo_ros_diff_drive.so`` (``cmd_vel`` in, ``odom``
  and ``odom -> base_footprint`` out) and a joint-state publisher for the wheels; Xacro
  arguments ``odometry_source`` (1 world, 0 encoder), ``camera_rate``, ``depth_rate``,
  ``ideal_sensors``. Frames follow REP 103 / 105 with optical child frames.
* ``quadrotor.urdf.xacro``: a depth camera (640 x 480 at 20 Hz), p3d odometry and the
  ``libvisnav_quadrotor.so`` block holding
  :class:`~visnav.description.vehicle_params.QuadrotorParams`; root link ``base_link``.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Callable, Mapping
from importlib.resources import files
from pathlib import Path

from visnav.description.errors import RobotDescriptionError
from visnav.description.robot import RobotDescription, load_robot

__all__ = [
    "BUILTIN_ROBOTS",
    "CAR_BASE_FRAME",
    "builtin_robot_names",
    "car_description_path",
    "quadrotor_description_path",
    "resolve_robot",
]

CAR_BASE_FRAME = "base_footprint"
"""The car's root link (its free-floating body in MuJoCo and its odometry child frame)."""

_ROBOT_SUFFIXES = (".urdf", ".xacro", ".xml")


def _robot_file(name: str) -> Path:
    return Path(str(files("visnav.description") / "robots" / name))


def car_description_path() -> Path:
    """Path of the built-in car's Xacro file."""
    return _robot_file("car.urdf.xacro")


def quadrotor_description_path() -> Path:
    """Path of the built-in quadrotor's Xacro file (depth camera, p3d odometry)."""
    return _robot_file("quadrotor.urdf.xacro")


BUILTIN_ROBOTS: Mapping[str, Callable[[], Path]] = {
    "car": car_description_path,
    "quadrotor": quadrotor_description_path,
}
"""Built-in robot name -> the function returning its Xacro file."""


def builtin_robot_names() -> tuple[str, ...]:
    """Names of the built-in robots."""
    return tuple(sorted(BUILTIN_ROBOTS))


def resolve_robot(
    source: str | os.PathLike[str] | RobotDescription,
    *,
    args: Mapping[str, str] | None = None,
    packages: Mapping[str, Path | str] | None = None,
) -> RobotDescription:
    """Load a robot from a built-in name, a URDF / Xacro file or XML text.

    Args:
        source: ``car``, ``quadrotor``, a file path, URDF XML, or a loaded description.
        args: Xacro ``name:=value`` arguments.
        packages: package name -> directory for ``package://`` and ``$(find pkg)``.

    Raises:
        RobotDescriptionError: an unknown name (with the closest built-in name), a
            missing file or an invalid description.
    """
    if isinstance(source, RobotDescription):
        return source
    text = os.fspath(source)
    if text.lstrip().startswith("<"):
        return load_robot(text, args=args, packages=packages)
    path = Path(text)
    looks_like_file = path.suffix.lower() in _ROBOT_SUFFIXES or os.sep in text or path.exists()
    if not looks_like_file:
        maker = BUILTIN_ROBOTS.get(text)
        if maker is None:
            close = difflib.get_close_matches(text, list(BUILTIN_ROBOTS), n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            msg = (
                f"unknown robot {text!r}{hint} Built-in robots: {', '.join(builtin_robot_names())}"
                "; or give the path of a .urdf / .urdf.xacro file"
            )
            raise RobotDescriptionError(msg)
        return load_robot(maker(), args=args, packages=packages)
    if not path.is_file():
        msg = (
            f"robot file {text!r} does not exist (built-in robots: "
            f"{', '.join(builtin_robot_names())})"
        )
        raise RobotDescriptionError(msg)
    return load_robot(path, args=args, packages=packages)
