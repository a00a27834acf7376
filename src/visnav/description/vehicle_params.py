"""Vehicle parameters a robot description carries for the simulator's controllers.

:class:`QuadrotorParams` are the children of ``<plugin filename="libvisnav_quadrotor.so">``
(:func:`visnav.description.gazebo.parse_gazebo_extensions` validates them while parsing;
:class:`visnav.sim.vehicles.quadrotor.QuadrotorController` flies with them). Plain data,
no MuJoCo.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from visnav.description.errors import QuadrotorParamsError

__all__ = ["QuadrotorParams"]

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, kw_only=True)
class QuadrotorParams:
    """Physical limits of the vehicle (mass and inertia come from the MuJoCo model).

    Attributes:
        max_thrust: Collective thrust limit (N).
        max_moment: Body moment limits about x, y, z (N m).
        max_tilt: Largest tilt of the commanded thrust from vertical (rad).
        motor_time_constant: First-order lag of thrust and moments (s); 0 = none.
        disturbance_std: Standard deviation of a random world-frame force applied
            each physics step (N); drawn from a generator seeded by the controller.
    """

    max_thrust: float = 25.0
    max_moment: Vec3 = (1.5, 1.5, 0.4)
    max_tilt: float = math.radians(45.0)
    motor_time_constant: float = 0.0
    disturbance_std: float = 0.0

    def __post_init__(self) -> None:
        checks = (
            ("max_thrust", (self.max_thrust,), "> 0 N"),
            ("max_moment", self.max_moment, "> 0 N m"),
        )
        for name, values, expected in checks:
            if not all(math.isfinite(v) and v > 0 for v in values):
                msg = f"quadrotor: {name} must be {expected}, got {list(values)}"
                raise QuadrotorParamsError(msg)
        if not 0 < self.max_tilt < math.pi / 2:
            msg = f"quadrotor: max_tilt must be in (0, pi/2) rad, got {self.max_tilt}"
            raise QuadrotorParamsError(msg)
        for name, value in (
            ("motor_time_constant", self.motor_time_constant),
            ("disturbance_std", self.disturbance_std),
        ):
            if not (math.isfinite(value) and value >= 0):
                msg = f"quadrotor: {name} must be >= 0, got {value}"
                raise QuadrotorParamsError(msg)

    @classmethod
    def from_plugin_params(cls, params: Mapping[str, str]) -> QuadrotorParams:
        """Read the ``<plugin filename="libvisnav_quadrotor.so">`` children (text values).

        Recognised: ``max_thrust``, ``max_moment`` ("x y z"), ``max_tilt``,
        ``motor_time_constant``, ``disturbance_std``. Unknown names raise.

        Raises:
            QuadrotorParamsError: An unknown name or a value that is not a number.
        """
        known = {"max_thrust", "max_moment", "max_tilt", "motor_time_constant", "disturbance_std"}
        kwargs: dict[str, object] = {}
        for name, text in params.items():
            if name not in known:
                msg = f"quadrotor plugin: unknown parameter <{name}>; known: {sorted(known)}"
                raise QuadrotorParamsError(msg)
            try:
                values = [float(v) for v in text.split()]
            except ValueError:
                msg = f"quadrotor plugin: <{name}> must be numbers, got {text!r}"
                raise QuadrotorParamsError(msg) from None
            expected = 3 if name == "max_moment" else 1
            if len(values) != expected:
                msg = f"quadrotor plugin: <{name}> needs {expected} number(s), got {text!r}"
                raise QuadrotorParamsError(msg)
            kwargs[name] = tuple(values) if expected == 3 else values[0]
        return cls(**kwargs)  # type: ignore[arg-type]
