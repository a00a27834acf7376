"""``/gazebo/model_states`` and ``/gazebo/link_states``, as gazebo_ros_api_plugin publishes them.

The simulator's node (``/sim``; ``/gazebo`` when a roslaunch file's gazebo_ros node became
it) publishes, at every physics step while the topic has a subscriber (the
ROS 1 plugin connects its world-update callback on the first subscriber and drops it on
the last), the state at the step's sim time ``t`` (after ``mj_step1``):

* ``gazebo_msgs/ModelStates``: one entry per model, ``ground_plane`` (when the world has a
  ground) and every robot by its name: the pose of the robot's root link in the world and
  its twist (linear velocity of the link origin and angular velocity, both in the world
  frame);
* ``gazebo_msgs/LinkStates``: one entry per link, named ``model::link`` as Gazebo's scoped
  names, with the same world pose and twist.

The types are not in the ROS 2 Humble store; :mod:`visnav.msgs.gazebo_msgs` adds them
(hash and ROS 1 MD5 as gazebo_msgs'). The messages carry no header or stamp (as in
gazebo_msgs); they describe the sim time of the ``/clock`` published in the same step.

Where visnav differs: the world's static shapes are not grouped into Gazebo models, so
only the ground plane and the robots are listed; every URDF link is a link (Gazebo lumps
links joined by fixed joints into their parent, so ``imu_link`` or ``base_scan`` of a
TurtleBot3 are not in Gazebo's list).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.graph.qos import QoSProfile
from visnav.msgs.serde import get_message_class
from visnav.msgs.types import Point, Pose, Quaternion, Twist, Vector3
from visnav.sim.plugins import SimPlugin

if TYPE_CHECKING:
    import mujoco

    from visnav.graph.node import Node
    from visnav.sim.simulator import Simulator

__all__ = [
    "LINK_STATES_TOPIC",
    "MODEL_STATES_TOPIC",
    "ModelStatesPublisher",
    "StateEntry",
    "model_states_publisher",
]

MODEL_STATES_TOPIC = "/gazebo/model_states"
LINK_STATES_TOPIC = "/gazebo/link_states"
_QOS = QoSProfile(depth=10)

StateEntry = tuple[str, int | None]
"""``(name, MuJoCo body id)``; None: an entity fixed at the world origin (the ground)."""


class ModelStatesPublisher(SimPlugin):
    """gazebo_ros_api_plugin's model and link state topics.

    Args:
        node: the simulator's node (kept by :meth:`close`, which drops the publishers).
        model: the compiled model.
        models: the models, in order.
        links: the links (scoped ``model::link`` names), in order.
    """

    def __init__(
        self,
        node: Node,
        model: mujoco.MjModel,
        *,
        models: Sequence[StateEntry],
        links: Sequence[StateEntry],
    ) -> None:
        super().__init__(node, "model_states")
        self._models = _Entities(model, models)
        self._links = _Entities(model, links)
        self._model_cls = get_message_class("gazebo_msgs/msg/ModelStates")
        self._link_cls = get_message_class("gazebo_msgs/msg/LinkStates")
        self._model_pub = node.create_publisher(self._model_cls, MODEL_STATES_TOPIC, _QOS)
        self._link_pub = node.create_publisher(self._link_cls, LINK_STATES_TOPIC, _QOS)
        self._wanted = (-1, False, False)
        self.published = 0

    def close(self) -> None:
        """Drop the two publishers (the node is the simulator's)."""
        self.node.destroy_publisher(self._model_pub)
        self.node.destroy_publisher(self._link_pub)

    def _subscribed(self) -> tuple[bool, bool]:
        version = self.node.context.graph.version
        if version != self._wanted[0]:
            self._wanted = (
                version,
                self._model_pub.get_subscription_count() > 0,
                self._link_pub.get_subscription_count() > 0,
            )
        return self._wanted[1], self._wanted[2]

    def sense(self, data: mujoco.MjData, now_ns: int) -> None:
        """Publish the states at ``now_ns`` on the topics that have subscribers."""
        del now_ns
        models, links = self._subscribed()
        if models:
            self._model_pub.publish(self._models.message(self._model_cls, data))
            self.published += 1
        if links:
            self._link_pub.publish(self._links.message(self._link_cls, data))
            self.published += 1


class _Entities:
    """Named bodies read together: world pose and the twist of each body frame's origin.

    After ``mj_step1`` the kinematics and ``cvel`` describe the step's state for every body
    (free ones included): ``cvel`` is the angular velocity and the linear velocity at the
    tree's centre of mass (``subtree_com`` of the root), moved here to the body origin.
    """

    def __init__(self, model: mujoco.MjModel, entries: Sequence[StateEntry]) -> None:
        self.names = [name for name, _ in entries]
        self._rows = [i for i, (_, body) in enumerate(entries) if body is not None]
        self._bodies = np.array([b for _, b in entries if b is not None], dtype=np.int64)
        self._roots = np.asarray(model.body_rootid[self._bodies], dtype=np.int64)
        origin = Pose(position=Point(0.0, 0.0, 0.0), orientation=Quaternion(0.0, 0.0, 0.0, 1.0))
        still = Twist(linear=Vector3(0.0, 0.0, 0.0), angular=Vector3(0.0, 0.0, 0.0))
        self._origin_poses = [origin] * len(self.names)  # entities without a body
        self._still = [still] * len(self.names)

    def message(self, msg_type: type[Any], data: mujoco.MjData) -> Any:
        poses = list(self._origin_poses)
        twists = list(self._still)
        if self._rows:
            b = self._bodies
            # a few array reads, then plain Python: numpy's per-call cost dominates 8 rows
            positions = data.xpos[b].tolist()
            quats = data.xquat[b].tolist()
            velocities = data.cvel[b].tolist()
            centres = data.subtree_com[self._roots].tolist()
            for row, p, q, v, c in zip(
                self._rows, positions, quats, velocities, centres, strict=True
            ):
                wx, wy, wz, vx, vy, vz = v
                rx, ry, rz = p[0] - c[0], p[1] - c[1], p[2] - c[2]
                poses[row] = Pose(
                    position=Point(*p), orientation=Quaternion(q[1], q[2], q[3], q[0])
                )
                twists[row] = Twist(
                    linear=Vector3(vx + wy * rz - wz * ry, vy + wz * rx - wx * rz,
                                   vz + wx * ry - wy * rx),
                    angular=Vector3(wx, wy, wz),
                )  # fmt: skip
        return msg_type(name=list(self.names), pose=poses, twist=twists)


def model_states_publisher(sim: Simulator) -> ModelStatesPublisher:
    """The model and link states of a simulator: its world's ground, its robots and links."""
    model = sim.model
    models: list[StateEntry] = []
    links: list[StateEntry] = []
    if sim.world.ground is not None:
        models.append(("ground_plane", None))
        links.append(("ground_plane::link", None))
    for robot in sim.robots:
        handles = robot.handles
        models.append((robot.name, model.body(handles.root_body).id))
        for link, body in handles.bodies.items():
            links.append((f"{robot.name}::{link}", model.body(body).id))
    return ModelStatesPublisher(sim.node, model, models=models, links=links)
