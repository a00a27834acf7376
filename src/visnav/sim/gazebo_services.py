"""gazebo_ros_api_plugin's services on the simulator's node (``/gazebo/...``).

Every :class:`~visnav.sim.simulator.Simulator` serves, on its own node (``/sim``, or
``/gazebo`` when a roslaunch file's gazebo_ros node became it; the names are absolute
either way), on the context's executor like every other callback:

=================================  ==============================  ===========================
name                               type                            does
=================================  ==============================  ===========================
``/gazebo/reset_world``            ``std_srvs/srv/Empty``          robots back to their spawn
                                                                   poses, velocities zero,
                                                                   plugins reset; time runs on
``/gazebo/reset_simulation``       ``std_srvs/srv/Empty``          the same, and sim time back
                                                                   to 0 (``/clock`` too)
``/gazebo/pause_physics``          ``std_srvs/srv/Empty``          stop stepping: ``/clock``
                                                                   stands still, callbacks run
``/gazebo/unpause_physics``        ``std_srvs/srv/Empty``          step again (no catching up)
``/gazebo/get_model_state``        ``gazebo_msgs/srv/              pose and twist of a model,
                                   GetModelState``                 optionally relative to an
                                                                   entity
``/gazebo/set_model_state``        ``gazebo_msgs/srv/              move a robot (pose, twist)
                                   SetModelState``
``/gazebo/spawn_urdf_model``,      ``gazebo_msgs/srv/SpawnModel``  add a URDF or SDF model at
``/gazebo/spawn_sdf_model``                                        ``initial_pose`` (relative to
                                                                   ``reference_frame``), its
                                                                   plugins publishing under
                                                                   ``robot_namespace``
``/gazebo/delete_model``           ``gazebo_msgs/srv/DeleteModel`` remove a model, its plugins
                                                                   and their topics
=================================  ==============================  ===========================

Entities are named as in ``/gazebo/model_states`` and ``link_states``: a robot by its
name, ``ground_plane``, a link as ``model::link``; ``""``, ``world``, ``map`` and ``/map``
mean the world frame (gazebo_ros' own list). A pose or twist relative to an entity is
rotated into its frame and, for the twist, has the entity's velocity subtracted
(gazebo_ros' arithmetic, no cross term for a rotating frame). A quaternion of zeros
(what a request that leaves the orientation out carries) is the identity, as
gazebo_ros' normalisation makes it.

State changes asked for by a callback that runs inside a lock-step physics step are
applied at the end of that step (:meth:`Simulator.edit`), so MuJoCo never integrates a
half-computed step from a moved body; the reply is sent at once.

Where visnav differs from gazebo_ros:

* Spawning composes a new MuJoCo model (the world, the robots in order, the new one;
  :mod:`visnav.sim.rebind`), compiles it and builds the new model's plugins in the
  service callback (so a model MuJoCo or a plugin rejects is answered ``success: false``
  with the reason and the simulation is untouched), then moves the simulation onto it at
  the end of the step: every other body keeps its position and velocity, every plugin its
  state (odometry, commands, schedules, noise), sim time runs on. Gazebo inserts a model
  at once; visnav's compile takes a second or more (meshes are loaded again).
* ``model_xml`` must be URDF or SDF text: a file name or ``model://`` database name is
  refused (Gazebo's ``spawn_model -database`` is not served). An SDF model is rewritten
  into URDF (:mod:`visnav.description.sdf_model`): one tree of links; several unjoined
  links, nested models and ``<include>`` are refused. ``package://`` meshes resolve
  through ``ROS_PACKAGE_PATH`` / ``AMENT_PREFIX_PATH`` of the simulator's process.
* A spawned robot keeps the full ``initial_pose`` orientation when it floats; a robot
  fixed to the world (a ``world`` root link, a ``<static>`` SDF model) takes its yaw only.
* The world's own models (``ground_plane``, the shapes of the world file) cannot be
  deleted; robots started with the simulation can, as spawned ones.
* ``reset_simulation`` rewinds sim time to 0 as Gazebo does: ``/clock`` goes back, every
  sensor's and plugin's schedule restarts (:meth:`~visnav.sim.plugins.SimPlugin.rewind`);
  TF listeners clear their buffers on the jump ("Detected jump back in time") and timers
  re-arm, as in ROS. :attr:`~visnav.sim.simulator.Simulator.elapsed_ns` (durations,
  real-time pacing) does not go back.
* Only robots with a free-floating base can be moved; the world's static shapes are not
  models (as in ``model_states``). A position beyond :data:`MAX_POSITION_M` or a velocity
  beyond :data:`MAX_SPEED` is refused (Gazebo takes it and its physics blows up; visnav's
  instability guard would stop the simulation).
* ros_control controllers keep their odometry over a reset (gazebo_ros_control does not
  reset controllers either); the diff drive and skid steer plugins zero their command and
  encoder odometry, as gazebo_ros_diff_drive's ``Reset()`` does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import numpy.typing as npt

from visnav.description.sdf_model import is_sdf, sdf_model_to_urdf
from visnav.errors import VisnavError
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Point, Pose, Quaternion, Twist, Vector3
from visnav.sim.rebind import IdMap, transfer_state
from visnav.sim.sim_robots import RobotSpawn

if TYPE_CHECKING:
    from visnav.graph.service import Service
    from visnav.sim.simulator import SimRobot, Simulator

__all__ = [
    "GAZEBO_SERVICE_NAMES",
    "MAX_POSITION_M",
    "MAX_SPEED",
    "WORLD_FRAMES",
    "EntityState",
    "GazeboServices",
]

GAZEBO_SERVICE_NAMES: dict[str, str] = {
    "/gazebo/reset_world": "std_srvs/srv/Empty",
    "/gazebo/reset_simulation": "std_srvs/srv/Empty",
    "/gazebo/pause_physics": "std_srvs/srv/Empty",
    "/gazebo/unpause_physics": "std_srvs/srv/Empty",
    "/gazebo/get_model_state": "gazebo_msgs/srv/GetModelState",
    "/gazebo/set_model_state": "gazebo_msgs/srv/SetModelState",
    "/gazebo/spawn_urdf_model": "gazebo_msgs/srv/SpawnModel",
    "/gazebo/spawn_sdf_model": "gazebo_msgs/srv/SpawnModel",
    "/gazebo/delete_model": "gazebo_msgs/srv/DeleteModel",
}
"""Service name -> type, as gazebo_ros_api_plugin (ROS 1) names them."""

WORLD_FRAMES = frozenset({"", "world", "map", "/map"})
"""Reference names that mean the world frame (gazebo_ros' list)."""

MAX_POSITION_M = 1e6
"""``set_model_state`` refuses a coordinate farther out (float precision, MuJoCo's limits)."""
MAX_SPEED = 1e3
"""``set_model_state`` refuses a faster linear (m/s) or angular (rad/s) velocity component."""

_STATE = mujoco.mjtState.mjSTATE_PHYSICS | mujoco.mjtState.mjSTATE_USER
_Vec = npt.NDArray[np.float64]


@dataclass(frozen=True)
class EntityState:
    """World pose and velocity of an entity (a model's root link, a link, the ground).

    Attributes:
        rotation: 3x3 rotation, entity frame -> world.
        position: origin in the world (m).
        linear: velocity of the origin in the world frame (m/s).
        angular: angular velocity in the world frame (rad/s).
    """

    rotation: _Vec
    position: _Vec
    linear: _Vec
    angular: _Vec


_ORIGIN = EntityState(np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3))


