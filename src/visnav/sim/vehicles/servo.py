"""The velocity servo that turns a joint velocity command into a joint torque each physics step.

Gazebo's wheel plugins and gazebo_ros_control set a joint motor's velocity (ODE's ``fmax``
bounded motor); MuJoCo has no such motor, so the diff drive and ros_control drive their joints
through ``qfrc_applied`` with a PI servo: the P part is a fraction of the one-step (deadbeat)
correction of the joint's own inertia (``dof_M0 / timestep``), the I part removes the steady
error under load (ground contact, scrubbing); both saturate at the joint's torque limit, so the
integral cannot wind up.

The servo runs once per physics step on a few joints, so it works on Python floats rather than
small numpy arrays (a quarter of the cost) with the same operations in the same order.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import mujoco

    from visnav.sim.rebind import IdMap

__all__ = ["GAIN", "INTEGRAL_TIME", "VelocityServo"]

GAIN = 0.9
"""Fraction of the one-step (deadbeat) velocity correction applied per physics step."""
INTEGRAL_TIME = 0.05
"""Integral time of the servo (s)."""


class VelocityServo:
    """PI velocity servo on a set of MuJoCo degrees of freedom.

    Args:
        model: the compiled model (its timestep and the joints' ``dof_M0``).
        dofs: the degrees of freedom driven (``jnt_dofadr`` of each joint).
        limits: the torque limit of each (``inf``: none).
    """

    def __init__(self, model: mujoco.MjModel, dofs: Sequence[int], limits: Sequence[float]) -> None:
        if len(limits) != len(dofs):
            msg = f"{len(limits)} torque limits for {len(dofs)} joints"
            raise ValueError(msg)
        timestep = float(model.opt.timestep)
        self.dofs = [int(d) for d in dofs]
        self._gain = [GAIN * float(model.dof_M0[d]) / timestep for d in self.dofs]
        self._integral_step = timestep / INTEGRAL_TIME
        self._limits = [float(limit) for limit in limits]
        self.integral = [0.0] * len(self.dofs)

    def rebind(self, ids: IdMap) -> None:
        """Drive the same joints of a recompiled model (integrals kept)."""
        self.dofs = [int(d) for d in ids.dof(self.dofs)]

    def reset(self) -> None:
        """Forget the integral (a new command history)."""
        self.integral = [0.0] * len(self.dofs)

    def apply(self, data: mujoco.MjData, targets: Sequence[float]) -> None:
        """Write the torques that drive each joint towards its target velocity (rad/s or m/s)."""
        qvel = data.qvel
        torque = data.qfrc_applied
        step = self._integral_step
        for k, dof in enumerate(self.dofs):
            limit = self._limits[k]
            gain = self._gain[k]
            error = targets[k] - float(qvel[dof])
            integral = min(max(self.integral[k] + gain * error * step, -limit), limit)
            self.integral[k] = integral
            torque[dof] = min(max(gain * error + integral, -limit), limit)
