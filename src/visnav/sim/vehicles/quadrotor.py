"""A quadrotor: a free rigid body driven by collective thrust and body moments, SO(3)-controlled.

The controller is the geometric tracking controller of Lee, Leok and
McClamroch (2010), in the form ZJU FAST-Lab's ``so3_control`` and
``so3_quadrotor_simulator`` use with ego-planner:

* position loop (world frame, z up)::

      F = m * (kx * (p_des - p) + kv * (v_des - v) + a_des + g * e3)

  with the tilt of ``F`` limited to ``max_tilt`` (the horizontal part is scaled
  down, the vertical part kept); a NaN in ``position``, ``velocity`` or
  ``acceleration`` of the command drops that term, as in ``so3_control``;
* desired attitude: ``b3 = F / |F|``, ``b2 = b3 x [cos yaw, sin yaw, 0]``
  normalised, ``b1 = b2 x b3``;
* thrust ``f = F . (R e3)`` in ``[0, max_thrust]``; moments
  ``M = J (-kR e_R - kOm e_Om) + Om x J Om`` with
  ``e_R = vee(Rd^T R - R^T Rd) / 2``, ``e_Om = Om - R^T Rd Om_d`` and
  ``Om_d = (0, 0, yaw_dot)`` in the desired frame, each axis limited to
  ``max_moment``.

visnav's gains are normalised (``kx``, ``kv`` are accelerations per metre and
per m/s; ``kR``, ``kOm`` angular accelerations per radian and per rad/s), so they
hold for any mass and inertia. A :class:`PositionCommand` with non-zero ``kx`` /
``kv`` overrides them with ``so3_control``'s force gains (N/m, N s/m), divided by
the mass. Thrust and moments optionally pass a first-order motor lag and a
seeded random force disturbance, then act on the body through
``data.xfrc_applied`` (world-frame force and torque at the body's centre of
mass), so any free-floating MuJoCo body can fly, including one loaded from the
built-in ``quadrotor.urdf.xacro``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from visnav.description.vehicle_params import QuadrotorParams
from visnav.sim.errors import QuadrotorError
from visnav.sim.vehicles._state import BodyReader
from visnav.tf.transforms import yaw_from_matrix

if TYPE_CHECKING:
    import mujoco
    import numpy.typing as npt

    from visnav.sim.rebind import IdMap

__all__ = [
    "ControlOutput",
    "PositionCommand",
    "QuadrotorController",
    "QuadrotorError",
    "QuadrotorParams",
    "QuadrotorState",
    "SO3Gains",
    "add_quadrotor",
    "so3_control",
]

Vec3 = tuple[float, float, float]
GRAVITY = 9.81


@dataclass(frozen=True, kw_only=True)
class PositionCommand:
    """The shape of ``quadrotor_msgs/PositionCommand`` (ZJU FAST-Lab), world frame.

    Attributes:
        stamp_ns: Time of the command (ns).
        frame_id: Frame of the references (``world``).
        position: Desired position (m); NaN drops the position term.
        velocity: Desired velocity (m/s); NaN drops the velocity term.
        acceleration: Desired (feed-forward) acceleration (m/s^2); NaN drops it.
        jerk: Desired jerk (m/s^3); carried, not used by the controller.
        yaw: Desired yaw (rad).
        yaw_dot: Desired yaw rate (rad/s).
        kx: ``so3_control`` position gains (N/m); all zero = controller defaults.
        kv: ``so3_control`` velocity gains (N s/m); all zero = controller defaults.
        trajectory_id: Trajectory id (starts at 1).
        trajectory_flag: One of the ``TRAJECTORY_STATUS_*`` constants.
    """

    TRAJECTORY_STATUS_EMPTY: ClassVar[int] = 0
    TRAJECTORY_STATUS_READY: ClassVar[int] = 1
    TRAJECTORY_STATUS_COMPLETED: ClassVar[int] = 3
    TRAJECTORY_STATUS_ABORT: ClassVar[int] = 4
    TRAJECTORY_STATUS_ILLEGAL_START: ClassVar[int] = 5
    TRAJECTORY_STATUS_ILLEGAL_FINAL: ClassVar[int] = 6
    TRAJECTORY_STATUS_IMPOSSIBLE: ClassVar[int] = 7

    stamp_ns: int = 0
    frame_id: str = "world"
    position: Vec3 = (0.0, 0.0, 0.0)
    velocity: Vec3 = (0.0, 0.0, 0.0)
    acceleration: Vec3 = (0.0, 0.0, 0.0)
    jerk: Vec3 = (0.0, 0.0, 0.0)
    yaw: float = 0.0
    yaw_dot: float = 0.0
    kx: Vec3 = (0.0, 0.0, 0.0)
    kv: Vec3 = (0.0, 0.0, 0.0)
    trajectory_id: int = 0
    trajectory_flag: int = 0

    @classmethod
    def hold(cls, position: Vec3, yaw: float = 0.0, *, stamp_ns: int = 0) -> PositionCommand:
        """A command that hovers at ``position`` with heading ``yaw``."""
        return cls(stamp_ns=stamp_ns, position=position, yaw=yaw)


@dataclass(frozen=True, kw_only=True)
class SO3Gains:
    """Normalised gains (see the module docstring)."""

    kx: Vec3 = (5.8, 5.8, 6.3)
    kv: Vec3 = (3.5, 3.5, 4.1)
    kR: Vec3 = (400.0, 400.0, 100.0)  # noqa: N815  (the paper's name)
    kOm: Vec3 = (40.0, 40.0, 20.0)  # noqa: N815


@dataclass(frozen=True)
class QuadrotorState:
    """Rigid-body state: position, velocity (world), rotation (world <- body), body rates."""

    position: npt.NDArray[np.float64]
    velocity: npt.NDArray[np.float64]
    rotation: npt.NDArray[np.float64]
    angular_velocity: npt.NDArray[np.float64]


@dataclass(frozen=True)
class ControlOutput:
    """Controller output: thrust (N), body moments (N m), desired force and attitude."""

    thrust: float
    moments: npt.NDArray[np.float64]
    force: npt.NDArray[np.float64] = field(repr=False)
    desired_rotation: npt.NDArray[np.float64] = field(repr=False)


def _vee(m: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    return np.array([m[2, 1], m[0, 2], m[1, 0]])


def _cross(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    # np.cross costs ~30 us per call on 3-vectors; this is ~1 us
    out: npt.NDArray[np.float64] = np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )
    return out


def _limit_tilt(force: npt.NDArray[np.float64], max_tilt: float) -> npt.NDArray[np.float64]:
    vertical = max(float(force[2]), 1e-6)
    horizontal = float(np.hypot(force[0], force[1]))
    limit = vertical * math.tan(max_tilt)
    out: npt.NDArray[np.float64] = force.copy()
    out[2] = vertical
    if horizontal > limit:
        out[:2] *= limit / horizontal
    return out


def so3_control(
    state: QuadrotorState,
    command: PositionCommand,
    *,
    mass: float,
    inertia: npt.NDArray[np.float64],
    gains: SO3Gains,
    params: QuadrotorParams,
    gravity: float = GRAVITY,
) -> ControlOutput:
    """One evaluation of the geometric controller (pure function of its inputs).

    Args:
        state: The vehicle state.
        command: The references.
        mass: Vehicle mass (kg).
        inertia: ``(3, 3)`` inertia about the centre of mass, body frame (kg m^2).
        gains: Normalised gains.
        params: Limits.
        gravity: Gravity magnitude (m/s^2), acting along -z.

    Returns:
        Thrust, moments (limited), the desired force and the desired rotation.
    """
    kx = np.asarray(gains.kx, dtype=np.float64)
    kv = np.asarray(gains.kv, dtype=np.float64)
    if any(abs(k) > 1e-5 for k in command.kx):
        kx = np.asarray(command.kx, dtype=np.float64) / mass
    if any(abs(k) > 1e-5 for k in command.kv):
        kv = np.asarray(command.kv, dtype=np.float64) / mass
    acc = np.array([0.0, 0.0, gravity])
    p_des = np.asarray(command.position, dtype=np.float64)
    v_des = np.asarray(command.velocity, dtype=np.float64)
    a_des = np.asarray(command.acceleration, dtype=np.float64)
    if not np.isnan(p_des).any():
        acc += kx * (p_des - state.position)
    if not np.isnan(v_des).any():
        acc += kv * (v_des - state.velocity)
    if not np.isnan(a_des).any():
        acc += a_des
    force = _limit_tilt(mass * acc, params.max_tilt)

    b3 = force / np.linalg.norm(force)
    heading = np.array([math.cos(command.yaw), math.sin(command.yaw), 0.0])
    b2 = _cross(b3, heading)
    norm = np.linalg.norm(b2)
    b2 = b2 / norm if norm > 1e-9 else state.rotation[:, 1]
    b1 = _cross(b2, b3)
    r_des = np.column_stack([b1, b2, b3])

    rot = state.rotation
    thrust = float(np.clip(force @ rot[:, 2], 0.0, params.max_thrust))
    e_r = 0.5 * _vee(r_des.T @ rot - rot.T @ r_des)
    omega = state.angular_velocity
    omega_des = np.array([0.0, 0.0, command.yaw_dot])
    e_om = omega - rot.T @ r_des @ omega_des
    k_r = np.asarray(gains.kR, dtype=np.float64)
    k_om = np.asarray(gains.kOm, dtype=np.float64)
    moments = inertia @ (-k_r * e_r - k_om * e_om) + _cross(omega, inertia @ omega)
    limit = np.asarray(params.max_moment, dtype=np.float64)
    return ControlOutput(
        thrust=thrust,
        moments=np.clip(moments, -limit, limit),
        force=force,
        desired_rotation=r_des,
    )


def _subtree(model: mujoco.MjModel, root: int) -> list[int]:
    return [b for b in range(model.nbody) if b == root or _is_descendant(model, b, root)]


def _is_descendant(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body > 0:
        body = int(model.body_parentid[body])
        if body == root:
            return True
    return False


class QuadrotorController:
    """Flies a free-floating MuJoCo body with :func:`so3_control`.

    Mass and inertia are the composite of the body and everything attached to
    it, taken from the model. Call :meth:`set_command` when a command arrives and
    :meth:`step` before every physics step.

    Args:
        model: The compiled model.
        body: MuJoCo name of the vehicle's root body (it must have a free joint).
        params: Limits, motor lag and disturbance.
        gains: Normalised controller gains.
        seed: Seed of the disturbance generator.

    Raises:
        QuadrotorError: The body is missing, not free-floating, or massless.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        body: str,
        params: QuadrotorParams | None = None,
        gains: SO3Gains | None = None,
        seed: int = 0,
    ) -> None:
        import mujoco  # noqa: PLC0415  (keep module import light)

        self._mujoco = mujoco
        self.model = model
        self.params = params or QuadrotorParams()
        self.gains = gains or SO3Gains()
        self.body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        if self.body < 0:
            msg = f"quadrotor: body {body!r} is not in the MuJoCo model"
            raise QuadrotorError(msg)
        if not BodyReader(model, self.body).free:
            msg = f"quadrotor: body {body!r} must be a child of the world with a free joint"
            raise QuadrotorError(msg)
        self._reader = BodyReader(model, self.body)
        self.mass, self.inertia = self._composite_inertia()
        if self.mass <= 0:
            msg = f"quadrotor: body {body!r} has no mass; give its links inertials"
            raise QuadrotorError(msg)
        self.gravity = float(-model.opt.gravity[2])
        self.command: PositionCommand | None = None
        self._rng = np.random.default_rng(seed)
        self._applied = np.zeros(4)  # thrust, moments after the motor lag
        self.last_output: ControlOutput | None = None

    def rebind(self, ids: IdMap) -> None:
        """Fly the same body of a recompiled model; command and motor state are kept."""
        self.model = ids.model
        self.body = ids.body(self.body)
        self._reader.rebind(ids)

    def _composite_inertia(self) -> tuple[float, npt.NDArray[np.float64]]:
        mujoco = self._mujoco
        data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, data)
        bodies = _subtree(self.model, self.body)
        masses = self.model.body_mass[bodies]
        total = float(masses.sum())
        if total <= 0:
            return 0.0, np.zeros((3, 3))
        com = (masses[:, None] * data.xipos[bodies]).sum(axis=0) / total
        rot_root = data.xmat[self.body].reshape(3, 3)
        inertia = np.zeros((3, 3))
        for b, m in zip(bodies, masses, strict=True):
            rot = data.ximat[b].reshape(3, 3)
            inertia += rot @ np.diag(self.model.body_inertia[b]) @ rot.T
            r = data.xipos[b] - com
            inertia += m * (float(r @ r) * np.eye(3) - np.outer(r, r))
        return total, rot_root.T @ inertia @ rot_root

    def set_command(self, command: PositionCommand) -> None:
        """Track ``command`` from now on."""
        self.command = command

    def state(self, data: mujoco.MjData) -> QuadrotorState:
        """The vehicle state from ``qpos`` / ``qvel`` (body frame origin, world frame)."""
        body = self._reader.read(data)
        return QuadrotorState(
            position=body.position,
            velocity=body.linear,
            rotation=body.rotation,
            angular_velocity=body.rotation.T @ body.angular,
        )

    def step(self, data: mujoco.MjData) -> ControlOutput | None:
        """Compute and apply thrust and moments; call before every physics step.

        Without a command yet, the vehicle holds the position and yaw it has
        at the first call (as ``so3_control`` does with its initial state).

        Returns:
            The controller output.
        """
        state = self.state(data)
        if self.command is None:
            yaw = yaw_from_matrix(state.rotation)
            p = state.position
            self.command = PositionCommand.hold((float(p[0]), float(p[1]), float(p[2])), yaw)
        output = so3_control(
            state,
            self.command,
            mass=self.mass,
            inertia=self.inertia,
            gains=self.gains,
            params=self.params,
            gravity=self.gravity,
        )
        target = np.concatenate([[output.thrust], output.moments])
        tau = self.params.motor_time_constant
        if self.last_output is None:
            self._applied = target  # motors start at the first command (no spin-up)
        elif tau > 0:
            alpha = min(1.0, float(self.model.opt.timestep) / tau)
            self._applied += alpha * (target - self._applied)
        else:
            self._applied = target
        force = state.rotation[:, 2] * self._applied[0]
        if self.params.disturbance_std > 0:
            force = force + self._rng.normal(0.0, self.params.disturbance_std, 3)
        data.xfrc_applied[self.body, :3] = force
        data.xfrc_applied[self.body, 3:] = state.rotation @ self._applied[1:]
        self.last_output = output
        return output


