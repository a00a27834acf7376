"""A robot's contacts on a topic: the simulator's bumper (``gazebo_ros_bumper``'s role).

:class:`ContactSensor` samples MuJoCo's contact list at ``rate_hz`` of sim time (after
``mj_step1``, so the contacts describe the state at ``t``) and publishes every sample on
``<robot namespace>/bumper_states`` as ``diagnostic_msgs/DiagnosticArray``, an empty
``status`` list when nothing touches. One ``DiagnosticStatus`` per contact between a geom
of the robot and a geom that is not the robot's:

* ``name``: the robot's geom (its MuJoCo name; ``body/geom<N>`` for an unnamed one),
  Gazebo's ``collision1_name``;
* ``hardware_id``: the other geom, Gazebo's ``collision2_name``;
* ``message``: the other geom's shape (``plane``, ``box``, ``cylinder``, ...), so a
  consumer can leave the floor out;
* ``values``: ``x``, ``y``, ``z`` (contact position in ``world``, m) and ``depth``
  (penetration, m).

Where visnav differs from Gazebo: gazebo_ros_bumper publishes
``gazebo_msgs/ContactsState`` for one ``<sensor type="contact">`` of the URDF; that type is
not in the ROS 2 Humble type store visnav's graph carries, and the sensor is switched on
for the whole robot by the simulator's ``contact_rate`` (Hz, 0 = off) instead of per
collision element, so the robot description needs no extra tags.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from visnav.graph.node import Node
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header
from visnav.sim.plugins import DEFAULT_QOS, SimPlugin
from visnav.sim.sensor_timing import SensorClock

if TYPE_CHECKING:
    from visnav.sim.rebind import IdMap

__all__ = ["CONTACT_TOPIC", "ContactSensor", "geom_label"]

CONTACT_TOPIC = "bumper_states"
"""The topic (relative to the robot's namespace), gazebo_ros_bumper's default name."""

_SHAPES = {
    int(mujoco.mjtGeom.mjGEOM_PLANE): "plane",
    int(mujoco.mjtGeom.mjGEOM_HFIELD): "heightfield",
    int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): "ellipsoid",
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder",
    int(mujoco.mjtGeom.mjGEOM_BOX): "box",
    int(mujoco.mjtGeom.mjGEOM_MESH): "mesh",
}


def geom_label(model: mujoco.MjModel, geom: int) -> str:
    """The MuJoCo name of a geom (``body/geom<N>`` for an unnamed one)."""
    name = model.geom(geom).name
    if name:
        return str(name)
    body = int(model.geom_bodyid[geom])
    return f"{model.body(body).name or f'body{body}'}/geom{geom}"


class ContactSensor(SimPlugin):
    """Publishes a robot's contacts (module docstring).

    Args:
        node: the node that publishes (the plugin destroys it on close).
        model: the compiled MuJoCo model.
        root_body: MuJoCo id of the robot's root body; every body of its tree is the robot.
        rate_hz: samples per simulated second (> 0).
    """

    def __init__(self, node: Node, model: mujoco.MjModel, root_body: int, rate_hz: float) -> None:
        super().__init__(node, "contacts")
        self._root = int(root_body)
        self._bind(model)
        self._clock = SensorClock(rate_hz)
        self._status = get_message_class("diagnostic_msgs/msg/DiagnosticStatus")
        self._key_value = get_message_class("diagnostic_msgs/msg/KeyValue")
        self._array = get_message_class("diagnostic_msgs/msg/DiagnosticArray")
        self._pub = node.create_publisher(self._array, CONTACT_TOPIC, DEFAULT_QOS)

    def _bind(self, model: mujoco.MjModel) -> None:
        self._model = model
        robot_bodies = np.asarray(model.body_rootid) == self._root
        # per geom: does it belong to the robot (contacts are filtered with numpy)
        self._robot_geom = robot_bodies[np.asarray(model.geom_bodyid)]
        self._robot_list: list[bool] = self._robot_geom.tolist()
        self._shapes = [_SHAPES.get(int(t), "other") for t in model.geom_type]  # per geom
        self._labels: dict[int, str] = {}  # geom -> label, filled on first contact

    def _label(self, geom: int) -> str:
        label = self._labels.get(geom)
        if label is None:
            label = self._labels[geom] = geom_label(self._model, geom)
        return label

    def rebind(self, ids: IdMap) -> None:
        """Watch the same robot in a recompiled model (a spawned model is "the rest")."""
        self._root = ids.body(self._root)
        self._bind(ids.model)

    def sense(self, data: mujoco.MjData, now_ns: int) -> None:
        """Publish the contacts at ``now_ns`` when a sample is due."""
        if not self._clock.due(now_ns):
            return
        statuses: list[Any] = []
        ncon = int(data.ncon)
        if ncon:
            # plain Python values: for a handful of contacts numpy calls cost more
            contacts = data.contact
            robot = self._robot_list
            g1 = contacts.geom1.tolist()
            g2 = contacts.geom2.tolist()
            mixed = [k for k in range(ncon) if robot[g1[k]] != robot[g2[k]]]  # robot vs rest
            if mixed:
                pos = contacts.pos.tolist()
                dist = contacts.dist.tolist()
                shapes, label = self._shapes, self._label
                kv, status = self._key_value, self._status
                for k in mixed:
                    a, b = g1[k], g2[k]
                    own, other = (a, b) if robot[a] else (b, a)
                    x, y, z = pos[k]
                    depth = -dist[k]
                    statuses.append(
                        status(
                            level=0,
                            name=label(own),
                            message=shapes[other],
                            hardware_id=label(other),
                            values=[
                                kv(key="x", value=f"{x:.6g}"),
                                kv(key="y", value=f"{y:.6g}"),
                                kv(key="z", value=f"{z:.6g}"),
                                kv(key="depth", value=f"{depth:.6g}"),
                            ],
                        )
                    )
        header = Header(stamp=ns_to_time(now_ns), frame_id="world")
        self._pub.publish(self._array(header=header, status=statuses))