def _vector(v: Any) -> _Vec:
    return np.array([float(v.x), float(v.y), float(v.z)], dtype=np.float64)


def _rotation(q: Any) -> tuple[_Vec, str]:
    """A message quaternion (x, y, z, w) as a rotation matrix, or an error text."""
    xyzw = np.array([float(q.x), float(q.y), float(q.z), float(q.w)], dtype=np.float64)
    if not np.all(np.isfinite(xyzw)):
        return np.eye(3), f"orientation {xyzw.tolist()} is not finite"
    norm = float(np.linalg.norm(xyzw))
    if norm == 0.0:  # left out of the request: gazebo_ros normalises it to the identity
        return np.eye(3), ""
    x, y, z, w = xyzw / norm
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.array([w, x, y, z]))
    return mat.reshape(3, 3), ""


def _quat_xyzw(rotation: _Vec) -> tuple[float, float, float, float]:
    wxyz = np.zeros(4)
    mujoco.mju_mat2Quat(wxyz, np.ascontiguousarray(rotation, dtype=np.float64).reshape(9))
    return float(wxyz[1]), float(wxyz[2]), float(wxyz[3]), float(wxyz[0])


def _pose(rotation: _Vec, position: _Vec) -> Pose:
    x, y, z, w = _quat_xyzw(rotation)
    return Pose(position=Point(*(float(v) for v in position)), orientation=Quaternion(x, y, z, w))


