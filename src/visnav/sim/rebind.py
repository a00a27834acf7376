"""Moving a running simulation onto a recompiled MuJoCo model (models spawned or deleted).

``/gazebo/spawn_*_model`` and ``/gazebo/delete_model`` change which bodies exist. The
simulator composes a new spec (the world, then every remaining robot in order, then the
new one), compiles it, and moves onto it between two physics steps:

* :func:`transfer_state` copies the physics state of every element that exists in both
  models (joint positions and velocities, warm start, applied forces, controls and
  actuator activations, sim time), matched by name; a new robot starts at its spawn pose;
* an :class:`IdMap` translates the old model's ids and addresses into the new one's
  (deleting a robot shifts the ids of the robots after it), and each plugin's
  :meth:`~visnav.sim.plugins.SimPlugin.rebind` takes its new ids, the new model and, for
  cameras, the new render context; controller state (odometry, integrators, commands,
  sensor schedules) stays as it was.

MuJoCo's ``MjSpec.recompile(model, data)`` keeps the state the same way, but edits the
spec in place: a model that does not compile would leave the running spec half changed.
Composing a fresh spec keeps the running simulation untouched until the new model is
known to compile and its plugins are built.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np
import numpy.typing as npt

from visnav.sim.errors import SimulatorError

if TYPE_CHECKING:
    from visnav.sim.gl import RenderContext

__all__ = ["IdMap", "transfer_state"]

_Ints = npt.NDArray[np.int64]
_OBJ = mujoco.mjtObj
_JOINT_QPOS = {0: 7, 1: 4, 2: 1, 3: 1}  # free, ball, slide, hinge
_JOINT_DOF = {0: 6, 1: 3, 2: 1, 3: 1}


def _ids(old: mujoco.MjModel, new: mujoco.MjModel, obj: mujoco.mjtObj, n_old: int) -> _Ints:
    """Old id -> new id (-1: gone), matched by name.

    Unnamed elements keep their index if it is unnamed in the new model too (the
    world's own elements, which come first).
    """
    out = np.full(n_old, -1, dtype=np.int64)
    for i in range(n_old):
        name = mujoco.mj_id2name(old, obj, i)
        if name:
            out[i] = mujoco.mj_name2id(new, obj, name)
        elif i < _count(new, obj) and not mujoco.mj_id2name(new, obj, i):
            out[i] = i
    return out


def _count(model: mujoco.MjModel, obj: mujoco.mjtObj) -> int:
    return int(
        {
            _OBJ.mjOBJ_BODY: model.nbody,
            _OBJ.mjOBJ_JOINT: model.njnt,
            _OBJ.mjOBJ_GEOM: model.ngeom,
            _OBJ.mjOBJ_SITE: model.nsite,
            _OBJ.mjOBJ_CAMERA: model.ncam,
            _OBJ.mjOBJ_SENSOR: model.nsensor,
            _OBJ.mjOBJ_ACTUATOR: model.nu,
        }[obj]
    )


def _spread(old_adr: _Ints, new_adr: _Ints, sizes: _Ints, ids: _Ints, length: int) -> _Ints:
    """Per-element address map (qpos, dof, sensordata) from a per-object id map."""
    out = np.full(length, -1, dtype=np.int64)
    for i, j in enumerate(ids.tolist()):
        if j < 0:
            continue
        a, b, n = int(old_adr[i]), int(new_adr[j]), int(sizes[i])
        out[a : a + n] = np.arange(b, b + n)
    return out


class IdMap:
    """Ids and addresses of an old model in a new one (elements matched by name).

    Args:
        old: the model the simulation ran on.
        new: the recompiled model.
        render_context: the new model's render context (None without cameras).

    Attributes:
        model: the new model.
        render_context: its render context.
        identity: True when every surviving element keeps its id (a model was appended).
    """

    def __init__(
        self,
        old: mujoco.MjModel,
        new: mujoco.MjModel,
        *,
        render_context: RenderContext | None = None,
    ) -> None:
        self.model = new
        self.render_context = render_context
        self._maps = {
            obj: _ids(old, new, obj, _count(old, obj))
            for obj in (
                _OBJ.mjOBJ_BODY,
                _OBJ.mjOBJ_JOINT,
                _OBJ.mjOBJ_GEOM,
                _OBJ.mjOBJ_SITE,
                _OBJ.mjOBJ_CAMERA,
                _OBJ.mjOBJ_SENSOR,
                _OBJ.mjOBJ_ACTUATOR,
            )
        }
        joints = self._maps[_OBJ.mjOBJ_JOINT]
        types = np.asarray(old.jnt_type, dtype=np.int64)
        nq = np.array([_JOINT_QPOS[int(t)] for t in types], dtype=np.int64)
        nv = np.array([_JOINT_DOF[int(t)] for t in types], dtype=np.int64)
        self._qpos = _spread(old.jnt_qposadr, new.jnt_qposadr, nq, joints, old.nq)
        self._dof = _spread(old.jnt_dofadr, new.jnt_dofadr, nv, joints, old.nv)
        sensors = self._maps[_OBJ.mjOBJ_SENSOR]
        self._sensordata = _spread(
            old.sensor_adr, new.sensor_adr, old.sensor_dim, sensors, old.nsensordata
        )
        self.identity = all(
            bool(np.all((m < 0) | (m == np.arange(len(m))))) for m in self._maps.values()
        )

    def _one(self, obj: mujoco.mjtObj, i: int, what: str) -> int:
        j = int(self._maps[obj][int(i)])
        if j < 0:
            msg = f"{what} {int(i)} of the old model is not in the recompiled model"
            raise SimulatorError(msg)
        return j

    def body(self, i: int) -> int:
        """New id of body ``i``.

        Raises:
            SimulatorError: the body was deleted (so is every id method's error).
        """
        return self._one(_OBJ.mjOBJ_BODY, i, "body")

    def camera(self, i: int) -> int:
        """New id of camera ``i``."""
        return self._one(_OBJ.mjOBJ_CAMERA, i, "camera")

    def _many(self, table: _Ints, values: npt.ArrayLike, what: str) -> _Ints:
        arr = np.asarray(values, dtype=np.int64)
        out = table[arr] if arr.size else arr.copy()
        if np.any(out < 0):
            msg = f"{what} {arr[out < 0].tolist()} of the old model are not in the new model"
            raise SimulatorError(msg)
        return out

    def qpos(self, adr: npt.ArrayLike) -> _Ints:
        """New ``qpos`` addresses of old ones (any shape)."""
        return self._many(self._qpos, adr, "qpos addresses")

    def dof(self, adr: npt.ArrayLike) -> _Ints:
        """New dof (``qvel``) addresses of old ones."""
        return self._many(self._dof, adr, "dof addresses")

    def sensordata(self, adr: npt.ArrayLike) -> _Ints:
        """New ``sensordata`` addresses of old ones."""
        return self._many(self._sensordata, adr, "sensordata addresses")

    @property
    def qpos_table(self) -> _Ints:
        """Old qpos address -> new one (-1: gone)."""
        return self._qpos

    @property
    def dof_table(self) -> _Ints:
        """Old dof address -> new one (-1: gone)."""
        return self._dof

    def kept(self, obj: mujoco.mjtObj) -> _Ints:
        """old id -> new id (-1: gone) of one object type (body, joint, geom, ...)."""
        return self._maps[obj]


def _copy(dst: npt.NDArray[np.float64], src: npt.NDArray[np.float64], table: _Ints) -> None:
    keep = table >= 0
    if np.any(keep):
        dst[table[keep]] = src[keep]


def transfer_state(
    old: mujoco.MjModel,
    old_data: mujoco.MjData,
    ids: IdMap,
    new_data: mujoco.MjData,
) -> None:
    """Copy the state of every element that survives from ``old_data`` into ``new_data``.

    ``new_data`` keeps its defaults (the new model's ``qpos0``: a spawned model at its
    spawn pose, at rest) for elements only the new model has. Runs ``mj_forward``.
    """
    new = ids.model
    new_data.time = old_data.time
    _copy(new_data.qpos, old_data.qpos, ids.qpos_table)
    for name in ("qvel", "qacc_warmstart", "qfrc_applied"):
        _copy(getattr(new_data, name), getattr(old_data, name), ids.dof_table)
    bodies = ids.kept(_OBJ.mjOBJ_BODY)
    keep = bodies >= 0
    new_data.xfrc_applied[bodies[keep]] = old_data.xfrc_applied[keep]
    actuators = ids.kept(_OBJ.mjOBJ_ACTUATOR)
    for i, j in enumerate(actuators.tolist()):
        if j < 0:
            continue
        new_data.ctrl[j] = old_data.ctrl[i]
        n = int(old.actuator_actnum[i])
        if n and int(new.actuator_actnum[j]) == n:
            a, b = int(old.actuator_actadr[i]), int(new.actuator_actadr[j])
            new_data.act[b : b + n] = old_data.act[a : a + n]
    for i, j in enumerate(bodies.tolist()):
        m_old = int(old.body_mocapid[i])
        if j >= 0 and m_old >= 0 and int(new.body_mocapid[j]) >= 0:
            m_new = int(new.body_mocapid[j])
            new_data.mocap_pos[m_new] = old_data.mocap_pos[m_old]
            new_data.mocap_quat[m_new] = old_data.mocap_quat[m_old]
    n = min(len(new_data.userdata), len(old_data.userdata))
    new_data.userdata[:n] = old_data.userdata[:n]
    mujoco.mj_forward(new, new_data)