def add_quadrotor(
    spec: mujoco.MjSpec,
    *,
    name: str = "quadrotor",
    pos: Vec3 = (0.0, 0.0, 1.0),
    yaw: float = 0.0,
    mass: float = 0.98,
    inertia: Vec3 = (0.0025, 0.0025, 0.0043),
    arm_length: float = 0.17,
) -> str:
    """Add a quadrotor body (free joint, box body, four rotor discs) to a spec.

    The same geometry as ``description/robots/quadrotor.urdf.xacro``, without its
    sensors, for tests and scripts that need a flying body without a URDF.

    Args:
        spec: The spec (a world spec, for example).
        name: Body name (also the prefix of its geoms and joint).
        pos: Initial position (m).
        yaw: Initial heading (rad).
        mass: Mass (kg).
        inertia: Principal moments about x, y, z (kg m^2).
        arm_length: Rotor arm length (m).

    Returns:
        The body name, for :class:`QuadrotorController`.
    """
    import mujoco  # noqa: PLC0415

    half = 0.5 * yaw
    body = spec.worldbody.add_body(
        name=name, pos=list(pos), quat=[math.cos(half), 0.0, 0.0, math.sin(half)]
    )
    body.add_freejoint(name=f"{name}:free")
    body.explicitinertial = True
    body.mass = mass
    body.inertia = list(inertia)
    body.ipos = [0.0, 0.0, 0.0]
    body.add_geom(
        name=f"{name}:frame",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[0.08, 0.08, 0.03],
        rgba=[0.2, 0.2, 0.25, 1.0],
    )
    for i in range(4):
        angle = math.pi / 4 + i * math.pi / 2
        x, y = arm_length * math.cos(angle), arm_length * math.sin(angle)
        body.add_geom(
            name=f"{name}:arm{i}",
            type=mujoco.mjtGeom.mjGEOM_CAPSULE,
            fromto=[0.0, 0.0, 0.0, x, y, 0.0],
            size=[0.01, 0.0, 0.0],
            rgba=[0.3, 0.3, 0.3, 1.0],
        )
        body.add_geom(
            name=f"{name}:rotor{i}",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            pos=[x, y, 0.03],
            size=[0.06, 0.005, 0.0],
            rgba=[0.8, 0.1, 0.1, 0.6] if i < 2 else [0.1, 0.1, 0.8, 0.6],
            contype=0,
            conaffinity=0,
        )
    return name
