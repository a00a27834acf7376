"""robot_state_publisher's algorithm without a graph: URDF + JointState -> transforms.

* Fixed joints give static transforms (``/tf_static``), ``parent -> child`` at
  the joint origin, published once.
* Moving joints named in a ``sensor_msgs/JointState`` give dynamic transforms
  (``/tf``) stamped with the message's stamp: revolute and continuous joints
  rotate about their axis by the position, prismatic joints translate along it.
* A ``<mimic>`` joint follows its master (``multiplier * q + offset``) when the
  master is in the message, as robot_state_publisher does.
* ``frame_prefix`` is prepended to every frame id (robot_state_publisher's
  ``frame_prefix`` parameter).

Differences from robot_state_publisher: floating joints are neither static nor
dynamic here (their pose comes from odometry / p3d, not joint states); KDL would
publish them as fixed at their origin. A JointState whose ``name`` and
``position`` lengths differ raises :class:`RobotStateError` instead of being
logged and dropped, so the node wrapper decides how to report it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from visnav.description.rigid import axis_angle_matrix, matrix_to_quat_xyzw
from visnav.description.urdf_model import Joint, Urdf
from visnav.msgs.time import ns_to_time, time_to_ns
from visnav.msgs.types import (
    Header,
    JointState,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
)
from visnav.tf.errors import TransformException

__all__ = [
    "RobotStateError",
    "RobotStateModel",
    "dynamic_transforms",
    "joint_state_message",
    "static_transforms",
]


class RobotStateError(TransformException, ValueError):
    """A JointState message cannot be applied to the robot."""


def _stamped(
    parent: str, child: str, matrix: NDArray[np.float64], stamp_ns: int
) -> TransformStamped:
    x, y, z, w = matrix_to_quat_xyzw(matrix[:3, :3])
    return TransformStamped(
        header=Header(stamp=ns_to_time(stamp_ns), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(
                x=float(matrix[0, 3]), y=float(matrix[1, 3]), z=float(matrix[2, 3])
            ),
            rotation=Quaternion(x=x, y=y, z=z, w=w),
        ),
    )


class RobotStateModel:
    """Precomputed joint origins of one robot for fast transform computation.

    Args:
        urdf: the robot.
        frame_prefix: prepended to every frame id (e.g. ``"robot1/"``).
    """

    def __init__(self, urdf: Urdf, *, frame_prefix: str = "") -> None:
        self.urdf = urdf
        self.frame_prefix = frame_prefix
        self._origins = {name: j.origin.matrix() for name, j in urdf.joints.items()}
        self.fixed_joints: tuple[Joint, ...] = tuple(
            j for j in urdf.joints.values() if j.type == "fixed"
        )
        self.moving_joints: Mapping[str, Joint] = {
            name: j
            for name, j in urdf.joints.items()
            if j.type in ("revolute", "continuous", "prismatic")
        }
        self._mimics: dict[str, Joint] = {
            name: j for name, j in self.moving_joints.items() if j.mimic is not None
        }

    def frame(self, link: str) -> str:
        """Return the frame id of a link (with the prefix)."""
        return f"{self.frame_prefix}{link}"

    def static_transforms(self, *, stamp_ns: int = 0) -> list[TransformStamped]:
        """Return ``parent -> child`` for every fixed joint, stamped ``stamp_ns``."""
        return [
            _stamped(self.frame(j.parent), self.frame(j.child), self._origins[j.name], stamp_ns)
            for j in self.fixed_joints
        ]

    def joint_transform(self, joint: str, position: float) -> NDArray[np.float64]:
        """Return ``T_parent_child`` (4x4) of a moving joint at ``position`` (rad or m)."""
        spec = self.moving_joints.get(joint)
        if spec is None:
            msg = (
                f"joint {joint!r} is not a revolute, continuous or prismatic joint of robot "
                f"{self.urdf.name!r} (moving joints: {', '.join(self.moving_joints) or 'none'})"
            )
            raise RobotStateError(msg)
        motion = np.eye(4)
        if spec.type == "prismatic":
            motion[:3, 3] = np.asarray(spec.axis) * position
        else:
            motion[:3, :3] = axis_angle_matrix(spec.axis, position)
        return self._origins[joint] @ motion

    def joint_positions(self, joint_state: JointState) -> dict[str, float]:
        """Return the positions of the model's moving joints found in ``joint_state``.

        Names the robot does not have are ignored; mimic joints are added when
        their master is present (and not themselves in the message).

        Raises:
            RobotStateError: ``name`` and ``position`` have different lengths, or
                a position is not finite.
        """
        names = list(joint_state.name)
        positions = np.asarray(joint_state.position, dtype=np.float64).reshape(-1)
        if len(names) != positions.size:
            msg = (
                f"JointState has {len(names)} names but {positions.size} positions: "
                "expected one position per name (robot_state_publisher drops such messages)"
            )
            raise RobotStateError(msg)
        out: dict[str, float] = {}
        for name, value in zip(names, positions.tolist(), strict=True):
            if name not in self.moving_joints:
                continue
            if not math.isfinite(value):
                msg = f"JointState position of joint {name!r} is {value}: expected a finite number"
                raise RobotStateError(msg)
            out[name] = float(value)
        for name, joint in self._mimics.items():
            mimic = joint.mimic
            if mimic is not None and name not in out and mimic.joint in out:
                out[name] = mimic.multiplier * out[mimic.joint] + mimic.offset
        return out

    def dynamic_transforms(
        self, joint_state: JointState, *, stamp_ns: int | None = None
    ) -> list[TransformStamped]:
        """Return ``parent -> child`` of every moving joint in ``joint_state``.

        Args:
            joint_state: the joint positions.
            stamp_ns: override the stamp (default: the message's header stamp).
        """
        stamp = time_to_ns(joint_state.header.stamp) if stamp_ns is None else stamp_ns
        out = []
        for name, position in self.joint_positions(joint_state).items():
            joint = self.moving_joints[name]
            out.append(
                _stamped(
                    self.frame(joint.parent),
                    self.frame(joint.child),
                    self.joint_transform(name, position),
                    stamp,
                )
            )
        return out


def static_transforms(
    urdf: Urdf, *, stamp_ns: int = 0, frame_prefix: str = ""
) -> list[TransformStamped]:
    """Return the ``/tf_static`` transforms of a robot's fixed joints."""
    return RobotStateModel(urdf, frame_prefix=frame_prefix).static_transforms(stamp_ns=stamp_ns)


def dynamic_transforms(
    urdf: Urdf,
    joint_state: JointState,
    *,
    frame_prefix: str = "",
    stamp_ns: int | None = None,
) -> list[TransformStamped]:
    """Return the ``/tf`` transforms of a robot's moving joints for one JointState."""
    model = RobotStateModel(urdf, frame_prefix=frame_prefix)
    return model.dynamic_transforms(joint_state, stamp_ns=stamp_ns)


def joint_state_message(
    names: Sequence[str], positions: Sequence[float], *, stamp_ns: int = 0
) -> JointState:
    """Build a ``sensor_msgs/JointState`` with positions only (a convenience for callers)."""
    return JointState(
        header=Header(stamp=ns_to_time(stamp_ns), frame_id=""),
        name=list(names),
        position=np.asarray(positions, dtype=np.float64),
        velocity=np.zeros(0, dtype=np.float64),
        effort=np.zeros(0, dtype=np.float64),
    )
