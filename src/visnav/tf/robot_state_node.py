"""robot_state_publisher: the publisher the simulator runs per robot, and a standalone node.

:class:`RobotStatePublisher` wires a :class:`~visnav.tf.robot_state.RobotStateModel` to a
node; :class:`RobotStatePublisherNode` is ``executable: robot_state_publisher``.

Parameters, as ROS 2's robot_state_publisher:

* ``robot_description`` (string, required): the URDF XML (Xacro already expanded);
  republished latched on ``robot_description``;
* ``frame_prefix`` (string): prepended to every frame id;
* ``publish_frequency`` (Hz, 20.0 as ROS 2; ROS 1's default is 50.0): at most this
  often per joint, by the messages' stamps; 0 publishes every message.

It publishes ``/tf_static`` for the fixed joints once and ``/tf`` for the moving
joints on ``joint_states`` messages, stamped as the message (see
:mod:`visnav.tf.robot_state` for the differences from ROS). Meshes are not
needed: only links and joints are read.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import TYPE_CHECKING

from visnav.description.urdf import parse_urdf
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.graph.qos import QoSProfile, qos_profile_latched
from visnav.msgs.types import JointState, String
from visnav.tf.errors import TransformException
from visnav.tf.robot_state import RobotStateError, RobotStateModel
from visnav.tf.ros import StaticTransformBroadcaster, TransformBroadcaster

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "RobotStatePublisher",
    "RobotStatePublisherNode",
    "RobotStatePublisherNodeError",
    "RobotStatePublisherParams",
    "kinematics_only",
]

_DEFAULT_QOS = QoSProfile(depth=10)


class RobotStatePublisherNodeError(TransformException, ValueError):
    """The ``robot_description`` parameter is missing."""


def kinematics_only(urdf_xml: str) -> str:
    """The URDF without ``<visual>`` and ``<collision>`` elements (no meshes to resolve).

    Malformed XML is returned unchanged, for :func:`~visnav.description.urdf.parse_urdf` to
    report with its line.
    """
    try:
        root = ET.fromstring(urdf_xml)  # noqa: S314 - the robot description, not network input
    except ET.ParseError:
        return urdf_xml
    for link in root.iter("link"):
        for child in list(link):
            if child.tag in ("visual", "collision"):
                link.remove(child)
    return ET.tostring(root, encoding="unicode")


class RobotStatePublisher:
    """robot_state_publisher: ``robot_description``, ``/tf_static`` once, ``/tf`` per JointState.

    Args:
        node: the node (``robot_state_publisher`` in the robot's namespace).
        model: the robot's kinematics (with its frame prefix).
        description: the URDF XML, published latched on ``robot_description``.
        joint_states_topic: where joint states arrive.
        stamp_ns: stamp of the static transforms.
        publish_interval_ns: a joint's transform is published at most once per this
            interval of message stamps (robot_state_publisher's ``publish_frequency``);
            0: every message.
    """

    def __init__(
        self,
        node: Node,
        model: RobotStateModel,
        description: str,
        *,
        joint_states_topic: str = "joint_states",
        stamp_ns: int = 0,
        publish_interval_ns: int = 0,
    ) -> None:
        self.node = node
        self.model = model
        self.publish_interval_ns = publish_interval_ns
        self._last_ns: dict[str, int] = {}
        node.create_publisher(String, "robot_description", qos_profile_latched).publish(
            String(data=description)
        )
        self._static = StaticTransformBroadcaster(node)
        statics = model.static_transforms(stamp_ns=stamp_ns)
        if statics:
            self._static.send_transform(statics)
        self._tf = TransformBroadcaster(node)
        self._sub = None
        if model.moving_joints:
            self._sub = node.create_subscription(
                JointState, joint_states_topic, self._on_joint_states, _DEFAULT_QOS
            )

    def _due(self, msg: JointState) -> bool:
        """robot_state_publisher's throttle: the oldest last publish of the message's joints."""
        if self.publish_interval_ns <= 0:
            return True
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        known = [self._last_ns[n] for n in msg.name if n in self._last_ns]
        # a joint never published, or time gone backwards (a restarted simulation): publish
        fresh = not known or len(known) < len(msg.name) or stamp < min(known)
        if not fresh and stamp < min(known) + self.publish_interval_ns:
            return False
        for name in msg.name:
            self._last_ns[name] = stamp
        return True

    def _on_joint_states(self, msg: JointState) -> None:
        if not self._due(msg):
            return
        try:
            transforms = self.model.dynamic_transforms(msg)
        except RobotStateError as exc:
            self.node.get_logger().warning(f"dropped a JointState: {exc}")
            return
        if transforms:
            self._tf.send_transform(transforms)

    def close(self) -> None:
        """Destroy the node."""
        self.node.destroy_node()


@dataclass(frozen=True)
class RobotStatePublisherParams:
    """robot_state_publisher's parameters (read once at start)."""

    robot_description: str = param("", description="the robot's URDF XML (required)")
    frame_prefix: str = param("", description="prepended to every published frame id")
    publish_frequency: float = param(
        20.0, description="max /tf rate per joint (Hz); 0: every message", range=(0.0, 1e6)
    )


class RobotStatePublisherNode(Node):
    """A robot_state_publisher node (see the module docstring).

    Args:
        name: the node's name.
        **node_kwargs: :class:`~visnav.graph.Node`'s keyword parameters (context, ...).

    Raises:
        RobotStatePublisherNodeError: no ``robot_description`` parameter.
        RobotDescriptionError: the description is not a valid URDF.
    """

    def __init__(
        self, name: str = "robot_state_publisher", **node_kwargs: Unpack[NodeOptions]
    ) -> None:
        super().__init__(name, **node_kwargs)
        try:
            params = declare_params(self, RobotStatePublisherParams)
            description, prefix = params.robot_description, params.frame_prefix
            if not description.strip():
                msg = (
                    f"{self.get_fully_qualified_name()}: parameter robot_description is empty. "
                    "Fix: pass the URDF XML (e.g. the output of xacro) as robot_description"
                )
                raise RobotStatePublisherNodeError(msg)
            urdf = parse_urdf(kinematics_only(description), source="robot_description")
            self.publisher = RobotStatePublisher(
                self,
                RobotStateModel(urdf, frame_prefix=prefix),
                description,
                stamp_ns=self.get_clock().now_ns(),
                publish_interval_ns=(
                    round(1e9 / params.publish_frequency) if params.publish_frequency > 0 else 0
                ),
            )
        except BaseException:
            self.destroy_node()
            raise
