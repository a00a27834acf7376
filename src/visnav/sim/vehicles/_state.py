"""Pose and velocity of a body's frame origin, read so that they are current after ``mj_step``.

``mj_step`` leaves ``xpos``, ``xmat`` and ``cvel`` at the state *before* its
integration, one step old. For a body with a free joint the pose and velocity
come straight from ``qpos`` / ``qvel`` (always current); for other bodies they
come from the kinematics, which the caller keeps current (``mj_forward``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import mujoco
    import numpy.typing as npt

    from visnav.sim.rebind import IdMap

__all__ = ["BodyReader", "BodyState"]


@dataclass(frozen=True)
class BodyState:
    """A body frame in the world: position, rotation (world <- body), velocities.

    ``linear`` is the velocity of the frame origin and ``angular`` the angular
    velocity, both in world coordinates; ``quat_wxyz`` is MuJoCo's order.
    """

    position: npt.NDArray[np.float64]
    rotation: npt.NDArray[np.float64]
    quat_wxyz: npt.NDArray[np.float64]
    linear: npt.NDArray[np.float64]
    angular: npt.NDArray[np.float64]


class BodyReader:
    """Reads :class:`BodyState` of one body of a model."""

    def __init__(self, model: mujoco.MjModel, body: int) -> None:
        import mujoco  # noqa: PLC0415

        self._mujoco = mujoco
        self._bind(model, body)

    def _bind(self, model: mujoco.MjModel, body: int) -> None:
        mujoco = self._mujoco
        self.model = model
        self.body = body
        jnt = int(model.body_jntadr[body]) if model.body_jntnum[body] > 0 else -1
        self.free = (
            jnt >= 0
            and model.jnt_type[jnt] == mujoco.mjtJoint.mjJNT_FREE
            and int(model.body_parentid[body]) == 0
        )
        self._qpos = int(model.jnt_qposadr[jnt]) if self.free else -1
        self._dof = int(model.jnt_dofadr[jnt]) if self.free else -1

    def rebind(self, ids: IdMap) -> None:
        """Read the same body of a recompiled model (:mod:`visnav.sim.rebind`)."""
        self._bind(ids.model, ids.body(self.body))

    def read(self, data: mujoco.MjData) -> BodyState:
        """The body's current state."""
        mujoco = self._mujoco
        if self.free:
            rot = np.empty(9)
            q = self._qpos
            pos = data.qpos[q : q + 3].copy()
            quat = data.qpos[q + 3 : q + 7].copy()
            quat /= np.linalg.norm(quat)
            mujoco.mju_quat2Mat(rot, quat)
            r = rot.reshape(3, 3)
            linear = data.qvel[self._dof : self._dof + 3].copy()
            angular = r @ data.qvel[self._dof + 3 : self._dof + 6]
            return BodyState(pos, r, quat, linear, angular)
        b = self.body
        pos = data.xpos[b].copy()
        r = data.xmat[b].reshape(3, 3).copy()
        velocity = np.empty(6)
        mujoco.mj_objectVelocity(self.model, data, mujoco.mjtObj.mjOBJ_BODY, b, velocity, 0)
        # mj_objectVelocity reports the velocity of the centre of mass; move it to the origin:
        # + angular x offset, written out in floats (np.cross costs ~100 us here)
        wx, wy, wz, vx, vy, vz = velocity.tolist()
        ox, oy, oz = (pos - data.xipos[b]).tolist()
        linear = np.array(
            [vx + (wy * oz - wz * oy), vy + (wz * ox - wx * oz), vz + (wx * oy - wy * ox)]
        )
        return BodyState(pos, r, data.xquat[b].copy(), linear, velocity[:3])