def _twist(linear: _Vec, angular: _Vec) -> Twist:
    return Twist(
        linear=Vector3(*(float(v) for v in linear)),
        angular=Vector3(*(float(v) for v in angular)),
    )


class GazeboServices:
    """The ``/gazebo/*`` services of a simulator (see the module docstring).

    Args:
        sim: the simulator, fully built (its robots placed and at rest): its physics
            state now is what ``reset_world`` returns to.
    """

    def __init__(self, sim: Simulator) -> None:
        self._sim = sim
        model = sim.model
        self._initial = np.zeros(mujoco.mj_stateSize(model, _STATE))
        mujoco.mj_getState(model, sim.data, self._initial, _STATE)
        node = sim.node
        self.resets = 0
        callbacks = {
            "/gazebo/reset_world": self._on_reset_world,
            "/gazebo/reset_simulation": self._on_reset_simulation,
            "/gazebo/pause_physics": self._on_pause,
            "/gazebo/unpause_physics": self._on_unpause,
            "/gazebo/get_model_state": self._on_get_model_state,
            "/gazebo/set_model_state": self._on_set_model_state,
            "/gazebo/spawn_urdf_model": self._on_spawn,
            "/gazebo/spawn_sdf_model": self._on_spawn,
            "/gazebo/delete_model": self._on_delete,
        }
        self._services: list[Service[Any, Any]] = [
            node.create_service(get_service_type(GAZEBO_SERVICE_NAMES[name]), name, callback)
            for name, callback in callbacks.items()
        ]

    def close(self) -> None:
        """Remove the services from the simulator's node."""
        for service in self._services:
            self._sim.node.destroy_service(service)
        self._services.clear()

    # ------------------------------------------------------------------ operations

    def reset_world(self) -> None:
        """Every body back to its state at start, velocities zero, plugins reset.

        Sim time is not changed. Call it between steps (the services go through
        :meth:`Simulator.edit`).
        """
        sim = self._sim
        model, data = sim.model, sim.data
        mujoco.mj_setState(model, data, self._initial, _STATE)
        data.qacc_warmstart[:] = 0.0
        mujoco.mj_forward(model, data)
        for robot in sim.robots:
            for plugin in robot.plugins:
                plugin.reset(data, sim.now_ns)
        self.resets += 1

    def entity(self, name: str) -> EntityState | None:
        """World state of ``name``, or None when there is no such entity.

        ``name`` is a model, ``model::link``, ``ground_plane`` or a world name.
        """
        sim = self._sim
        if name in WORLD_FRAMES:
            return _ORIGIN
        if sim.world.ground is not None and name in ("ground_plane", "ground_plane::link"):
            return _ORIGIN
        model_name, sep, link = name.partition("::")
        robot = self._robot(model_name)
        if robot is None:
            return None
        if not sep:
            body = robot.handles.root_body
        elif link in robot.handles.bodies:
            body = robot.handles.bodies[link]
        else:
            return None
        return self._body_state(body)

    def _body_state(self, body: str) -> EntityState:
        model, data = self._sim.model, self._sim.data
        b = model.body(body).id
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, b, velocity, 0)
        return EntityState(
            rotation=np.array(data.xmat[b], dtype=np.float64).reshape(3, 3),
            position=np.array(data.xpos[b], dtype=np.float64),
            linear=velocity[3:].copy(),
            angular=velocity[:3].copy(),
        )

    def _robot(self, name: str) -> SimRobot | None:
        for robot in self._sim.robots:
            if robot.name == name:
                return robot
        return None

    def _models(self) -> list[str]:
        names = ["ground_plane"] if self._sim.world.ground is not None else []
        return names + [r.name for r in self._sim.robots]

    def get_model_state(self, model_name: str, relative_entity_name: str) -> tuple[Any, str]:
        """Pose and twist of a model relative to an entity.

        Returns:
            ``(pose, twist)`` as a :class:`EntityState` in the entity's frame and ``""``,
            or ``(None, error text)``.
        """
        if model_name not in self._models():
            known = ", ".join(self._models())
            return None, f"GetModelState: model [{model_name}] does not exist (models: {known})"
        state = self.entity(model_name)
        frame = self.entity(relative_entity_name)
        if state is None or frame is None:
            return None, (
                f"GetModelState: reference relative_entity_name [{relative_entity_name}] not "
                "found, did you forget to scope the body by model name (model::link)?"
            )
        rt = frame.rotation.T
        return EntityState(
            rotation=rt @ state.rotation,
            position=rt @ (state.position - frame.position),
            linear=rt @ (state.linear - frame.linear),
            angular=rt @ (state.angular - frame.angular),
        ), ""

    def set_model_state(self, state: Any) -> tuple[bool, str]:
        """Move a robot as a ``gazebo_msgs/ModelState`` says (through :meth:`Simulator.edit`).

        Returns:
            ``(success, status_message)``.
        """
        name = str(state.model_name)
        robot = self._robot(name)
        if robot is None:
            if name in self._models():
                return False, f"SetModelState: model [{name}] is static and cannot be moved"
            known = ", ".join(self._models())
            return False, f"SetModelState: model [{name}] does not exist (models: {known})"
        free = robot.handles.free_joint
        if free is None:
            return False, (
                f"SetModelState: model [{name}] is fixed to the world (its root link has no "
                "floating base), so visnav cannot move it"
            )
        frame = self.entity(str(state.reference_frame))
        if frame is None:
            return False, (
                f"SetModelState: specified reference frame entity [{state.reference_frame}] "
                "does not exist (a model, model::link, or ''/world for the world)"
            )
        rotation, error = _rotation(state.pose.orientation)
        position = _vector(state.pose.position)
        linear, angular = _vector(state.twist.linear), _vector(state.twist.angular)
        values = np.concatenate([position, linear, angular])
        if error or not np.all(np.isfinite(values)):
            what = error or f"pose/twist {values.tolist()} has a value that is not finite"
            return False, f"SetModelState: model [{name}]: {what}"
        if np.abs(position).max() > MAX_POSITION_M or np.abs(values[3:]).max() > MAX_SPEED:
            return False, (
                f"SetModelState: model [{name}]: position {position.tolist()} or twist "
                f"{values[3:].tolist()} is beyond what the simulation can integrate "
                f"(|position| <= {MAX_POSITION_M:g} m, |velocity| <= {MAX_SPEED:g} m/s or rad/s)"
            )
        target = EntityState(
            rotation=frame.rotation @ rotation,
            position=frame.position + frame.rotation @ position,
            linear=frame.rotation @ linear,
            angular=frame.rotation @ angular,
        )
        sim = self._sim
        qadr = int(sim.model.joint(free).qposadr[0])
        dadr = int(sim.model.joint(free).dofadr[0])

        def move() -> None:
            model, data = sim.model, sim.data
            wxyz = np.zeros(4)
            mujoco.mju_mat2Quat(wxyz, np.ascontiguousarray(target.rotation).reshape(9))
            data.qpos[qadr : qadr + 3] = target.position
            data.qpos[qadr + 3 : qadr + 7] = wxyz
            data.qvel[dadr : dadr + 3] = target.linear  # MuJoCo: world frame
            data.qvel[dadr + 3 : dadr + 6] = target.rotation.T @ target.angular  # body frame
            mujoco.mj_forward(model, data)

        sim.edit(move)
        return True, "SetModelState: set model state done"

    # ------------------------------------------------------------------ callbacks

    def _on_reset_world(self, request: Any, response: Any) -> Any:
        del request
        self._sim.edit(self.reset_world)
        return response

    def reset_simulation(self) -> None:
        """Gazebo's ``reset_simulation``: sim time back to 0, then :meth:`reset_world`.

        Call it between steps (the service goes through :meth:`Simulator.edit`).
        """
        self._sim.rewind()
        self.reset_world()

    def _on_reset_simulation(self, request: Any, response: Any) -> Any:
        del request
        self._sim.edit(self.reset_simulation)
        return response

    def _on_pause(self, request: Any, response: Any) -> Any:
        del request
        self._sim.pause()
        return response

    def _on_unpause(self, request: Any, response: Any) -> Any:
        del request
        self._sim.unpause()
        return response

    def _on_get_model_state(self, request: Any, response: Any) -> Any:
        relative = str(request.relative_entity_name)
        response.header.stamp = ns_to_time(self._sim.now_ns)
        response.header.frame_id = relative
        state, error = self.get_model_state(str(request.model_name), relative)
        if state is None:
            response.success = False
            response.status_message = error
            return response
        response.pose = _pose(state.rotation, state.position)
        response.twist = _twist(state.linear, state.angular)
        response.success = True
        response.status_message = "GetModelState: got properties"
        return response

    def _on_set_model_state(self, request: Any, response: Any) -> Any:
        response.success, response.status_message = self.set_model_state(request.model_state)
        return response

    def rebind(self, old_model: mujoco.MjModel, ids: IdMap) -> None:
        """Carry the reset state onto a recompiled model (a model was spawned or deleted).

        Surviving bodies keep their state at start; a spawned model's is its spawn pose.
        """
        old = mujoco.MjData(old_model)
        mujoco.mj_setState(old_model, old, self._initial, _STATE)
        new = mujoco.MjData(ids.model)
        transfer_state(old_model, old, ids, new)
        self._initial = np.zeros(mujoco.mj_stateSize(ids.model, _STATE))
        mujoco.mj_getState(ids.model, new, self._initial, _STATE)

    def spawn_model(self, request: Any) -> tuple[bool, str]:
        """Spawn a URDF or SDF model as a ``gazebo_msgs/srv/SpawnModel`` request says.

        Returns:
            ``(success, status_message)``.
        """
        xml = str(request.model_xml)
        name = str(request.model_name)
        if name and name in self._models():
            return False, f"SpawnModel: Failure - model name {name} already exists."
        if not xml.strip().startswith("<"):
            return False, (
                "SpawnModel: Failure - model_xml is not URDF or SDF XML text (visnav reads no "
                "file or database name from it: pass the file's contents)"
            )
        if "xmlns:xacro" in xml:
            return False, (
                "SpawnModel: Failure - model_xml is Xacro, which Gazebo does not expand either. "
                "Fix: send the expanded URDF (xacro FILE > model.urdf)"
            )
        frame = self.entity(str(request.reference_frame))
        if frame is None:
            return False, (
                f"SpawnModel: Failure - reference frame [{request.reference_frame}] not found "
                "(a model, model::link, or ''/world for the world)"
            )
        rotation, error = _rotation(request.initial_pose.orientation)
        position = _vector(request.initial_pose.position)
        if error or not np.all(np.isfinite(position)):
            what = error or f"position {position.tolist()} is not finite"
            return False, f"SpawnModel: Failure - initial_pose: {what}"
        if np.abs(position).max() > MAX_POSITION_M:
            return False, (
                f"SpawnModel: Failure - initial_pose position {position.tolist()} is beyond "
                f"|{MAX_POSITION_M:g}| m"
            )
        world_rot = frame.rotation @ rotation
        world_pos = frame.position + frame.rotation @ position
        wxyz = np.zeros(4)
        mujoco.mju_mat2Quat(wxyz, np.ascontiguousarray(world_rot).reshape(9))
        yaw = float(np.arctan2(world_rot[1, 0], world_rot[0, 0]))
        try:
            if is_sdf(xml):
                xml = sdf_model_to_urdf(xml, name=name or None)
            spawn = RobotSpawn(
                source=xml,
                name=name or None,
                spawn=(float(world_pos[0]), float(world_pos[1]), float(world_pos[2]), yaw),
                namespace=str(request.robot_namespace) or "/",
            )
            spawned = self._sim.spawn_robot(
                spawn, quat_wxyz=(float(wxyz[0]), float(wxyz[1]), float(wxyz[2]), float(wxyz[3]))
            )
        except VisnavError as exc:
            if "already exists" in str(exc):
                return False, f"SpawnModel: Failure - model name {name} already exists."
            return False, f"SpawnModel: Failure - model [{name}] cannot be spawned: {exc}"
        return True, f"SpawnModel: Successfully spawned entity [{spawned}]"

    def delete_model(self, name: str) -> tuple[bool, str]:
        """Delete a spawned or started robot (``gazebo_msgs/srv/DeleteModel``).

        Returns:
            ``(success, status_message)``.
        """
        if name not in self._sim.model_names:
            if name in self._models():
                return False, (
                    f"DeleteModel: model [{name}] is part of the world, which visnav cannot "
                    "change while it runs"
                )
            known = ", ".join(self._models())
            return False, f"DeleteModel: model [{name}] does not exist (models: {known})"
        try:
            self._sim.delete_robot(name)
        except VisnavError as exc:
            return False, f"DeleteModel: Failure - model [{name}] cannot be deleted: {exc}"
        return True, f"DeleteModel: successfully deleted model [{name}]"

    def _on_spawn(self, request: Any, response: Any) -> Any:
        response.success, response.status_message = self.spawn_model(request)
        return response

    def _on_delete(self, request: Any, response: Any) -> Any:
        response.success, response.status_message = self.delete_model(str(request.model_name))
        return response
